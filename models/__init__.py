"""Demo content, outside the library: the bundled MJCF scenes, the generated scenes and the
controllers that drive them (:mod:`~dua_mujoco.models.scenes`)."""
