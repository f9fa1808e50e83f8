"""Which steps of a pilot rollout measure the motion: the levels (``PilotMotion``), each tree's
screen at every step (``MotionScreen``), and the maxima a level keeps (``level_maxima``)."""

from __future__ import annotations

import enum

import mujoco
import numpy as np

__all__ = ["LEVELS", "MotionScreen", "PilotMotion", "level_maxima"]


class PilotMotion(enum.StrEnum):
    """Which steps of its rollout the pilot measures (``PilotOptions(motion=...)``).

    A constraint's impulse is what the predictor must foresee, not part of the motion model:
    with it the bounds become loose enough to alarm every pair. A step the pilot leaves out is
    one where the tree was, or in the two steps before (the span of a second difference), in
    a contact (``FREE``: free motion, what the actuators and gravity do; also at a joint limit)
    or in a *new* contact (``NO_IMPACTS``: sustained contact such as resting or grasping is
    measured as ordinary motion); ``ALL`` measures every step. A body the level measures at no
    step (a foot always on the ground) takes the next level's maxima: free, then no impacts,
    then every step. The motion the pilot leaves out breaks the bounds in a run, and the
    step re-evaluates the pairs of the bodies involved (docs/theory.md, section 6).
    """

    FREE = "free"
    NO_IMPACTS = "no-impacts"
    ALL = "all"


LEVELS = (PilotMotion.FREE, PilotMotion.NO_IMPACTS, PilotMotion.ALL)
"""The levels in the order :meth:`MotionScreen.update` screens them, each admitting more."""


class MotionScreen:
    """Which trees a pilot step measures, level by level (:class:`PilotMotion`).

    Call :meth:`update` after every ``mj_step`` of a rollout. ``MjData``'s contacts and
    constraints are then those of the state the step started from, whose forces made the step's
    velocity. The pilot's second difference at a step differences the chords of that step and
    the one before, so the constraints seen by this update and the last can reach it. The
    screen spans three updates, one more than that, and a tree's step is screened out when any
    of them saw the event.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self._rootid = np.asarray(model.body_rootid, dtype=np.int64)
        self._geom_root = self._rootid[np.asarray(model.geom_bodyid, dtype=np.int64)]
        self._joint_root = self._rootid[np.asarray(model.jnt_bodyid, dtype=np.int64)]
        # Per tree, over the last three steps: a new contact; any contact or joint limit.
        self._new = np.zeros((3, model.nbody), dtype=bool)
        self._held = np.zeros((3, model.nbody), dtype=bool)
        self._in_contact: set[tuple[int, int]] = set()
        self._step = 0

    def update(self, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The screens after this step, ``(nbody,)`` bool each, by body (its tree's verdict).

        Returns:
            ``free``: no contact and no joint limit in the last three steps (``FREE``);
            ``calm``: no new contact in them (``NO_IMPACTS``). Every step is ``ALL``'s.
        """
        k = self._step % 3
        self._step += 1
        new, held = self._new, self._held
        new[k] = False
        held[k] = False
        nc = int(d.ncon)
        now = set(zip(d.contact.geom1[:nc].tolist(), d.contact.geom2[:nc].tolist(), strict=True))
        # A flex's contact has geom -1 on the flex's side: only the geom's tree is marked.
        for g1, g2 in now:
            held[k, self._geom_root[[g for g in (g1, g2) if g >= 0]]] = True
        for g1, g2 in now - self._in_contact:
            new[k, self._geom_root[[g for g in (g1, g2) if g >= 0]]] = True
        if d.nefc:
            limit = np.asarray(d.efc_type[: d.nefc]) == int(
                mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
            )
            held[k, self._joint_root[np.asarray(d.efc_id[: d.nefc])[limit]]] = True
        self._in_contact = now
        calm = ~np.asarray(new.any(axis=0))[self._rootid]
        return calm & ~np.asarray(held.any(axis=0))[self._rootid], calm


def level_maxima(maxima: np.ndarray, measured: np.ndarray, motion: PilotMotion) -> np.ndarray:
    """``(n,)`` the maxima of ``motion``'s level, from ``(3, n)`` maxima and ``measured`` flags by
    level (:data:`LEVELS`' order); a column the level never measured takes the next level's."""
    out = maxima[-1].copy()
    for level in range(len(LEVELS) - 2, LEVELS.index(motion) - 1, -1):
        out = np.where(measured[level], maxima[level], out)
    return out
