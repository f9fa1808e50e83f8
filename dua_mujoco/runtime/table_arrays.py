"""What a predictor's native runtime reads, as named float64 tables.

A :class:`~dua_mujoco.Predictor` builds its covering, pairs, bounds, static shapes, exact level,
violation check and (pruned) reach in Python, then hands them to the native core as the tables
below: the same tables :func:`dua_mujoco.attach` writes into a model for the MuJoCo plugin, which
reads them back from text fields. Either way the core checks every table against the model
(``csrc/src/tables.cc``) and runs the same ``Runtime`` on them, so the Python predictor and the
plugin make one prediction.

The tables, by name (rows x columns; the columns are ``dua_mujoco._core.LAYOUT``'s):

- ``config``: the ``CFG_*`` entries (schedule, timestep, exact level, the model's fingerprint,
  pruned pairs' options).
- ``spheres`` (nsphere, 8), ``shapes`` (nshape, 16), ``pairs`` (npair, 8), ``pair_geom``
  (npair,), ``geom_pairs`` (ngp, 2), ``geom_pair_contact`` (ngp, 2: MuJoCo's margin and gap).
- ``events_rec`` (nchecked, 12), ``events_params`` (2,): the violation check.
- with the exact level: ``exact_geoms`` (ngeom, 24), ``exact_records`` (npair, 10).
- pruned pairs: ``reach`` (nsphere, 4), and what learning a pair reads: ``filter`` (ngeom, 7),
  ``exclude``, ``contact`` (ngeom, 2), ``geom_start`` (ngeom + 1,), ``geom_lone`` (ngeom, 2),
  ``plane_geom``, ``shape_geom``, ``body_bounds`` (nbody, 3).
"""

from __future__ import annotations

from typing import Protocol

import mujoco
import numpy as np

from dua_mujoco._core import LAYOUT, structure_hash
from dua_mujoco.build.bounds import MotionBounds
from dua_mujoco.build.covering import Covering
from dua_mujoco.build.events import EventTable, no_events
from dua_mujoco.build.filter import contacts_enabled, margin_override
from dua_mujoco.build.mocap import PredictorMocap
from dua_mujoco.build.pairbounds import body_vel_uncertainty
from dua_mujoco.build.pairfilter import FilterTables
from dua_mujoco.build.pruning import RENEW_MAX, Reach
from dua_mujoco.build.universe import PairUniverse
from dua_mujoco.core.schedules import Schedule, schedule_config

__all__ = ["CONFIG", "TableSource", "predictor_tables"]

CONFIG = {name[4:].lower(): value for name, value in LAYOUT.items() if name.startswith("CFG_")}
"""The ``config`` table's entries by name (``CONFIG["dt"]`` is its index of ``dt``)."""


class TableSource(Protocol):
    """What :func:`predictor_tables` reads off a :class:`~dua_mujoco.Predictor` (a protocol,
    not the class: the predictor's module imports this one)."""

    model: mujoco.MjModel
    period: int
    dt: float
    latency: int
    alarm_periods: int
    schedule: Schedule
    slots_per_bucket: int
    max_evals_per_step: int | None
    alarm_backoff: int
    covering: Covering
    universe: PairUniverse
    bounds: MotionBounds
    mocap: PredictorMocap | None
    events: EventTable | None
    reach: Reach | None

    @property
    def sphere_records(self) -> np.ndarray: ...

    @property
    def shape_records(self) -> np.ndarray: ...


def predictor_tables(p: TableSource) -> dict[str, np.ndarray]:
    """The tables of predictor ``p`` (its pairs as it knows them when built: every active pair,
    or, pruned, those held always; the runtime learns the rest)."""
    m = p.model
    c = schedule_config(
        p.schedule,
        dt=p.dt,
        latency=p.latency,
        alarm_periods=p.alarm_periods,
        slots_per_bucket=p.slots_per_bucket,
        max_evals_per_step=p.max_evals_per_step,
        alarm_backoff=p.alarm_backoff,
    )
    c[CONFIG["timestep"]] = float(m.opt.timestep)
    exact = p.universe.exact
    c[CONFIG["exact_on"]] = exact is not None
    if exact is not None:
        c[CONFIG["exact_below"]], c[CONFIG["query_below"]] = exact.exact_below, exact.query_below
    shape = structure_hash(m)
    c[CONFIG["ngeom"]], c[CONFIG["nbody"]] = m.ngeom, m.nbody
    c[CONFIG["shape"]], c[CONFIG["shape"] + 1] = shape & 0xFFFFFFFF, shape >> 32
    u = p.universe
    gp = u.geom_pairs
    events = no_events() if p.events is None else p.events
    tables = {
        "config": c,
        "spheres": p.sphere_records,
        # (static_shapes' placeholder row, for a model without static shapes, is not a shape)
        "shapes": p.shape_records if p.covering.nshape else np.zeros((0, p.shape_records.shape[1])),
        "pairs": u.records,
        "pair_geom": np.asarray(u.sphere_pairs.geom_pair),
        "geom_pairs": np.stack([gp.geom1, gp.geom2], axis=1),
        "geom_pair_contact": np.stack([gp.margin, gp.gap], axis=1),
        "events_rec": events.records,
        "events_params": events.params,
    }
    if exact is not None:
        tables.update(exact_geoms=exact.geoms, exact_records=exact.records)
    reach = p.reach
    if reach is not None:
        c[CONFIG["pruned"]] = 1
        c[CONFIG["horizon"]], c[CONFIG["margin"]] = reach.horizon, reach.margin
        c[CONFIG["stride"]], c[CONFIG["renew_max"]] = reach.stride, RENEW_MAX
        tables["reach"] = reach.table
        tables.update(_learn_tables(p, c))
    return {name: np.ascontiguousarray(t, dtype=np.float64) for name, t in tables.items()}


def _learn_tables(p: TableSource, config: np.ndarray) -> dict[str, np.ndarray]:
    """What a pruned runtime reads to learn a pair as MuJoCo's filter lets it through: the
    filter per geom, margins and gaps, the covering's per-geom layout, each body's bounds (and
    their entries of ``config``)."""
    m, cov, b = p.model, p.covering, p.bounds
    ft = FilterTables.of(m)
    o_margin = margin_override(m)
    config[CONFIG["contacts"]] = contacts_enabled(m)
    config[CONFIG["filter_parent"]] = ft.filterparent
    config[CONFIG["override"]] = o_margin is not None
    config[CONFIG["o_margin"]] = 0.0 if o_margin is None else o_margin
    config[CONFIG["has_speed"]] = b.speed is not None
    delta = body_vel_uncertainty(m, b, period=p.period, mocap=p.mocap)
    speed = np.full(m.nbody, np.inf) if b.speed is None else b.speed
    filt = [ft.body, ft.weld, ft.parent_weld, ft.movable, ft.contype, ft.conaffinity, ft.lone]
    return {
        "filter": np.stack([np.asarray(a, dtype=np.float64) for a in filt], axis=1),
        "exclude": ft.exclude,
        "contact": np.stack([m.geom_margin, m.geom_gap], axis=1),
        "geom_start": cov.geom_sphere_start,
        "geom_lone": np.stack([cov.geom_plane, cov.geom_shape], axis=1),
        "plane_geom": np.asarray(cov.plane_geom),
        "shape_geom": np.asarray(cov.shape_geom),
        "body_bounds": np.stack([b.accel, delta, speed], axis=1),
    }
