"""The MuJoCo layer: covering, pair filter, kinematics, bounds, the predictor, the exact stage."""
