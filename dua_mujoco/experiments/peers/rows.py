"""The benchmark's result rows: ghost world, scenes, memory, speculative-contact demo."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from dua_mujoco.experiments.peers.tracker import Tracker

__all__ = ["GhostRow", "MemoryRow", "PeerRow", "SceneRow", "TunnelRow", "peer_measures"]


@dataclass(frozen=True)
class PeerRow:
    """What one peer measured on one recording, in the ghost world or on a scene.

    Attributes:
        peer: Peer name (``GHOST_PEERS`` or ``SCENE_PEERS``).
        pairs: Pairs watched (sphere pairs ``n (n - 1) / 2``, or active geom pairs).
        steps: Predictor steps after the initial one.
        time_us: Median wall time of one step (microseconds).
        time_us_p90: 90th percentile of the same.
        candidates_per_step: Pair evaluations (DUA, SA) or broadphase candidates per step
            (None where the library does not expose them).
        alarms_per_step: Alarmed pairs per step (what the exact stage must check).
        initial_alarms: Alarms of the initial classification (step 0; not judged).
        onsets: Collision onsets during the run.
        missed: Onsets not predicted.
        false_alarms: Alarms not followed by a collision within their horizon.
        open_alarms: Alarms whose horizon ends after the recorded trajectory, no collision seen.
        judged_alarms: Alarms whose horizon ends inside the recorded trajectory.
        lead_time_mean_s: Mean lead time of the predicted onsets (None if none).
        note: Anything the numbers need to be read right.
    """

    peer: str
    pairs: int
    steps: int
    time_us: float
    time_us_p90: float
    candidates_per_step: float | None
    alarms_per_step: float
    initial_alarms: int
    onsets: int
    missed: int
    false_alarms: int
    open_alarms: int
    judged_alarms: int
    lead_time_mean_s: float | None
    note: str = ""


# kw_only: the base ends with a defaulted field (note), which positional fields may not follow.
@dataclass(frozen=True, kw_only=True)
class GhostRow(PeerRow):
    """One peer at one N in the ghost world (see :class:`PeerRow`).

    Attributes:
        n: Spheres.
    """

    n: int


@dataclass(frozen=True, kw_only=True)
class SceneRow(PeerRow):
    """One peer on one bundled MuJoCo scene (see :class:`PeerRow`; units are active geom pairs).

    Attributes:
        scene: The bundled scene's name.
    """

    scene: str


def peer_measures(
    tracker: Tracker,
    truth: np.ndarray,
    last_step: int,
    times: npt.ArrayLike,
    candidates: Sequence[float],
    alarms: int,
    dt: float,
) -> dict[str, Any]:
    """The :class:`PeerRow` fields one run measured: all but ``peer``, ``pairs`` and ``note``.

    Args:
        tracker: The peer's alarm bookkeeping after the run.
        truth: Sorted collision keys ``pair * S + step`` of the recording (``truth_keys``).
        last_step: The recording's last step (alarms are judged up to it).
        times: ``(steps,)`` wall time of each step after the initial one (s).
        candidates: Candidates of the steps that reported them.
        alarms: Alarms over the steps after the initial one.
        dt: Predictor period (s).
    """
    t = np.asarray(times)
    steps = int(t.size)
    _, false, open_, judged = tracker.judge(truth, last_step)
    return {
        "steps": steps,
        "time_us": float(np.median(t) * 1e6),
        "time_us_p90": float(np.percentile(t, 90) * 1e6),
        "candidates_per_step": float(np.mean(candidates)) if candidates else None,
        "alarms_per_step": alarms / steps,
        "initial_alarms": tracker.initial,
        "onsets": tracker.onsets,
        "missed": tracker.missed,
        "false_alarms": false,
        "open_alarms": open_,
        "judged_alarms": judged,
        "lead_time_mean_s": tracker.lead_mean(dt),
    }


@dataclass(frozen=True)
class MemoryRow:
    """Memory and set-up cost of one peer's data structures at one N (measured in a subprocess).

    Attributes:
        peer: Peer name.
        n: Spheres.
        pairs: Sphere pairs.
        traced_mb: Peak of Python/numpy allocations while building and stepping (tracemalloc).
        rss_mb: Growth of the process's peak resident set over the build and the steps
            (includes C allocations tracemalloc cannot see, e.g. MuJoCo's and FCL's).
        build_s: Time to build the structure (DUA and SA: the initial classification).
        step_us: Median time of a step after the build.
        note: How the number was obtained.
    """

    peer: str
    n: int
    pairs: int
    traced_mb: float | None
    rss_mb: float
    build_s: float
    step_us: float
    note: str = ""


@dataclass(frozen=True)
class TunnelRow:
    """One case of the speculative-contact demonstration (a sphere driven at a thin plate).

    Attributes:
        case: Short description.
        accel: Applied acceleration (m/s^2) along +x.
        speed0: Initial speed (m/s) along +x.
        clearance: Initial surface distance between sphere and plate (m).
        crossing_step: The step during which the sphere's path reaches the plate.
        plain: Outcome without speculative contacts (``stopped``, ``tunneled``: no contact ever,
            ``penetrated``: a contact came too late).
        speculative: Outcome with ``mjENBL_SPECULATIVE``.
        speculative_contact_step: First step with a sphere-plate contact (speculative run;
            -1 if never).
        dua_alarm_step: Instant of DUA's first alarm on the sphere-plate pair (-1 if none).
        dua_lead_s: Time from DUA's first alarm to the crossing (None if no alarm).
    """

    case: str
    accel: float
    speed0: float
    clearance: float
    crossing_step: int
    plain: str
    speculative: str
    speculative_contact_step: int
    dua_alarm_step: int
    dua_lead_s: float | None
