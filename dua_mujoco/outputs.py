"""Output files written safely: atomically for regular files, in place for everything else.

A report or a video is written to a temporary file beside its target and moved into place
(``publish``), so that an interrupted or failed run never leaves a half-written file where an
older one was. Symlinks, devices and FIFOs (``--json /dev/stdout``) are written through instead:
replacing them would destroy them.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

__all__ = ["publish", "temporary_beside", "writes_in_place"]


def writes_in_place(path: Path) -> bool:
    """True for a path that is written through, never replaced: a symlink, device or FIFO."""
    try:
        mode = os.lstat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return False
    return not stat.S_ISREG(mode)


def temporary_beside(path: Path, suffix: str) -> Path:
    """A new empty file in ``path``'s folder, with the mode a plain ``open`` would give it
    (``mkstemp`` makes it private, 0600)."""
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=suffix)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(name, 0o666 & ~umask)
    return Path(name)


def publish(tmp: Path, path: Path) -> None:
    """Move a finished temporary file onto ``path`` (atomic on one file system)."""
    os.replace(tmp, path)
