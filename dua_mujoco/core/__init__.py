"""Core kernels that import nothing from MuJoCo."""
