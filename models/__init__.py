"""Demo content, outside the library: the bundled MJCF scenes, the generated scenes and the
controllers that drive them (:mod:`~dua_mujoco.models.scenes`)."""

from pathlib import Path

__all__ = ["models_dir"]


def models_dir() -> Path:
    """The folder holding the bundled XMLs: this package's own.

    Returns:
        The folder's path.
    """
    return Path(__file__).resolve().parent
