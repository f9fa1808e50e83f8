"""Speculative contacts against DUA: a sphere driven at a thin plate, with and without them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco

from dua_mujoco.build.options import CoveringOptions
from dua_mujoco.experiments.peers.horizon import LATENCY
from dua_mujoco.experiments.peers.rows import TunnelRow

__all__ = [
    "TUNNEL_DT",
    "TUNNEL_HALF_THICKNESS",
    "TUNNEL_HALF_WIDTH",
    "TUNNEL_RADIUS",
    "tunnel_cases",
    "tunnel_sweep",
]


TUNNEL_RADIUS = 0.01
TUNNEL_HALF_THICKNESS = 0.002
TUNNEL_DT = 0.002
TUNNEL_HALF_WIDTH = 0.05


def _tunnel_model(clearance: float, speculative: bool) -> mujoco.MjModel:
    """A free sphere at the origin and a thin static plate ahead of it along +x (no gravity)."""
    spec = mujoco.MjSpec()
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.timestep = TUNNEL_DT
    plate_x = TUNNEL_RADIUS + clearance + TUNNEL_HALF_THICKNESS
    spec.worldbody.add_geom(
        name="plate",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[plate_x, 0.0, 0.0],
        size=[TUNNEL_HALF_THICKNESS, TUNNEL_HALF_WIDTH, TUNNEL_HALF_WIDTH],
    )
    body = spec.worldbody.add_body(name="ball")
    body.add_freejoint()
    body.add_geom(
        name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[TUNNEL_RADIUS, 0, 0], mass=0.1
    )
    model = spec.compile()
    if speculative:
        model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SPECULATIVE)
    return model


def _tunnel_case(case: str, accel: float, speed0: float, clearance: float) -> TunnelRow:
    """Drive the sphere at the plate with and without speculative contacts; run DUA alongside.

    The push (a constant applied force) stops at the first contact, so a detected impact ends
    with the sphere stopped; "tunneled" means no contact was ever generated and the sphere ended
    beyond the plate, "penetrated" that a contact came too late to stop it.

    Instants: after ``mj_step`` number ``k``, ``qpos`` is instant ``k`` while ``geom_xpos`` and the
    contacts are instant ``k - 1`` (docs/discrete-time.md, section 1), so an alarm returned there
    is from instant ``k - 1``. The sphere reaches the plate during step ``crossing`` (between
    instants ``crossing - 1`` and ``crossing``); an alarm is in time if its instant is
    ``< crossing``.
    """
    from dua_mujoco import Predictor

    far_face = TUNNEL_RADIUS + clearance + 2 * TUNNEL_HALF_THICKNESS
    near_face = TUNNEL_RADIUS + clearance
    steps = 400
    outcomes = []
    first_contact = -1
    crossing = -1
    dua_instant = -1
    for speculative in (False, True):
        model = _tunnel_model(clearance, speculative)
        data = mujoco.MjData(model)
        body = model.body("ball").id
        data.qvel[0] = speed0
        data.xfrc_applied[body, 0] = accel * float(model.body_mass[body])
        mujoco.mj_forward(model, data)
        predictor = None
        if not speculative:
            # Exact bound: the only force is the applied one until contact.
            # Multi-sphere covering: the plate's single bounding sphere (radius 71 mm) would
            # swallow the ball and alarm from the first instant.
            predictor = Predictor(
                model,
                accel=accel * 1.000001 + 1e-9,
                latency=LATENCY,
                schedule="dua",
                covering=CoveringOptions(mode="multi", max_spheres_per_geom=64),
            )
            if len(predictor.reset(data)):
                dua_instant = 0
        touched = False
        for k in range(1, steps + 1):
            mujoco.mj_step(model, data)
            if predictor is not None:
                alarms = predictor.step(data)
                if dua_instant < 0 and len(alarms):
                    dua_instant = k - 1
            x = float(data.qpos[0])
            if not speculative and crossing < 0 and x + TUNNEL_RADIUS >= near_face:
                crossing = k
            if int(data.ncon) > 0:
                if not touched:
                    data.xfrc_applied[body, 0] = 0.0  # the push ends at impact
                touched = True
                if speculative and first_contact < 0:
                    first_contact = k
            if x - TUNNEL_RADIUS > far_face:
                break
        beyond = float(data.qpos[0]) - TUNNEL_RADIUS > far_face
        outcomes.append("stopped" if not beyond else ("penetrated" if touched else "tunneled"))
    lead = None
    if 0 <= dua_instant < crossing:
        lead = (crossing - dua_instant) * TUNNEL_DT
    return TunnelRow(
        case=case,
        accel=accel,
        speed0=speed0,
        clearance=clearance,
        crossing_step=crossing,
        plain=outcomes[0],
        speculative=outcomes[1],
        speculative_contact_step=first_contact,
        dua_alarm_step=dua_instant,
        dua_lead_s=lead,
    )


def tunnel_cases() -> list[TunnelRow]:
    """The demonstration's cases: slow, fast, and accelerated from rest into a one-step jump."""
    h = TUNNEL_DT
    thick = 2 * TUNNEL_RADIUS + 2 * TUNNEL_HALF_THICKNESS  # 24 mm to jump over
    return [
        _tunnel_case("slow, constant speed", 0.0, 0.5, 0.05),
        _tunnel_case("fast, constant speed (3 x thickness per step)", 0.0, 3 * thick / h, 0.05),
        # From rest: first-step displacement a h^2 jumps clearance + thickness.
        _tunnel_case("from rest, one-step jump", 2 * (0.005 + thick) / h**2, 0.0, 0.005),
        # From rest, hard push: the velocity term lags a h^2 behind every step.
        _tunnel_case("from rest, a = 1e4 m/s^2, 0.5 m away", 1e4, 0.0, 0.5),
        _tunnel_case("from rest, a = 1e5 m/s^2", 1e5, 0.0, 0.2),
        _tunnel_case("moving 2 m/s, a = 1e5 m/s^2", 1e5, 2.0, 0.05),
    ]


def tunnel_sweep(accels: Sequence[float], clearances: Sequence[float]) -> list[dict[str, Any]]:
    """Fraction of starts (at rest) that tunnel, per acceleration, over a range of clearances."""
    out = []
    for a in accels:
        rows = [_tunnel_case("sweep", a, 0.0, g) for g in clearances]
        out.append(
            {
                "accel": a,
                "starts": len(rows),
                "plain_tunneled": sum(r.plain == "tunneled" for r in rows),
                "plain_penetrated": sum(r.plain == "penetrated" for r in rows),
                "speculative_tunneled": sum(r.speculative == "tunneled" for r in rows),
                "speculative_penetrated": sum(r.speculative == "penetrated" for r in rows),
                "dua_alarmed_before_crossing": sum(
                    0 <= r.dua_alarm_step < r.crossing_step for r in rows
                ),
            }
        )
    return out
