"""A predictor's tables, built by functions of the model and the options.

:func:`layout` checks the options and fixes what they fix before the bounds (the covering, the
pairs known at the start, the exact level, the boxes whose corners the bounds limit);
:func:`pilot_bounds` measures the bounds ``accel="auto"`` stands for at those corners;
:func:`build` makes the tables under the bounds: the static shapes, the violation check, the
(pruned) reach and the named float64 arrays the native core reads. A
:class:`~dua_mujoco.Predictor` stores what ``build`` returns; :func:`dua_mujoco.attach` writes the
same arrays into a model for the MuJoCo plugin, which reads them back from text fields. Either
way the core checks every table against the model (``csrc/src/tables.cc``) and runs the same
``Runtime`` on them, so the Python predictor and the plugin make one prediction.

The tables, by name (rows x columns; the columns are ``dua_mujoco._core.LAYOUT``'s):

- ``config``: the ``CFG_*`` entries (schedule, timestep, exact level, the model's fingerprint,
  pruned pairs' options).
- ``spheres`` (nsphere, 8), ``shapes`` (nshape, 16), ``pairs`` (npair, 8), ``pair_geom``
  (npair,), ``geom_pairs`` (ngp, 2), ``geom_pair_contact`` (ngp, 2: MuJoCo's margin and gap).
- ``static`` (nshape, 18): the static guard (``_core.static_records``): each static shape's geom,
  its pose, ``geom_size`` and a digest of its height field or mesh, as the shapes were built
  from them; the plugin and ``Predictor.reset`` refuse a model whose static geoms differ.
- ``events_rec`` (nchecked, 12), ``events_params`` (2,): the violation check.
- with the exact level: ``exact_geoms`` (ngeom, 24), ``exact_records`` (npair, 10).
- pruned pairs: ``reach`` (nsphere, 4), and what learning a pair reads: ``filter`` (ngeom, 7),
  ``exclude``, ``contact`` (ngeom, 2), ``geom_start`` (ngeom + 1,), ``geom_lone`` (ngeom, 2),
  ``plane_geom``, ``shape_geom``, ``body_bounds`` (nbody, 3).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, TypedDict

import mujoco
import numpy as np

from dua_mujoco._core import LAYOUT, static_records, structure_hash
from dua_mujoco.build.bounds import MotionBounds, estimate_bounds, with_speed
from dua_mujoco.build.covering import Covering, CoveringMode, cover_model
from dua_mujoco.build.events import BodyBoxes, EventTable, body_boxes, build_events, no_events
from dua_mujoco.build.exact import EXACT_PERIODS, QUERY_PERIODS
from dua_mujoco.build.filter import contacts_enabled, margin_override
from dua_mujoco.build.kinematics import pack_spheres
from dua_mujoco.build.mocap import PredictorMocap
from dua_mujoco.build.options import (
    CoveringOptions,
    PairOptions,
    PilotOptions,
    PredictorOptions,
    ScheduleOptions,
    UrgencyOptions,
    alarm_periods,
    removed_keywords_error,
    resolve_options,
)
from dua_mujoco.build.pairbounds import body_vel_uncertainty
from dua_mujoco.build.pairfilter import FilterTables
from dua_mujoco.build.pruning import RENEW_MAX, Reach, reach_for
from dua_mujoco.build.tables import check_model, static_shapes
from dua_mujoco.build.universe import PairUniverse
from dua_mujoco.core.schedules import Schedule, as_schedule, schedule_config
from dua_mujoco.core.spheres import PairMode, pair_mode
from dua_mujoco.core.validate import check_int, check_period

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "CONFIG",
    "Built",
    "Layout",
    "LayoutOptions",
    "build",
    "layout",
    "measure_pilot",
    "pilot_bounds",
]

CONFIG = {name[4:].lower(): value for name, value in LAYOUT.items() if name.startswith("CFG_")}
"""The ``config`` table's entries by name (``CONFIG["dt"]`` is its index of ``dt``)."""


@dataclass(frozen=True)
class Layout:
    """What a predictor's model and options fix before its bounds (:func:`layout`): the
    period (physics steps) and ``dt`` (seconds), the latency and the alarm horizon (periods),
    the option groups, the covering, whether the pairs are pruned, the pairs known at the start
    (no bounds yet) and the boxes: one a body around its covering spheres and the exact level's
    geoms."""

    model: mujoco.MjModel
    period: int
    dt: float
    latency: int
    alarm_periods: int
    ahead: int  # the periods past the next step a verdict must see (exact level, reach)
    options: PredictorOptions
    covering: Covering
    pruned: bool
    universe: PairUniverse
    boxes: BodyBoxes

    @property
    def points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(geom, body, offset)`` of the points whose motion the bounds limit: the corners of
        the boxes (``Predictor.bound_points``)."""
        return self.boxes.corners()


class LayoutOptions(TypedDict, total=False):
    """The keyword options that fix a predictor's layout: ``Predictor``'s (each documented
    there) but the bounds, as :func:`layout`, :func:`pilot_bounds` and ``Predictor`` take them
    (their defaults are :func:`layout`'s)."""

    period: int
    latency: int
    alarm_horizon: float | None
    covering: Covering | CoveringOptions | CoveringMode | str
    schedule: ScheduleOptions | Schedule | str
    urgency: UrgencyOptions
    pilot: PilotOptions
    pairs: PairOptions | PairMode | str


def layout(model: mujoco.MjModel, **options: Unpack[LayoutOptions]) -> Layout:
    """The options checked and the pieces they fix before the bounds (``Predictor``'s
    keywords, the same checks and messages; a keyword it does not take names its new home or
    the valid ones)."""
    if set(options) - LayoutOptions.__optional_keys__:
        raise removed_keywords_error(
            {k: v for k, v in options.items() if k not in LayoutOptions.__optional_keys__}
        )
    period = options.get("period", 1)
    latency = options.get("latency", 0)
    covering = options.get("covering", "bounding")
    schedule = options.get("schedule", Schedule.DEADLINE)
    urgency, pilot = options.get("urgency", UrgencyOptions()), options.get("pilot", PilotOptions())
    fix = ": load it with mujoco.MjModel.from_xml_path(path) (or dua_mujoco.load_scene(name))"
    check_model(model, fix)
    period = check_int("period", period)
    # The schedule's options are checked now rather than at reset(): same checks, same messages.
    dt, latency = check_period(period * float(model.opt.timestep), latency)
    periods = alarm_periods(options.get("alarm_horizon"), dt)
    groups = resolve_options(covering, schedule, urgency, pilot, options.get("pairs", "auto"))
    kind = as_schedule(groups.schedule.kind)
    # CoveringOptions' fields are cover_model's keywords.
    cov = (
        covering
        if isinstance(covering, Covering)
        else cover_model(model, **asdict(groups.covering))
    )
    mode = pair_mode(
        groups.pairs.mode,
        groups.pairs.horizon,
        nsphere=cov.nsphere,
        deadline=kind is Schedule.DEADLINE,
    )
    ahead = latency + periods - 1
    exact = None
    if groups.urgency.exact:
        below = groups.urgency.exact_below
        # Looks can clear an alarm (or lengthen a wait) only below the alarm horizon.
        below = (EXACT_PERIODS + ahead) * dt if below is None else below
        exact = (below, (QUERY_PERIODS + ahead) * dt)
    universe = PairUniverse(model, cov, lazy=mode is PairMode.PRUNED, exact=exact)
    spheres = (cov.sphere_geom, cov.sphere_body, cov.sphere_offset)
    if universe.exact is not None:
        spheres = universe.exact.with_corners(model, spheres, universe.exact_geoms())
    boxes = body_boxes(model, spheres)
    pruned = mode is PairMode.PRUNED
    return Layout(model, period, dt, latency, periods, ahead, groups, cov, pruned, universe, boxes)


def pilot_bounds(
    model: mujoco.MjModel,
    *,
    speed: float | Mapping[str, float] | None = None,
    **options: Unpack[LayoutOptions],
) -> MotionBounds:
    """The bounds ``Predictor(model, accel="auto", speed=speed, **options)`` measures: a pilot
    rollout (``options``' ``pilot``) over the points that predictor's bounds limit
    (``Predictor.bound_points``). ``Predictor(model, accel=pilot_bounds(model, **options),
    **options)`` raises the same alarms as ``accel="auto"``.

    Args:
        speed: A declared speed bound kept on top (scalar or dict by body name).
        **options: ``Predictor``'s keyword options but the bounds (``period``, ``covering``,
            ``urgency``, ``pairs``, ``pilot``, ...).

    Returns:
        The bounds, ``source="auto"``.
    """
    return measure_pilot(layout(model, **options), speed)


def measure_pilot(lay: Layout, speed: float | Mapping[str, float] | None) -> MotionBounds:
    """:func:`pilot_bounds` of a ready layout."""
    pilot = lay.options.pilot
    ctrl = pilot.controller
    bounds = estimate_bounds(
        lay.model,
        steps=pilot.steps,
        seed=pilot.seed,
        safety=pilot.safety,
        controller=None if ctrl is None else lambda m, d, rng: ctrl(m, d),
        spheres=lay.points,
        with_speed=False,
        motion=pilot.motion,
    )
    return with_speed(lay.model, bounds, speed)


@dataclass(frozen=True)
class Built:
    """A predictor's tables (:func:`build`): what its objects keep (the static shape records
    ``(nshape, 16)``, the packed spheres ``(nsphere, 8)``, the violation check and the pruned
    pairs' reach, None when off) and ``arrays``, the tables the native runtime reads by name."""

    layout: Layout
    bounds: MotionBounds
    shapes: np.ndarray
    spheres: np.ndarray
    events: EventTable | None
    reach: Reach | None
    arrays: dict[str, np.ndarray]


def build(lay: Layout, bounds: MotionBounds, *, mocap: PredictorMocap | None) -> Built:
    """The tables of a predictor of layout ``lay`` under ``bounds`` (its pairs as it knows them
    when built: every active pair, or, pruned, those held always; the runtime learns the rest).
    Binds ``lay.universe`` to the bounds."""
    m, cov = lay.model, lay.covering
    # Static shape records: their poses are model constants, checked against the data at
    # each reset.
    shapes = static_shapes(m, cov.shape_geom)
    lay.universe.bind(bounds, period=lay.period, mocap=mocap, shapes=shapes)
    sched = lay.options.schedule
    events = (
        build_events(m, lay.boxes, bounds, period=lay.period) if sched.violation_events else None
    )
    spheres = pack_spheres(cov.sphere_geom, cov.sphere_body, cov.sphere_offset, m.body_rootid)
    delta = body_vel_uncertainty(m, bounds, period=lay.period, mocap=mocap)
    reach = None
    if lay.pruned:
        horizon = lay.options.pairs.horizon
        reach = reach_for(
            lay.universe, horizon, bounds=bounds, delta=delta, dt=lay.dt, ahead=lay.ahead
        )
    c = schedule_config(
        as_schedule(sched.kind),
        dt=lay.dt,
        latency=lay.latency,
        alarm_periods=lay.alarm_periods,
        slots_per_bucket=sched.slots_per_bucket,
        max_evals_per_step=sched.max_evals_per_step,
        alarm_backoff=sched.alarm_backoff,
        screen=sched.screen,
    )
    c[CONFIG["timestep"]] = float(m.opt.timestep)
    u = lay.universe
    exact = u.exact
    c[CONFIG["exact_on"]] = exact is not None
    if exact is not None:
        c[CONFIG["exact_below"]], c[CONFIG["query_below"]] = exact.exact_below, exact.query_below
    shape = structure_hash(m)
    c[CONFIG["ngeom"]], c[CONFIG["nbody"]] = m.ngeom, m.nbody
    c[CONFIG["shape"]], c[CONFIG["shape"] + 1] = shape & 0xFFFFFFFF, shape >> 32
    gp = u.geom_pairs
    ev = no_events() if events is None else events
    tables = {
        "config": c,
        "spheres": spheres,
        # (static_shapes' placeholder row, for a model without static shapes, is not a shape)
        "shapes": shapes if cov.nshape else np.zeros((0, shapes.shape[1])),
        "static": static_records(m, np.asarray(cov.shape_geom, dtype=np.int64)),
        "pairs": u.records,
        "pair_geom": np.asarray(u.sphere_pairs.geom_pair),
        "geom_pairs": np.stack([gp.geom1, gp.geom2], axis=1),
        "geom_pair_contact": np.stack([gp.margin, gp.gap], axis=1),
        "events_rec": ev.records,
        "events_params": ev.params,
    }
    if exact is not None:
        tables.update(exact_geoms=exact.geoms, exact_records=exact.records)
    if reach is not None:
        c[CONFIG["pruned"]] = 1
        c[CONFIG["horizon"]], c[CONFIG["margin"]] = reach.horizon, reach.margin
        c[CONFIG["stride"]], c[CONFIG["renew_max"]] = reach.stride, RENEW_MAX
        tables["reach"] = reach.table
        tables.update(_learn_tables(m, cov, bounds, delta, c))
    arrays = {name: np.ascontiguousarray(t, dtype=np.float64) for name, t in tables.items()}
    return Built(lay, bounds, shapes, spheres, events, reach, arrays)


def _learn_tables(
    m: mujoco.MjModel, cov: Covering, b: MotionBounds, delta: np.ndarray, config: np.ndarray
) -> dict[str, np.ndarray]:
    """What a pruned runtime reads to learn a pair as MuJoCo's filter lets it through: the
    filter per geom, margins and gaps, the covering's per-geom layout, each body's bounds (and
    their entries of ``config``)."""
    ft = FilterTables.of(m)
    o_margin = margin_override(m)
    config[CONFIG["contacts"]] = contacts_enabled(m)
    config[CONFIG["filter_parent"]] = ft.filterparent
    config[CONFIG["override"]] = o_margin is not None
    config[CONFIG["o_margin"]] = 0.0 if o_margin is None else o_margin
    config[CONFIG["has_speed"]] = b.speed is not None
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
