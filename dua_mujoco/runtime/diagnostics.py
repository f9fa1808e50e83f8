"""Why a state cannot be predicted from: non-finite kinematics, or MuJoCo's own reset after a
divergence. Each message names what is wrong (geoms, joints, warnings) and what to do."""

from __future__ import annotations

import mujoco
import numpy as np

from dua_mujoco.build.bounds import DIVERGENCE_WARNINGS
from dua_mujoco.exceptions import NonFiniteStateError, SchedulerError

__all__ = ["clock_error", "divergence_message", "nonfinite_error"]


def nonfinite_error(
    model: mujoco.MjModel, data: mujoco.MjData, geom_names: np.ndarray, geoms: set[int]
) -> NonFiniteStateError:
    """The error for a non-finite state: the geoms whose state is NaN or inf (``geoms``), or,
    when none is (kinematics computed before a NaN was written), the joints of ``qpos``/``qvel``
    that are."""
    if geoms:
        listed = ", ".join(repr(geom_names[i]) for i in sorted(geoms))
        what = f"the state of geom(s) {listed}"
    else:
        bad = [
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            for vec, adr in ((data.qpos, model.jnt_qposadr), (data.qvel, model.jnt_dofadr))
            for j in np.unique(np.searchsorted(adr, np.flatnonzero(~np.isfinite(vec)), "right") - 1)
        ]
        what = f"data.qpos or data.qvel of joint(s) {sorted(set(bad))}"
    return NonFiniteStateError(
        f"{what} is not finite at t = {data.time}: the simulation has diverged (reduce the "
        "timestep or check the model) or MjData was not initialised (call mujoco.mj_forward)."
    )


def clock_error(
    data: mujoco.MjData, expected_steps: int, elapsed: float, period: int, dt: float
) -> NonFiniteStateError | SchedulerError:
    """The error for a predictor step whose ``data.time`` did not advance by one period
    (``elapsed`` seconds instead of ``dt``): MuJoCo's reset after a divergence when that is
    what happened (:func:`divergence_message`), else a step called at the wrong rate."""
    diverged = divergence_message(data, expected_steps)
    if diverged:
        return NonFiniteStateError(diverged)
    return SchedulerError(
        f"data.time advanced by {elapsed:.9g} s since the previous predictor call, but the "
        f"predictor period is {dt:.9g} s (period={period} x timestep {dt / period:g}): call "
        f"step() every {period} physics step(s), or reset() after changing the state."
    )


def divergence_message(data: mujoco.MjData, expected_steps: int) -> str:
    """Why the state jumped, if MuJoCo reset it after diverging (or "").

    Called only when ``data.time`` did not advance by one period. MuJoCo answers a diverged
    state with a warning and ``mj_resetData``, which also restarts its count of ``mj_step``
    calls: a divergence warning standing and a step count other than ``expected_steps`` (what
    the predictor's calls imply) mean MuJoCo reset the state (a user's own ``mj_resetData``
    clears the warnings; a rewound ``data.time`` leaves the step count as it was).
    """
    names = [w.name for w in DIVERGENCE_WARNINGS if data.warning[int(w)].number]
    if not names or int(data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].number) == expected_steps:
        return ""
    return (
        f"MuJoCo reported a NaN, inf or huge value ({', '.join(names)}) and reset the "
        f"simulation state itself (data.time is now {data.time:g} s): the simulation "
        "diverged. Reduce model.opt.timestep or check the model and controls, then call "
        "predictor.reset(data)."
    )
