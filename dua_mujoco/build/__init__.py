"""Building: a MuJoCo model and the options to the tables a predictor runs on (covering, pair
filter, bounds and their pilot, pair tables, static shapes, exact level, events, pruned reach)."""
