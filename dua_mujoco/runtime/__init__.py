"""Running: the thin objects over the native runtime (the predictor, its alarms, pair state and
plans, and the tables it hands the runtime)."""
