"""Test-session setup shared by every test module."""

import os

# MuJoCo picks its OpenGL backend when it is first imported, which may be in any test module:
# make the offscreen renderer headless (EGL, Mesa llvmpipe on the CPU) before any of them loads.
os.environ.setdefault("MUJOCO_GL", "egl")
