"""MuJoCo-free numerical core of dua_mujoco (no module here imports mujoco)."""
