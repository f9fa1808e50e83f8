"""The predictor inside ``mj_step``: the MuJoCo sensor plugin ``dua_mujoco.predictor``.

:func:`attach` adds the plugin to a ``mujoco.MjSpec``: one plugin instance, one sensor of
:data:`OUTPUTS`, and the tables the step reads (everything a :class:`~dua_mujoco.Predictor` of the
same options computes at construction: the covering, the pairs and their bounds, the static
shapes, the exact level's records, the violation check's boxes, the schedule's parameters) as
custom text fields ``<prefix>:<table>``. ``spec.compile()`` then gives a model whose every
``mj_step`` predicts, in Python or in any C or C++ program (``simulate`` included) that loads
``libdua_mujoco.so`` (docs/plugin.md). The step is the native core's, the same code
``Predictor.step`` runs.

Each table is written as its entry count followed by the entries' float64 bytes in base64:
MuJoCo writes custom numeric fields to XML with six significant digits, which would round the
bounds, and text fields verbatim; base64 decodes exactly and fast (hexadecimal floats, tried
first, took ``strtod`` 80 ms a ``MjData`` on a robot with meshes).

The plugin's state lives in each ``MjData`` (``mj_copyData`` copies it, ``mj_resetData`` starts it
over), so copies, resets and ``mujoco.rollout`` on several threads keep their runs apart.
"""

from __future__ import annotations

import base64
import ctypes
import functools
from typing import Any, NamedTuple

import mujoco
import numpy as np

from dua_mujoco.core.schedules.state import NPARAMS
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.mj.events import no_events
from dua_mujoco.mj.options import PairOptions
from dua_mujoco.mj.predictor import Predictor
from dua_mujoco.mj.pruning import RENEW_MAX
from dua_mujoco.native import ABI_VERSION, declare, library

__all__ = [
    "MAX_GEOM_PAIRS",
    "OUTPUTS",
    "PLUGIN_NAME",
    "PluginOutputs",
    "attach",
    "deactivate_contacts",
    "plugin_outputs",
    "set_active_bodies",
    "standing_pairs",
]

PLUGIN_NAME = "dua_mujoco.predictor"

OUTPUTS = ("standing", "min_tau", "evaluated", "deferred", "flagged")
"""The sensor's outputs, in order (:class:`PluginOutputs`)."""

# Entries of the "<prefix>:config" row (the plugin's kCfg*; tests/test_layout.py holds them
# together). CFG_SHAPE takes two entries, the structure hash's two 32-bit halves.
(
    CFG_ABI, CFG_KIND, CFG_DT, CFG_LATENCY, CFG_TIMESTEP, CFG_ROWS, CFG_NSLOTS, CFG_NQUEUE,
    CFG_EXACT_ON, CFG_EXACT_BELOW, CFG_QUERY_BELOW, CFG_PARAMS,
) = range(12)  # fmt: skip
CFG_NGEOM = CFG_PARAMS + NPARAMS  # after the schedule's params
CFG_NBODY, CFG_SHAPE, CFG_WIDTH = CFG_NGEOM + 1, CFG_NGEOM + 2, CFG_NGEOM + 4
(
    CFG_PRUNED, CFG_HORIZON, CFG_MARGIN, CFG_STRIDE, CFG_RENEW_MAX, CFG_CONTACTS,
    CFG_FILTER_PARENT, CFG_OVERRIDE, CFG_O_MARGIN, CFG_HAS_SPEED, CFG_SIZE,
) = range(CFG_WIDTH + 1, CFG_WIDTH + 12)  # fmt: skip

MAX_GEOM_PAIRS = 1_000_000
"""The most active geom pairs ``attach(spec, pairs="all")`` takes: holding every pair costs
about 150 bytes of tables each (in the model, and per ``MjData`` for the schedule); pruned
pairs learn the pairs they meet instead."""


class PluginOutputs(NamedTuple):
    """What the plugin's sensor says after a step.

    Attributes:
        standing: Geom pairs standing in alarm.
        min_tau: Least latest tau over the active sphere pairs (seconds; ``inf`` if none).
        evaluated: tau evaluations of the latest step (every pair at a classification).
        deferred: Pairs due at the latest step but left for a later one (a capped schedule).
        flagged: Bodies whose motion broke its bounds over the latest step's period.
    """

    standing: int
    min_tau: float
    evaluated: int
    deferred: int
    flagged: int


def _encode(values: np.ndarray) -> str:
    """A table as the plugin reads it: the entry count, a space, then the entries'
    little-endian float64 bytes in base64."""
    flat = np.ascontiguousarray(values, dtype="<f8").reshape(-1)
    return f"{flat.size} {base64.b64encode(flat.tobytes()).decode('ascii')}"


def structure_hash(model: mujoco.MjModel) -> int:
    """FNV-1a (64 bits) of ``geom_type``, ``geom_bodyid`` and ``body_parentid`` as little-endian
    int32s: what the plugin checks the model against (a spec edited after ``attach``)."""
    data = np.concatenate(
        [
            np.asarray(a, dtype="<i4")
            for a in (model.geom_type, model.geom_bodyid, model.body_parentid)
        ]
    ).tobytes()
    h = 0xCBF29CE484222325
    for byte in data:
        h = ((h ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def _check_prefix(spec: mujoco.MjSpec, prefix: object) -> str:
    if not isinstance(prefix, str) or not prefix or any(c.isspace() or c == ":" for c in prefix):
        raise InvalidInputError(
            f"prefix = {prefix!r} is invalid: a non-empty name without spaces or ':' (the "
            "tables are the model's text fields '<prefix>:<table>')."
        )
    taken = [t.name for t in spec.texts if t.name.startswith(f"{prefix}:")]
    if taken or any(s.name == prefix for s in spec.sensors):
        what = ", ".join(taken[:2]) or f"a sensor named {prefix!r}"
        raise InvalidInputError(
            f"the spec already holds a predictor under prefix {prefix!r} ({what}): attach "
            "another with a prefix='...' of its own."
        )
    return prefix


def _tables(p: Predictor) -> dict[str, np.ndarray]:
    """The plugin's tables for predictor ``p``, by name: its pairs as it knows them now (every
    active pair; pruned: those held always, the plugin learning the rest as ``p`` does), and
    for pruned pairs its reaches and what learning a pair reads."""
    held = p._held
    sched = p.new_scheduler(np.full(p.nsphere_pairs, np.inf))
    state = sched.state
    gp = p.geom_pairs
    exact = p.exact
    config = np.zeros(CFG_SIZE)
    config[CFG_ABI] = ABI_VERSION
    config[CFG_KIND] = int(state.kind)
    config[CFG_DT], config[CFG_LATENCY] = p.dt, p.latency
    config[CFG_TIMESTEP] = float(p.model.opt.timestep)
    config[CFG_ROWS] = state.ints.shape[0]
    config[CFG_NSLOTS] = state.slots.shape[0]
    config[CFG_NQUEUE] = state.queue.shape[0] - 1
    config[CFG_EXACT_ON] = exact is not None
    config[CFG_EXACT_BELOW] = 0.0 if exact is None else exact.exact_below
    config[CFG_QUERY_BELOW] = 0.0 if exact is None else exact.query_below
    config[CFG_PARAMS : CFG_PARAMS + len(state.params)] = state.params
    # The model the tables are for: the plugin refuses another (a spec edited after attach).
    shape = structure_hash(p.model)
    config[CFG_NGEOM], config[CFG_NBODY] = p.model.ngeom, p.model.nbody
    config[CFG_SHAPE], config[CFG_SHAPE + 1] = shape & 0xFFFFFFFF, shape >> 32
    config[CFG_WIDTH] = state.work.shape[1]
    if held is not None:
        config[CFG_PRUNED:CFG_CONTACTS] = [1, held.horizon, held.margin, p.stride, RENEW_MAX]
    tables = {
        "config": config,
        "pairs": p.pair_records,
        "spheres": p.sphere_records,
        "shapes": p.shape_records,
        "horizon": state.horizon,
        "pair_geom": p.geom_pair_of(np.arange(p.nsphere_pairs)),
        "geom_pairs": np.stack([gp.geom1, gp.geom2], axis=1),
    }
    rec, _, _, _, start, members, params = no_events() if p.events is None else p.events.args()
    tables.update(events_rec=rec, events_params=params, events_start=start, events_members=members)
    if exact is not None:
        # The mesh vertices are the model's (mesh_vert): the plugin reads them there.
        tables.update(exact_geoms=exact.geoms, exact_records=exact.records)
    if held is not None:
        tables["reach"] = np.stack(
            [held.radius, held.accel, held.vel_uncertainty, held.speed], axis=1
        )
        config[CFG_CONTACTS:CFG_SIZE], learn = _learn_tables(p)
        tables.update(learn)
    return tables


def _learn_tables(p: Predictor) -> tuple[list[float], dict[str, np.ndarray]]:
    """What the plugin's pruned pairs read to learn a pair as ``p.universe.learn`` does: config
    entries ``CFG_CONTACTS`` to ``CFG_HAS_SPEED`` and tables (MuJoCo's filter per geom, margins
    and gaps, the covering's per-geom layout, each body's bounds)."""
    from dua_mujoco.mj.filter import contacts_enabled, margin_override
    from dua_mujoco.mj.pairbounds import body_vel_uncertainty
    from dua_mujoco.mj.pairfilter import FilterTables

    m, cov, b = p.model, p.covering, p.bounds
    ft = FilterTables.of(m)
    o_margin = margin_override(m)
    config = [
        contacts_enabled(m), ft.filterparent, o_margin is not None,
        0.0 if o_margin is None else o_margin, b.speed is not None,
    ]  # fmt: skip
    delta = body_vel_uncertainty(m, b, period=p.period, mocap=p.mocap)
    speed = np.full(m.nbody, np.inf) if b.speed is None else b.speed
    filt = [ft.body, ft.weld, ft.parent_weld, ft.movable, ft.contype, ft.conaffinity, ft.lone]
    return [float(c) for c in config], {
        "filter": np.stack([np.asarray(a, dtype=np.float64) for a in filt], axis=1),
        "exclude": ft.exclude,
        "contact": np.stack([m.geom_margin, m.geom_gap], axis=1),
        "geom_start": cov.geom_sphere_start,
        "geom_lone": np.stack([cov.geom_plane, cov.geom_shape], axis=1),
        "plane_geom": np.asarray(cov.plane_geom),
        "shape_geom": np.asarray(cov.shape_geom),
        "body_bounds": np.stack([b.accel, delta, speed], axis=1),
    }


def attach(
    spec: mujoco.MjSpec, *, prefix: str = "dua", overlay: bool = True, **options: Any
) -> Predictor:
    """Add the predictor to ``spec`` as the sensor plugin ``dua_mujoco.predictor``.

    The spec is compiled once (as it stands) to build a :class:`~dua_mujoco.Predictor` with
    ``options``; its tables go into the spec with a plugin instance and a sensor named
    ``prefix``. Every ``mj_step`` of ``spec.compile()``'s models then runs the predictor's step
    (the native core's, the one ``Predictor.step`` runs) at the instant ``Predictor.step`` would
    read after that ``mj_step``.

    Args:
        spec: The model's spec (edited in place).
        prefix: Name of the plugin instance and its sensor, and prefix of its text fields.
        overlay: Draw the pairs standing in alarm into every ``mjvScene`` (``visualize``).
        **options: ``Predictor``'s keyword options (``accel``, ``period``, ``covering``,
            ``urgency``, ``schedule``, ...). ``pairs``: ``"all"`` holds every pair;
            ``"pruned"`` or ``PairOptions(mode="pruned", horizon=...)`` only the pairs whose
            reaches meet, renewed as a pruned ``Predictor`` renews them, each ``MjData``
            learning the pairs it meets (set-up and memory O(N + pairs met)); ``"auto"`` (the
            default) chooses as ``Predictor`` does. Every pair held: at most
            :data:`MAX_GEOM_PAIRS`.

    Returns:
        The Python predictor the tables came from (a twin: same options, same pairs held, same
        step).

    Raises:
        InvalidInputError: ``spec`` is not an ``MjSpec``, the prefix is taken or malformed, or
            the model has more than :data:`MAX_GEOM_PAIRS` active geom pairs.
        InvalidChoiceError: An unknown pair mode.
    """
    if not isinstance(spec, mujoco.MjSpec):
        raise InvalidInputError(
            f"spec must be a mujoco.MjSpec, got {type(spec).__name__}: load one with "
            "mujoco.MjSpec.from_file(path) (or dua_mujoco.mj.scenes.load_spec(name))."
        )
    _check_prefix(spec, prefix)
    pairs = options.pop("pairs", "auto")
    if not isinstance(pairs, PairOptions):
        pairs = PairOptions(mode=pairs)
    library()  # registers the plugin with MuJoCo, if `import mujoco` did not
    model = spec.compile()
    if str(getattr(pairs.mode, "value", pairs.mode)) == "all":
        _check_size(model)  # before building every pair
    p = Predictor(model, pairs=pairs, **options)
    if p._held is None:
        # "auto" resolved to every pair (few spheres, or a schedule other than deadline): the
        # predictor holds them already, but the model must not carry more than the limit.
        _check_size(model)
    tables = _tables(p)
    spec.activate_plugin(PLUGIN_NAME)
    plugin = spec.add_plugin(name=prefix, plugin_name=PLUGIN_NAME, active=True)
    plugin.config = {"prefix": prefix, "overlay": "true" if overlay else "false"}
    sensor = spec.add_sensor(name=prefix, type=mujoco.mjtSensor.mjSENS_PLUGIN)
    sensor.plugin = plugin
    sensor.plugin.name = prefix
    sensor.plugin.active = True
    for name, values in tables.items():
        spec.add_text(name=f"{prefix}:{name}", data=_encode(values))
    return p


def _check_size(model: mujoco.MjModel) -> None:
    """Refuse a model whose every pair the plugin could not hold, before building them (counted
    as MuJoCo's filter sees them, one sphere a geom, nothing held: O(ngeom^2) time)."""
    from dua_mujoco.mj.covering import cover_model
    from dua_mujoco.mj.universe import PairUniverse

    # A height field without options would fail the covering here; the predictor says so.
    covering = cover_model(model, hfield="box")
    geom_pairs, _ = PairUniverse(model, covering, lazy=True, exact=None).counts()
    if geom_pairs > MAX_GEOM_PAIRS:
        raise InvalidInputError(
            f"the model has {geom_pairs:,} active geom pairs: holding every pair takes about "
            f"{geom_pairs * 150 / 1e6:,.0f} MB of tables, and pairs='all' takes at most "
            f"{MAX_GEOM_PAIRS:,}. Attach with pairs='pruned' (or the default 'auto'), which "
            "holds only the pairs that can meet soon and learns them as they come."
        )


def _sensor(model: mujoco.MjModel, prefix: str) -> int:
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, prefix)
    if sid < 0 or int(model.sensor_type[sid]) != int(mujoco.mjtSensor.mjSENS_PLUGIN):
        raise InvalidInputError(
            f"the model has no predictor sensor {prefix!r}: build it from a spec passed to "
            "dua_mujoco.attach(spec) (or pass the prefix it was attached with)."
        )
    return sid


def _instance(model: mujoco.MjModel, prefix: str) -> int:
    """The plugin instance behind sensor ``prefix``."""
    return int(model.sensor_plugin[_sensor(model, prefix)])


@functools.cache
def _functions() -> Any:
    """The plugin's C functions (``dua/dua.h``), their signatures declared once."""
    p, i64, i32 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_int
    return declare(
        {
            "dua_plugin_standing": (i64, [p, p, i32, p, i64]),
            "dua_plugin_set_active": (i64, [p, p, i32, i32, i32, i32]),
            "dua_plugin_deactivate_contacts": (i64, [p, p, i32]),
        }
    )


def plugin_outputs(
    model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "dua"
) -> PluginOutputs:
    """The plugin's sensor outputs in ``data`` (after ``mj_step`` or ``mj_forward``)."""
    sid = _sensor(model, prefix)
    adr = int(model.sensor_adr[sid])
    v = data.sensordata[adr : adr + len(OUTPUTS)]
    return PluginOutputs(int(v[0]), float(v[1]), int(v[2]), int(v[3]), int(v[4]))


def set_active_bodies(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    body_a: int | str,
    body_b: int | str | None = None,
    *,
    on: bool,
    prefix: str = "dua",
) -> int:
    """Switch the plugin's pairs between two bodies (or of one body) off or back on in ``data``,
    as :meth:`Predictor.set_active_bodies <dua_mujoco.Predictor.set_active_bodies>` does: off
    while contact is intended (a grasp), back on when it no longer is; a pair switched back on
    stands in alarm until the next step evaluates it. ``mj_resetData`` (and any classification)
    switches every pair back on. C and C++ programs call ``dua_plugin_set_active``.

    Returns:
        The number of sphere pairs between the bodies.

    Raises:
        InvalidInputError: The model has no predictor sensor ``prefix``, or no step has run yet
            (call ``mj_step`` or ``mj_forward`` first).
        InvalidChoiceError: An unknown body name.
    """
    from dua_mujoco.mj.filter import body_id

    instance = _instance(model, prefix)
    a = body_id(model, body_a)
    b = -1 if body_b is None else body_id(model, body_b)
    fn = _functions().dua_plugin_set_active
    return _checked(int(fn(model._address, data._address, instance, a, b, int(bool(on)))))


def deactivate_contacts(model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "dua") -> int:
    """Switch off the plugin's pairs of every geom pair in contact in ``data`` (resting contact),
    as :meth:`Predictor.deactivate_contacts <dua_mujoco.Predictor.deactivate_contacts>` does;
    they stay off until :func:`set_active_bodies` switches them back on. C and C++ programs call
    ``dua_plugin_deactivate_contacts``.

    Returns:
        The number of geom pairs switched off.

    Raises:
        InvalidInputError: The model has no predictor sensor ``prefix``, or no step has run yet.
    """
    fn = _functions().dua_plugin_deactivate_contacts
    return _checked(int(fn(model._address, data._address, _instance(model, prefix))))


def _checked(result: int) -> int:
    if result == -2:
        raise InvalidInputError(
            "the plugin has not classified the pairs of this data yet: call mujoco.mj_step "
            "(or mj_forward) first."
        )
    return result


def standing_pairs(
    model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "dua"
) -> np.ndarray:
    """Geom pairs standing in alarm now, ``(K, 2)`` int64 geom ids, ``geom1 < geom2`` rows in
    increasing order (empty before the first step's compute).

    Raises:
        InvalidInputError: The model has no predictor sensor ``prefix``.
    """
    instance = _instance(model, prefix)
    fn = _functions().dua_plugin_standing
    out = np.empty((64, 2), dtype=np.int64)
    while True:
        n = int(fn(model._address, data._address, instance, out.ctypes.data, out.shape[0]))
        if n < 0:  # pragma: no cover - the sensor names an instance of this plugin
            raise InvalidInputError(f"plugin instance {instance} is not a {PLUGIN_NAME!r}.")
        if n <= out.shape[0]:
            return out[:n].copy()
        out = np.empty((n, 2), dtype=np.int64)
