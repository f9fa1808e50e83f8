"""Which steps of a pilot rollout measure the motion, tree by tree (``PilotMotion``'s levels).

A constraint's impulse is what the predictor must foresee, not part of the motion model, so
the pilot measures a tree's accelerations only at steps its level admits (docs/theory.md,
section 6).
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["MotionScreen"]


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
        self._model = model
        self._rootid = np.asarray(model.body_rootid, dtype=np.int64)
        self._geom_root = self._rootid[np.asarray(model.geom_bodyid, dtype=np.int64)]
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
        for g1, g2 in now:
            held[k, self._geom_root[g1]] = held[k, self._geom_root[g2]] = True
        for g1, g2 in now - self._in_contact:
            new[k, self._geom_root[g1]] = new[k, self._geom_root[g2]] = True
        if d.nefc:
            limit = np.asarray(d.efc_type[: d.nefc]) == int(
                mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
            )
            joints = np.asarray(d.efc_id[: d.nefc])[limit]
            held[k, self._rootid[np.asarray(self._model.jnt_bodyid)[joints]]] = True
        self._in_contact = now
        calm = ~np.asarray(new.any(axis=0))[self._rootid]
        return calm & ~np.asarray(held.any(axis=0))[self._rootid], calm
