"""The benchmark's tables, markdown."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
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


_Column = tuple[str, Callable[[dict[str, Any]], str]]
"""A table column: its header and the cell of one result row (a JSON dict)."""

_MEMORY_COLUMNS: tuple[_Column, ...] = (
    ("peer", lambda r: r["peer"]),
    ("pairs", lambda r: str(r["pairs"])),
    ("traced MB", lambda r: _cell(r["traced_mb"])),
    ("peak RSS growth MB", lambda r: _cell(r["rss_mb"])),
    ("build s", lambda r: _cell(r["build_s"], 2)),
    ("us/step", lambda r: _cell(r["step_us"])),
    ("what", lambda r: r["note"]),
)

_TUNNEL_COLUMNS: tuple[_Column, ...] = (
    ("case", lambda r: r["case"]),
    ("a m/s^2", lambda r: _cell(r["accel"], 0)),
    ("v0 m/s", lambda r: _cell(r["speed0"], 2)),
    ("clearance mm", lambda r: _cell(r["clearance"] * 1e3, 1)),
    ("reaches plate at step", lambda r: str(r["crossing_step"])),
    ("plain", lambda r: r["plain"]),
    ("speculative", lambda r: r["speculative"]),
    ("spec. contact step", lambda r: str(r["speculative_contact_step"])),
    ("DUA alarm step", lambda r: str(r["dua_alarm_step"])),
    ("DUA lead ms", lambda r: _lead_ms(r["dua_lead_s"])),
)

_TUNNEL_SWEEP_COLUMNS: tuple[_Column, ...] = (
    ("a m/s^2", lambda s: _cell(s["accel"], 0)),
    ("starts", lambda s: str(s["starts"])),
    (
        "plain: tunneled / penetrated",
        lambda s: f"{s['plain_tunneled']} / {s['plain_penetrated']}",
    ),
    (
        "speculative: tunneled / penetrated",
        lambda s: f"{s['speculative_tunneled']} / {s['speculative_penetrated']}",
    ),
    ("DUA alarmed before reaching the plate", lambda s: str(s["dua_alarmed_before_crossing"])),
)


def _columns_table(columns: Sequence[_Column], rows: Iterable[dict[str, Any]]) -> str:
    """A markdown table of ``rows`` with one column per ``(header, cell)`` pair."""
    body = [[cell(r) for _, cell in columns] for r in rows]
    return table([header for header, _ in columns], body)


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
        out.append(_columns_table(_MEMORY_COLUMNS, result["memory"]))
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
    out.append(_columns_table(_TUNNEL_COLUMNS, result["tunnel"]))
    out += ["", "Starts from rest over a range of clearances:", ""]
    out.append(_columns_table(_TUNNEL_SWEEP_COLUMNS, result["tunnel_sweep"]))
    return "\n".join(out) + "\n"
