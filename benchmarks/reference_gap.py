"""The predictor's standing pairs against an exact-geometry reference at one period, and why.

    python benchmarks/reference_gap.py                       # spot, shadow_hand, adroit
    python benchmarks/reference_gap.py go1 h1 --protocol smooth --steps 500

At every physics step (period 1, latency 0, so the horizon ``H`` is one timestep) every active
geom pair is judged by ``mj_geomDistance`` against the two geoms' reach over ``H``,
``(|v_c| + |w| rbound) H + A H^2 / 2`` each (``v_c`` the geom origin's velocity, ``w`` its body's
angular velocity, ``A`` the predictor's own bound of the geom's body): the reference R0 flags the
pair when the distance is below the sum. R2 adds the pair's contact distance and the bodies'
velocity uncertainty ``delta H`` (what ``benchmarks/exact.py`` calls the reference). Beside
them, on the same trajectory and the same bounds (``accel="auto"``, a pilot driven as the run
is): the predictor as it is, with ``alarm_backoff=1`` (a pair stands in alarm only on its latest
verdict, select-all's alarms), and with the exact level off as well (the bounding spheres'
urgency). Each pair-step the predictor stands and R0 does not is put down to the first of:
standing only by the backoff (not with ``alarm_backoff=1``), flagged by R2 (contact distance or
velocity uncertainty), standing only with the exact level (never seen), other.
"""

from __future__ import annotations

import argparse
import collections
import sys
from pathlib import Path

import mujoco
import numpy as np

from dua_mujoco.build.options import PilotOptions, ScheduleOptions, UrgencyOptions
from dua_mujoco.build.pairbounds import body_vel_uncertainty
from dua_mujoco.models.scenes import make_controller
from dua_mujoco.runtime.predictor import Predictor

sys.path.insert(0, str(Path(__file__).parent))
from robots import load_robot

PILOT_SEED = 1_000_003
ROLLOUT_SEED = 0
VARIANTS = {
    "predictor": {},
    "backoff 1": {"schedule": ScheduleOptions(alarm_backoff=1)},
    "backoff 1, exact off": {
        "schedule": ScheduleOptions(alarm_backoff=1),
        "urgency": UrgencyOptions(exact=False),
    },
}


def _standing(p: Predictor, ngp: int) -> np.ndarray:
    sched = p.scheduler
    assert sched is not None
    out = np.zeros(ngp, dtype=bool)
    np.logical_or.at(out, p.sphere_pairs.geom_pair, sched.alarm_state() & sched.active)
    return out


def measure(name: str, protocol: str, steps: int) -> dict:
    """Mean standing fractions and the reasons of the predictor's pair-steps beyond R0."""
    m = load_robot(name)
    pilot = make_controller(m, protocol, seed=PILOT_SEED)
    bounds = Predictor(m, pilot=PilotOptions(controller=pilot, seed=PILOT_SEED)).bounds
    preds = {k: Predictor(m, accel=bounds, **kw) for k, kw in VARIANTS.items()}
    p = preds["predictor"]
    gp = p.geom_pairs
    g1, g2 = np.asarray(gp.geom1), np.asarray(gp.geom2)
    ngp = g1.size
    body = np.asarray(m.geom_bodyid)
    accel = p.bounds.accel[body]
    delta = body_vel_uncertainty(m, p.bounds, period=1)[body]
    rbound = np.asarray(m.geom_rbound)
    types = np.asarray(m.geom_type)
    h = p.dt

    def tname(g: int) -> str:
        return mujoco.mjtGeom(int(types[g])).name[len("mjGEOM_") :].lower()

    kind = np.array([" - ".join(sorted((tname(a), tname(b)))) for a, b in zip(g1, g2, strict=True)])
    d = mujoco.MjData(m)
    ctrl = make_controller(m, protocol, seed=ROLLOUT_SEED)
    ctrl(m, d)
    mujoco.mj_step(m, d)
    for q in preds.values():
        q.reset(d)
    vel = np.empty(6)
    sums: collections.Counter[str] = collections.Counter()
    why: collections.Counter[str] = collections.Counter()
    by_kind: collections.Counter[str] = collections.Counter()
    for _ in range(steps):
        ctrl(m, d)
        mujoco.mj_step(m, d)
        stand = {}
        for label, q in preds.items():
            q.step(d)
            stand[label] = _standing(q, ngp)
            sums[label] += int(stand[label].sum())
        speed = np.empty(m.ngeom)
        for g in range(m.ngeom):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, g, vel, 0)
            speed[g] = np.linalg.norm(vel[3:]) + np.linalg.norm(vel[:3]) * rbound[g]
        reach0 = speed * h + accel * h * h / 2
        reach2 = reach0 + delta * h
        dist = np.array(
            [
                mujoco.mj_geomDistance(m, d, int(a), int(b), 10.0, None)
                for a, b in zip(g1, g2, strict=True)
            ]
        )
        r0 = dist < reach0[g1] + reach0[g2]
        r2 = dist < np.asarray(gp.contact_distance) + reach2[g1] + reach2[g2]
        sums["R0"] += int(r0.sum())
        sums["R2"] += int(r2.sum())
        for i in np.flatnonzero(stand["predictor"] & ~r0):
            if not stand["backoff 1"][i]:
                why["backoff"] += 1
            elif r2[i]:
                why["R2 flags it"] += 1
            elif not stand["backoff 1, exact off"][i]:
                why["exact level only"] += 1
            else:
                why["other"] += 1
            by_kind[str(kind[i])] += 1
    total = steps * ngp
    return {
        "robot": name,
        "protocol": protocol,
        "pairs": ngp,
        **{k: v / total for k, v in sums.items()},
        "why": dict(why),
        "by_kind": dict(by_kind),
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("robots", nargs="*", default=["spot", "shadow_hand", "adroit"])
    ap.add_argument("--protocol", choices=["random", "smooth"], nargs="+", default=["random"])
    ap.add_argument("--steps", type=int, default=800)
    args = ap.parse_args(argv)
    cols = [*VARIANTS, "R0", "R2"]
    print(
        "| robot | drive | pairs | "
        + " | ".join(cols)
        + " | predictor / R0 | pair-steps beyond R0: why | by geom types |"
    )
    print("|---" * (len(cols) + 6) + "|")
    for name in args.robots:
        for protocol in args.protocol:
            r = measure(name, protocol, args.steps)
            ratio = r["predictor"] / r["R0"] if r["R0"] else float("inf")
            print(
                f"| {name} | {protocol} | {r['pairs']} | "
                + " | ".join(f"{100 * r[c]:.2f} %" for c in cols)
                + f" | {ratio:.2f} | {r['why']} | {r['by_kind']} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
