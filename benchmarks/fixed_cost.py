"""``Predictor.step``'s fixed cost a call: what it costs when nothing is due (issue 20).

    python benchmarks/fixed_cost.py [--rounds 7] [--steps 20000]

Two free spheres 3 m apart, no gravity: no pair is ever due after the classification, so a
step is the call itself (the period check, the native step's entry, the violation check of two
bodies, the result). Each round times a loop of ``mj_step`` alone and a loop of ``mj_step`` and
``Predictor.step``, alternating; the fixed cost is the difference a step, median over rounds.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from dua_mujoco.runtime.predictor import Predictor

XML = """
<mujoco>
  <option gravity="0 0 0"/>
  <worldbody>
    <body pos="-1.5 0 0"><freejoint/><geom size="0.1"/></body>
    <body pos="1.5 0 0"><freejoint/><geom size="0.1"/></body>
  </worldbody>
</mujoco>
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--steps", type=int, default=20_000)
    args = ap.parse_args(argv)
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    p = Predictor(m, accel=1.0)
    plain, with_step = [], []
    for _ in range(args.rounds):
        t0 = time.perf_counter()
        for _ in range(args.steps):
            mujoco.mj_step(m, d)
        plain.append((time.perf_counter() - t0) / args.steps)
        p.reset(d)  # the plain loop moved the clock on
        t0 = time.perf_counter()
        for _ in range(args.steps):
            mujoco.mj_step(m, d)
            p.step(d)
        with_step.append((time.perf_counter() - t0) / args.steps)
    assert p.evaluations_per_step == 0, "a pair was due: the scene no longer isolates the call"
    fixed = np.median(np.array(with_step) - np.array(plain)) * 1e6
    print(
        f"mj_step alone {np.median(plain) * 1e6:.2f} us, with Predictor.step "
        f"{np.median(with_step) * 1e6:.2f} us: fixed cost {fixed:.2f} us a call "
        f"(median of {args.rounds} rounds of {args.steps:,})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
