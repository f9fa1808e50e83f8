"""The MuJoCo-free core: tau, the schedules, pair geometry, raw sphere states and worlds."""
