"""Evaluations a step under two cheaper-or-tighter taus, on the robots where the plugin costs most.

The plugin's cost on these robots is its evaluations, and the deadline schedule revisits a pair
when its tau runs out. Per robot, this script measures what two changes to tau would do to them.

*A closed-form tau.* The tau kernel finds the first root of
``|x + v t| = eps + delta t + A t^2 / 2`` (docs/theory.md, section 1); on dmc_dog its lanes are
about 40 % of the plugin's time. ``|x + v t| >= |x| - |v| t`` gives a lower bound on that root in
closed form, one square root and one division:

    tau_c = 2 s / (w + sqrt(w^2 + 2 A s)),    s = |x| - eps,    w = |v| + delta

It is cheaper, and earlier: a pair is revisited sooner.

*Bounds per pair.* A pair's ``A`` is the sum of its two bodies' bounds, each a bound on every
point of its body. Two bodies that move together (links of one limb) could have a relative
acceleration well below that sum. The script measures it on the pilot's motion as the pilot
measures a body's (``MotionScreen``: the steps its level admits for both trees): the pilot's
safety factor times the largest second difference of the two centres' offset, per pair, and
the kernel's ``tau*`` with the smaller of the two bounds. It also counts the pairs whose offset
breaks that bound somewhere in the run (a pair bound the violation check would have to catch),
and those whose offset breaks the sum (then a body broke its own, and the check caught it).

*The geom pair's own gap (about the most a geom-pair tau could give).* A pair's tau is that of
two bounding spheres; a kernel on the geoms themselves (a capsule pair's segments, say) could
start from their distance instead. The script prices the best such a kernel could do: the same
root with the spheres' gap ``|x| - eps`` replaced by MuJoCo's distance between the two geoms
less the pair's margin (``mj_geomDistance``, exact on primitives), the centres' relative
velocity and the bounds kept. A sound tau on the geoms under the same bounds starts from that
gap at best, and its closing speed is that of the nearest points rather than the centres': the
evaluations this leaves are about the floor for any kernel that prices a pair from its geoms.
The same with the relative velocity taken as zero (``delta`` kept) shows whether the gap or the
motion sets the intervals.

Bounds come from plugin.py's pilot (``accel="auto"``, ``make_controller``'s random controls,
seed 99) and the run from the same kind of controller (seed 0). Every ``--every`` steps it takes
every sphere-sphere pair's taus, and the evaluations a step each would give the deadline
schedule: the sum over pairs of ``1 / interval(tau)``, the interval as the schedule sets it
(latency 0). ::

    python benchmarks/tau_variants.py                     # dmc_dog yam go1 franka_kitchen
    python benchmarks/tau_variants.py --robots dmc_dog --steps 600
    python benchmarks/tau_variants.py --accel 200          # a declared bound instead of auto
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from robots import robot_spec

from dua_mujoco import CoveringOptions, PilotOptions, Predictor
from dua_mujoco.build.pilot_screen import MotionScreen, PilotMotion, level_maxima
from dua_mujoco.core.urgency import time_to_collision
from dua_mujoco.exceptions import BoundViolationWarning
from dua_mujoco.models.scenes import make_controller

ROBOTS = ("dmc_dog", "yam", "go1", "franka_kitchen")
PILOT_SEED, RUN_SEED = 99, 0  # plugin.py's: the pilot's controls, and the run's


def _steps(p: Predictor, m: mujoco.MjModel, i: np.ndarray, j: np.ndarray, seed: int, steps: int):
    """Yield, after each ``mj_step`` under ``make_controller``'s random controls (``seed``): the
    ``MjData``, the pairs' centre offsets ``c_j - c_i`` and their velocities, ``(M, 3)`` each,
    and the ``(M,)`` norms of the offsets' second difference over the last three states (the
    pilot's discrete acceleration; zeros at the first two steps)."""
    d = mujoco.MjData(m)
    drive = make_controller(m, "random", seed=seed)
    mujoco.mj_forward(m, d)
    back: list[np.ndarray] = []
    for _ in range(steps):
        drive(m, d)
        mujoco.mj_step(m, d)
        c, u = p.sphere_states(d)
        x = c[j] - c[i]
        a = np.zeros(len(x))
        if len(back) == 2:
            a = np.linalg.norm(x - 2.0 * back[1] + back[0], axis=1) / (m.opt.timestep**2)
        back = [*back[-1:], x]
        yield d, x, u[j] - u[i], a


def _pilot(m: mujoco.MjModel) -> PilotOptions:
    """plugin.py's pilot: 1,000 steps of ``make_controller``'s random controls, seed 99."""
    controller = make_controller(m, "random", seed=PILOT_SEED)
    return PilotOptions(steps=1000, seed=PILOT_SEED, controller=controller)


def predictor_for(m: mujoco.MjModel, accel: str) -> Predictor:
    """The predictor of plugin.py's bounds: ``accel`` ``"auto"`` (its pilot) or m/s^2 declared."""
    cover = CoveringOptions(hfield="box")
    if accel == "auto":
        return Predictor(m, accel="auto", covering=cover, pilot=_pilot(m))
    return Predictor(m, accel=float(accel), covering=cover)


def sphere_pairs(p: Predictor) -> tuple[np.ndarray, ...]:
    """The sphere-sphere pairs of ``p``'s pair set: their spheres ``i``, ``j`` and their
    ``eps``, ``accel``, ``delta`` and ``speed``, ``(M,)`` each (the set's scalars broadcast)."""
    pairs, n = p.pair_set, len(p.pair_set)
    ids = np.flatnonzero(pairs.kind == 0)
    columns = (pairs.eps, pairs.accel, pairs.vel_uncertainty, pairs.speed)
    return (pairs.first[ids], pairs.second[ids], *(np.broadcast_to(c, (n,))[ids] for c in columns))


def _pair_accel(p: Predictor, m: mujoco.MjModel, i: np.ndarray, j: np.ndarray, pilot: PilotOptions):
    """``(M,)`` each pair's largest relative acceleration on the pilot's motion (its controller
    and seed), measured as the pilot measures a body's: at the steps where both trees pass the
    screen of the pilot's level; a pair that level never measured takes the next one's."""
    body = np.asarray(p.covering.sphere_body)
    bi, bj = body[i], body[j]
    screen = MotionScreen(m)
    largest = np.zeros((3, len(i)))
    measured = np.zeros((3, len(i)), dtype=bool)
    for k, (d, _, _, a) in enumerate(_steps(p, m, i, j, PILOT_SEED, pilot.steps)):
        free, calm = screen.update(d)
        if k < 2:
            continue
        levels = (free[bi] & free[bj], calm[bi] & calm[bj], np.ones(len(a), dtype=bool))
        for level, ok in enumerate(levels):
            np.maximum(largest[level], np.where(ok, a, 0.0), out=largest[level])
            measured[level] |= ok
    return level_maxima(largest, measured, PilotMotion(pilot.motion))


def geom_gap_eps(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    g1: np.ndarray,
    g2: np.ndarray,
    x: np.ndarray,
    margin: np.ndarray,
) -> np.ndarray:
    """``(M,)`` the contact distance that gives sphere pairs of centre offsets ``x`` ``(M, 3)``
    the gap of the geoms they cover, ``g1[k]`` and ``g2[k]``: ``|x| - eps`` is MuJoCo's distance
    between the two geoms less the pair's ``margin`` (at least 0: where that gap exceeds the
    centres' distance, eps is 0 and the gap ``|x|``, a lower tau). Each geom pair is asked once."""
    pairs, back = np.unique(np.stack([g1, g2], axis=1), axis=0, return_inverse=True)
    dist = np.array([mujoco.mj_geomDistance(m, d, int(a), int(b), 1e3, None) for a, b in pairs])
    gap = np.maximum(dist[back.ravel()] - margin, 0.0)
    return np.maximum(np.linalg.norm(x, axis=1) - gap, 0.0)


def measure(name: str, steps: int, every: int, accel_option: str) -> dict[str, float]:
    """Evaluations a step under ``tau*``, ``tau_c``, ``tau*`` with bounds per pair, and ``tau*``
    from the geoms' gap (with and without the velocity); quartiles of ``tau_c / tau*``; the
    share of pairs that break their pair bound in the run."""
    m = robot_spec(name).compile()
    pilot = _pilot(m)
    p = predictor_for(m, accel_option)
    dt = float(m.opt.timestep)
    i, j, eps, accel, delta, speed = sphere_pairs(p)
    geom = np.asarray(p.covering.sphere_geom)
    margin = eps - np.asarray(p.covering.sphere_radius)[i] - np.asarray(p.covering.sphere_radius)[j]
    own = pilot.safety * _pair_accel(p, m, i, j, pilot)
    pair_accel = np.minimum(accel, own)

    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    p.reset(d)
    cap = p.scheduler.max_interval  # the deadline schedule's longest interval

    def evaluations(tau: np.ndarray) -> float:
        return float(np.sum(1.0 / np.clip(np.floor(tau / dt), 1, cap)))

    kernel, closed, per_pair, ratios, on_geoms, at_rest = [], [], [], [], [], []
    broken = np.zeros(len(i), dtype=bool)
    broken_sum = np.zeros(len(i), dtype=bool)
    for k, (d, x, v, a) in enumerate(_steps(p, m, i, j, RUN_SEED, steps)):
        broken |= a > pair_accel
        broken_sum |= a > accel
        if k % every:
            continue
        with warnings.catch_warnings():
            # A pair faster than its speed bound falls back to the acceleration-only tau, as
            # the pair set's kernel does (the warning would repeat every sample).
            warnings.simplefilter("ignore", BoundViolationWarning)
            tau = time_to_collision(x, v, eps, accel, speed=speed, vel_uncertainty=delta)
            tau_p = time_to_collision(x, v, eps, pair_accel, speed=speed, vel_uncertainty=delta)
            eps_g = geom_gap_eps(m, d, geom[i], geom[j], x, margin)
            tau_g = time_to_collision(x, v, eps_g, accel, speed=speed, vel_uncertainty=delta)
            tau_r = time_to_collision(x, 0 * v, eps_g, accel, vel_uncertainty=delta)
        s = np.linalg.norm(x, axis=1) - eps
        w = np.linalg.norm(v, axis=1) + delta
        tau_c = np.where(s > 0, 2 * s / (w + np.sqrt(w * w + 2 * accel * np.maximum(s, 0))), 0)
        kernel.append(evaluations(tau))
        closed.append(evaluations(tau_c))
        per_pair.append(evaluations(tau_p))
        on_geoms.append(evaluations(tau_g))
        at_rest.append(evaluations(tau_r))
        ratios.append(tau_c[tau > 0] / tau[tau > 0])
    q = np.percentile(np.concatenate(ratios), [10, 50, 90])
    return dict(
        kernel=np.mean(kernel), closed=np.mean(closed), per_pair=np.mean(per_pair),
        q10=q[0], q50=q[1], q90=q[2], broken=100.0 * np.mean(broken),
        own=float(np.median(own / accel)), broken_sum=100.0 * np.mean(broken_sum),
        on_geoms=np.mean(on_geoms), at_rest=np.mean(at_rest), accel=float(np.median(accel)),
    )  # fmt: skip


def accel_option(text: str) -> str:
    """``--accel``: ``auto`` or a positive number of m/s^2 (kept as text for ``measure``)."""
    try:
        ok = text == "auto" or float(text) > 0
    except ValueError:
        ok = False
    if not ok:
        raise argparse.ArgumentTypeError(f"{text!r}: pass 'auto' or a positive number of m/s^2")
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="*", default=list(ROBOTS))
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--every", type=int, default=10, help="steps between samples")
    ap.add_argument(
        "--accel",
        type=accel_option,
        default="auto",
        help="'auto' (the pilot's) or a declared m/s^2",
    )
    args = ap.parse_args(argv)
    print(
        "| robot | sphere-sphere evaluations a step, tau* | with tau_c | ratio "
        "| tau_c / tau*: 10th percentile | median | 90th "
        "| pair's own bound / the sum, median | tau* with bounds per pair | ratio "
        "| pairs breaking theirs in the run | pairs breaking the sum "
        "| pair's A, median | tau* from the geoms' gap | ratio | the same at rest | ratio |"
    )
    print("|---" * 17 + "|")
    for k, name in enumerate(args.robots):
        print(f"{name} ({k + 1}/{len(args.robots)})", file=sys.stderr, flush=True)
        r = measure(name, args.steps, args.every, args.accel)
        print(
            f"| {name} | {r['kernel']:.0f} | {r['closed']:.0f} | {r['closed'] / r['kernel']:.3f} "
            f"| {r['q10']:.3f} | {r['q50']:.3f} | {r['q90']:.3f} | {r['own']:.2f} "
            f"| {r['per_pair']:.0f} "
            f"| {r['per_pair'] / r['kernel']:.3f} | {r['broken']:.1f} % "
            f"| {r['broken_sum']:.1f} % | {r['accel']:.0f} "
            f"| {r['on_geoms']:.0f} | {r['on_geoms'] / r['kernel']:.3f} "
            f"| {r['at_rest']:.0f} | {r['at_rest'] / r['kernel']:.3f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
