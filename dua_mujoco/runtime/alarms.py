"""``Alarms``: what one predictor step says.

The native runtime appends every step's alarms to a log that nobody overwrites (a full log is
replaced, and an old one lives as long as an ``Alarms`` of it does), so an ``Alarms`` is a span
of it: its arrays are read-only views, made when read, and a step copies nothing. Attributes:
``step`` (0 for the initial classification), ``time`` (``data.time`` when read), ``pairs`` (the
sphere-pair ids that raised an alarm), ``tau``, ``new`` (alarms this step raised, as opposed to
ones standing from before: print these to see changes), ``deferred`` (pairs due but left for a
later step), ``geom1``, ``geom2``, ``sphere1``, ``sphere2`` (-1 for half-space and static-shape
pairs), ``names`` and ``geom_pairs``.
"""

from __future__ import annotations

from dua_mujoco._core import Alarms

__all__ = ["Alarms"]
