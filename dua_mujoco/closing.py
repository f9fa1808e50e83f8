"""``Closing``: ``with`` for the package's resources (progress lines, renderers, video writers)."""

from __future__ import annotations

from types import TracebackType
from typing import Self

__all__ = ["Closing"]


class Closing:
    """Gives a class with ``close()`` the context-manager protocol: ``with`` closes it, also when
    the block raises (a Ctrl-C included)."""

    def close(self) -> None:
        """Release the resource (idempotent in every subclass)."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
