"""The benchmark's tables, markdown."""

from __future__ import annotations

from typing import Any

from dua_mujoco.experiments.peers.tunnel import (
    TUNNEL_DT,
    TUNNEL_HALF_THICKNESS,
    TUNNEL_HALF_WIDTH,
    TUNNEL_RADIUS,
)
from dua_mujoco.experiments.report import fmt, table

__all__ = ["markdown"]


def _cell(x: float | None, digits: int = 1) -> str:
    # The peers' cell style: "n/a" where a peer has no value, large numbers as 1e+05.
    return fmt(x, digits, missing="n/a", compact=True)


def _lead_ms(x: float | None) -> str:
    return "n/a" if x is None else f"{x * 1e3:.0f}"


# The columns shared by the ghost-world and scene tables (GhostRow / SceneRow fields).
_PEER_HEADER = (
    "peer",
    "us/step",
    "candidates/step",
    "alarms/step",
    "initial alarms",
    "onsets",
    "missed",
    "false",
    "open",
    "lead ms",
)


def _peer_cells(r: dict[str, Any]) -> list[str]:
    """The ``_PEER_HEADER`` cells of one ``GhostRow`` or ``SceneRow`` (as a JSON dict)."""
    return [
        r["peer"],
        _cell(r["time_us"]),
        _cell(r["candidates_per_step"]),
        _cell(r["alarms_per_step"], 2),
        str(r["initial_alarms"]),
        str(r["onsets"]),
        str(r["missed"]),
        str(r["false_alarms"]),
        str(r["open_alarms"]),
        _lead_ms(r["lead_time_mean_s"]),
    ]


def markdown(result: dict[str, Any]) -> str:
    """The tables of a :func:`run_peers` result as markdown."""
    meta = result["meta"]
    out = [
        "# DUA against its peers",
        "",
        f"Run: {'quick' if meta['quick'] else 'full'}, latency {meta['latency']}, "
        f"MuJoCo {meta['mujoco']}, {meta['cpus']} CPUs (every peer on one thread; load average "
        f"{meta['load_average'][0]:.1f} -> {meta['load_average'][1]:.1f}), "
        f"{result['runtime_s']:.0f} s.",
        "",
    ]
    out += [f"Note: {n}" for n in meta["notes"]]
    out += [
        "## Ghost world (SphereWorld, the paper's density)",
        "",
        f"{meta['ghost_steps']} predictor steps of 10 ms; alarms judged on "
        f"{meta['ghost_truth_steps']} recorded steps. Time: median per step (us). "
        "Candidates: pair evaluations (DUA, SA) or broadphase candidates per step. Initial alarms: "
        "those of the step-0 classification (not judged). False / open: alarms of steps >= 1 with "
        "no collision within their horizon / horizon past the recording.",
        "",
    ]
    body = [[str(r["n"]), *_peer_cells(r)] for r in result["ghost"]]
    out.append(table(["N", *_PEER_HEADER], body))
    if result["scenes"]:
        out += [
            "",
            "## Bundled MuJoCo scenes",
            "",
            f"{meta['scene_steps']} physics steps, random controls; units are active geom pairs; "
            "ground truth: MuJoCo's contacts. Bounds: each scene's accel hint.",
            "",
        ]
        body = [[r["scene"], *_peer_cells(r)] for r in result["scenes"]]
        out.append(table(["scene", *_PEER_HEADER], body))
    if result["memory"]:
        n = result["memory"][0]["n"]
        out += ["", f"## Memory at N = {n}", ""]
        body = [
            [
                r["peer"],
                str(r["pairs"]),
                _cell(r["traced_mb"]),
                _cell(r["rss_mb"]),
                _cell(r["build_s"], 2),
                _cell(r["step_us"]),
                r["note"],
            ]
            for r in result["memory"]
        ]
        out.append(
            table(
                ["peer", "pairs", "traced MB", "peak RSS growth MB", "build s", "us/step", "what"],
                body,
            )
        )
    out += [
        "",
        "## Speculative contacts: a sphere driven at a 4 mm plate",
        "",
        f"Sphere radius {TUNNEL_RADIUS * 1e3:.0f} mm, plate {2 * TUNNEL_HALF_THICKNESS * 1e3:.0f}"
        f" mm thick ({2 * TUNNEL_HALF_WIDTH * 1e3:.0f} mm square), timestep "
        f"{TUNNEL_DT * 1e3:.0f} ms, constant push along +x until the first contact, gravity off. "
        "DUA (multi-sphere covering, exact acceleration bound, latency 1) watches the plain "
        "simulation; its alarm instant must precede the step during which the sphere reaches "
        "the plate.",
        "",
    ]
    body = [
        [
            r["case"],
            _cell(r["accel"], 0),
            _cell(r["speed0"], 2),
            _cell(r["clearance"] * 1e3, 1),
            str(r["crossing_step"]),
            r["plain"],
            r["speculative"],
            str(r["speculative_contact_step"]),
            str(r["dua_alarm_step"]),
            _lead_ms(r["dua_lead_s"]),
        ]
        for r in result["tunnel"]
    ]
    out.append(
        table(
            [
                "case",
                "a m/s^2",
                "v0 m/s",
                "clearance mm",
                "reaches plate at step",
                "plain",
                "speculative",
                "spec. contact step",
                "DUA alarm step",
                "DUA lead ms",
            ],
            body,
        )
    )
    out += ["", "Starts from rest over a range of clearances:", ""]
    body = [
        [
            _cell(s["accel"], 0),
            str(s["starts"]),
            f"{s['plain_tunneled']} / {s['plain_penetrated']}",
            f"{s['speculative_tunneled']} / {s['speculative_penetrated']}",
            str(s["dua_alarmed_before_crossing"]),
        ]
        for s in result["tunnel_sweep"]
    ]
    out.append(
        table(
            [
                "a m/s^2",
                "starts",
                "plain: tunneled / penetrated",
                "speculative: tunneled / penetrated",
                "DUA alarmed before reaching the plate",
            ],
            body,
        )
    )
    return "\n".join(out) + "\n"
