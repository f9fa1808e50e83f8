"""Bundled MJCF scenes (shipped as ``dua_mujoco.models``)."""
