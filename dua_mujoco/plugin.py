"""The predictor inside ``mj_step``: the MuJoCo sensor plugin ``dua_mujoco.predictor``.

:func:`attach` adds the plugin to a ``mujoco.MjSpec``: one plugin instance, one sensor of
:data:`OUTPUTS`, and the tables a :class:`~dua_mujoco.Predictor` of the same options builds, as
custom text fields ``<prefix>:<table>`` (base64 float64: exact, and fast to read). Every
``mj_step`` of the compiled model then predicts, in Python or in any C or C++ program that loads
``libdua_mujoco.so``, with the native core's step, the same code ``Predictor.step`` runs. The
plugin's state lives in each ``MjData``, so copies, resets and ``mujoco.rollout`` on several
threads keep their runs apart (docs/plugin.md).
"""

from __future__ import annotations

import base64
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.options import PairOptions
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.runtime.flightplan import Bodies, Relative, plan_arrays
from dua_mujoco.runtime.predictor import Predictor

__all__ = [
    "FORGET_REBUILDS",
    "MAX_GEOM_PAIRS",
    "OUTPUTS",
    "PLUGIN_NAME",
    "KnownPairs",
    "PluginOutputs",
    "attach",
    "clear_plan",
    "deactivate_contacts",
    "known_pairs",
    "plugin_outputs",
    "set_active_bodies",
    "set_plan",
    "standing_pairs",
]

PLUGIN_NAME = "dua_mujoco.predictor"

OUTPUTS = ("standing", "min_tau", "evaluated", "deferred", "flagged")
"""The sensor's outputs, in order (:class:`PluginOutputs`)."""

FORGET_REBUILDS = 8
"""``attach``'s default ``forget``: rebuilds a learnt pair may go unheld before an ``MjData``
forgets it (the plugin's own default when the attribute is absent)."""

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


def attach(
    spec: mujoco.MjSpec,
    *,
    prefix: str = "dua",
    overlay: bool = True,
    forget: int | None = FORGET_REBUILDS,
    **options: Any,
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
        forget: Pruned pairs: each ``MjData`` forgets a pair it learnt once none of its geom
            pair's sphere pairs has been held for this many rebuilds (``None``: never), so that
            its memory stays bounded over a long run; a forgotten pair is learnt again when a
            rebuild meets it, before it can collide (docs/theory.md, Lemma 7.1).
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
            "mujoco.MjSpec.from_file(path) (or dua_mujoco.models.scenes.load_spec(name))."
        )
    _check_prefix(spec, prefix)
    bad_forget = isinstance(forget, bool) or not isinstance(forget, int) or forget < 0
    if forget is not None and bad_forget:
        raise InvalidInputError(
            f"forget must be a whole number of rebuilds >= 0 or None (never), got {forget!r}."
        )
    pairs = options.pop("pairs", "auto")
    if not isinstance(pairs, PairOptions):
        pairs = PairOptions(mode=pairs)
    model = spec.compile()
    if str(getattr(pairs.mode, "value", pairs.mode)) == "all":
        _check_size(model)  # before building every pair
    p = Predictor(model, pairs=pairs, **options)
    if p.reach is None:
        # "auto" resolved to every pair (few spheres, or a schedule other than deadline): the
        # predictor holds them already, but the model must not carry more than the limit.
        _check_size(model)
    spec.activate_plugin(PLUGIN_NAME)
    plugin = spec.add_plugin(name=prefix, plugin_name=PLUGIN_NAME, active=True)
    plugin.config = {
        "prefix": prefix,
        "overlay": "true" if overlay else "false",
        "forget": "never" if forget is None else str(forget),
    }
    sensor = spec.add_sensor(name=prefix, type=mujoco.mjtSensor.mjSENS_PLUGIN)
    sensor.plugin = plugin
    sensor.plugin.name = prefix
    sensor.plugin.active = True
    for name, values in p.table_arrays.items():
        spec.add_text(name=f"{prefix}:{name}", data=_encode(values))
    return p


def _check_size(model: mujoco.MjModel) -> None:
    """Refuse a model whose every pair the plugin could not hold, before building them (counted
    as MuJoCo's filter sees them, one sphere a geom, nothing held: O(ngeom^2) time)."""
    from dua_mujoco.build.covering import cover_model
    from dua_mujoco.build.universe import PairUniverse

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
    from dua_mujoco.build.filter import body_id

    instance = _instance(model, prefix)
    a = body_id(model, body_a)
    b = -1 if body_b is None else body_id(model, body_b)
    return _checked(int(_core.plugin_set_active(model, data, instance, a, b, bool(on))))


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
    return _checked(int(_core.plugin_deactivate_contacts(model, data, _instance(model, prefix))))


def set_plan(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    qpos: npt.ArrayLike,
    *,
    deviation: npt.ArrayLike,
    start: float | None = None,
    bodies: Bodies = None,
    mocap_pos: npt.ArrayLike | None = None,
    mocap_quat: npt.ArrayLike | None = None,
    relative: Relative = None,
    prefix: str = "dua",
) -> np.ndarray:
    """Have the plugin follow a flight plan in ``data``, as :meth:`Predictor.set_plan
    <dua_mujoco.Predictor.set_plan>` does (docs/plans.md; the same arguments and result). The
    plugin's step reads the state it runs on, before ``mj_step`` advances the time: a plan rolled
    from ``data`` starts at its ``time`` (the default ``start``), and its first knot is what the
    next ``mj_step`` reads. The plugin checks the plan at every physics step. C and C++ programs
    call ``dua_plugin_set_plan``.

    Raises:
        InvalidInputError: The model has no predictor sensor ``prefix``, no step has run yet,
            or the plan is refused (the message names the bad value).
        ShapeError: ``qpos``, ``deviation`` or the mocap poses do not fit the model.
    """
    start = data.time if start is None else start
    plan = plan_arrays(model, qpos, deviation, start, bodies, mocap_pos, mocap_quat, relative)
    result, departures = _core.plugin_set_plan(model, data, _instance(model, prefix), *plan)
    _checked(int(result))
    return np.asarray(departures)


def clear_plan(model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "dua") -> None:
    """Have the plugin stop following its plan in ``data`` (C: ``dua_plugin_clear_plan``)."""
    _checked(int(_core.plugin_clear_plan(model, data, _instance(model, prefix))))


def _query(
    fn: Callable[[mujoco.MjModel, mujoco.MjData, int], object],
    model: mujoco.MjModel,
    data: mujoco.MjData,
    prefix: str,
) -> np.ndarray:
    """What ``fn`` (a ``_core.plugin_*`` query) answers for the instance behind sensor
    ``prefix``."""
    instance = _instance(model, prefix)
    out = fn(model, data, instance)
    if out is None:  # pragma: no cover - the sensor names an instance of this plugin
        raise InvalidInputError(f"plugin instance {instance} is not a {PLUGIN_NAME!r}.")
    return np.asarray(out)


def _checked(result: int) -> int:
    if result == -2:
        raise InvalidInputError(
            "the plugin has not classified the pairs of this data yet: call mujoco.mj_step "
            "(or mj_forward) first."
        )
    return result


@dataclass(frozen=True)
class KnownPairs:
    """What a plugin instance knows now (:func:`known_pairs`).

    Attributes:
        npair: Sphere pairs known.
        held: Of them, those held.
        forgotten: Geom pairs forgotten so far.
        compactions: Times the known pairs were compacted.
        geom_pairs: ``(K, 2)`` int64 known geom pairs, ``geom1 < geom2`` rows in increasing order.
    """

    npair: int
    held: int
    forgotten: int
    compactions: int
    geom_pairs: np.ndarray


def known_pairs(model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "dua") -> KnownPairs:
    """The pairs plugin instance ``prefix`` of ``data`` knows: the memory that grows with the
    pairs met, and shrinks as it forgets (``attach``'s ``forget``).

    Raises:
        InvalidInputError: The model has no predictor sensor ``prefix``.
    """
    out = _query(_core.plugin_memory, model, data, prefix)
    return KnownPairs(
        npair=int(out[0]),
        held=int(out[2]),
        forgotten=int(out[3]),
        compactions=int(out[4]),
        geom_pairs=out[5:].reshape(-1, 2),
    )


def standing_pairs(
    model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "dua"
) -> np.ndarray:
    """Geom pairs standing in alarm now, ``(K, 2)`` int64 geom ids, ``geom1 < geom2`` rows in
    increasing order (empty before the first step's compute).

    Raises:
        InvalidInputError: The model has no predictor sensor ``prefix``.
    """
    return _query(_core.plugin_standing, model, data, prefix)
