"""dua_mujoco's native core (libdua_mujoco) as Python calls it."""

from collections.abc import Sequence
from typing import Annotated

import numpy
from numpy.typing import NDArray


LAYOUT: dict = ...

TABLES_VERSION: int = 7

def structure_hash(model: object) -> int:
    """
    FNV-1a of geom_type, geom_bodyid, body_parentid (what the tables check).
    """

def tau_speed_batch(x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], v: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], eps: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], delta: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], speed: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

def tau_halfspace_batch(gap: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], vn: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], delta: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

def settle_tau(x0: float, x1: float, x2: float, v0: float, v1: float, v2: float, eps: float, accel: float, delta: float, cover: float = 0.0) -> float:
    """
    The bound that settles a flagged body's pair (the step's SettleBound on a sphere pair's relative state; cover > 0: just above it where it covers that long): at most TauAccel's exact first root; -inf where it does not apply.
    """

def screen_clears(first: Sequence[float], second: Sequence[float], eps: float, accel: float, delta: float, h: float) -> bool:
    """
    The deadline schedule's screen on one sphere pair, as a step runs it (docs/theory.md, section 3, 'The screen'): whether two spheres whose rows (centre, velocity) are first and second cannot come within eps of each other in h seconds under the pair's bounds (accel, delta).
    """

def tau_static_batch(centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], eps: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], delta: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

def support(directions: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

def closest_point(points: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

def static_gap(points: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

def check_shapes(shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> int:
    """The first terrain record whose block does not fit the table, or -1."""

def shape_record_count(shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> int:
    """
    How many leading rows of a shape table are records (then terrain blocks).
    """

def tau_terrain(table: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], row: int, shape: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], v: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], spin: float, eps: float, accel: float, delta: float) -> tuple[float, int]:
    """
    tau of a convex shape record moving with velocity v against terrain record `row`, and what
    decided it: 0 the base or the first cell, 1 the cells within reach one by one, 2 the
    pyramid's branch and bound (so that tests can assert the search ran).
    """

def deadline_interval(tau: float, dt: float, latency: int, max_interval: int, extra: float = 0.0) -> int: ...

def grid_tau(tau: float, h: float, period: int) -> float:
    """
    A lower bound tau on the time to the first state in contact, counted in whole physics
    steps of h (rounded up) and put on the grid of `period` steps, as the step does at
    period > 1 (so that tests can hold it to the exact ceiling).
    """

def exceeds12(q: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], bound: float) -> bool: ...

def rigid_points(points: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], twist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], twist_ref: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], root_twist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], root_origin: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
    """
    (n, 6) centres and velocities of points ids on a frame (dua_rigid_point).
    """

def check_points(points: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], twist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], twist_ref: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], root_twist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], root_origin: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], prev: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], cur: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], nprev: int, h: float, accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], disc: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], speed: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], check_disc: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], rtol: float, values: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], broken: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu')]) -> int: ...

def check_groups(points: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], twist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], twist_ref: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], root_twist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], root_origin: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], group_start: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], groups: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], frames: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], computed: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu')], update: int, prev: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], cur: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], nprev: int, h: float, h_prev: float, accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], disc: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], speed: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], check_disc: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], rtol: float, values: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], broken: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu')]) -> int: ...

def index_by_row(row_of_geom: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], nrow: int) -> tuple:
    """
    The runtime's index of held pairs by the violation check's rows: (start, members).
    """

def candidate_pairs(centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], reach: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], margin: float) -> NDArray[numpy.int64]: ...

def reaches(radius: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], speed: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], delta: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], vmax: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], horizon: float) -> NDArray[numpy.float64]: ...

def reach_pairs(anchor: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], reach: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], margin: float, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]: ...

def escapes(anchor: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], speed0: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], delta: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], vmax: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], elapsed: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]: ...

def sphere_pairs(g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], dist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], index: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], start: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], plane: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], shape: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], radius: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple: ...

def pair_bounds(first: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], second: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], kind: Annotated[NDArray[numpy.int8], dict(order='C', device='cpu', writable=False)], sphere_body: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], accel: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], delta: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], speed: object | None) -> tuple: ...

def contact_distance(margin: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], gap: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], override_margin: bool, o_margin: float) -> tuple[NDArray[numpy.float64], NDArray[numpy.float64]]: ...

def exact_rows(geoms: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], geom1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], geom2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], kind: Annotated[NDArray[numpy.int8], dict(order='C', device='cpu', writable=False)], dist: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

class Filter:
    """MuJoCo's dynamic pair filter over per-geom tables."""

    def __init__(self, body: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], weld: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], parent_weld: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], movable: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], contype: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], conaffinity: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], lone: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], exclude: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], filterparent: bool) -> None: ...

    def mask(self, g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.bool_]: ...

    def all(self) -> tuple[NDArray[numpy.int64], NDArray[numpy.int64]]: ...

    def count(self, weight: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> tuple[int, int]: ...

    def any(self) -> bool: ...

def plugin_standing(model: object, data: object, instance: int) -> object:
    """
    Geom pairs standing in alarm in plugin instance `instance` ((K, 2)), or None.
    """

def plugin_memory(model: object, data: object, instance: int) -> object:
    """
    Plugin instance `instance`'s pairs known, geom pairs known, pairs held, geom pairs forgotten, compactions, then its known geom pairs as (g1, g2) rows, flat; or None.
    """

def plugin_set_active(model: object, data: object, instance: int, body_a: int, body_b: int, on: bool) -> int: ...

def plugin_set_plan(model: object, data: object, instance: int, qpos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], deviation: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], start: float, bodies: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], mocap_pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_quat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rel_bodies: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], rel_deviation: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
    """
    dua_plugin_set_plan: (its result, each body's departure time from the plan replaced).
    """

def mixed_stray(t: float, accel: float, disc: float, spin: float, place: float, velocity: float) -> float:
    """
    MixedStray (plan.h): how far a free point strays in t from where its velocity read carries it ((spin + disc) t + accel t^2 / 2), rounded up, plus room for the rounding of the carried place (|place|_1 and |velocity|_1).
    """

def mixed_reach(t: float, s: float, accel: float, disc: float, speed: float) -> float:
    """
    MixedReach (plan.h): how far any point of a free body (speed s now) can move in t: (s + disc) t + accel t^2 / 2 or speed t, whichever is less, each rounded up.
    """

def box_within(box: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pa: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ra: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pb: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rb: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], limit: float) -> bool:
    """
    BoxWithin (plan.h): every corner of box within limit between the poses (pa, ra) and (pb, rb), screened first by a bound that needs no corner.
    """

def relative_within(box: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pa: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ra: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pb: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rb: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], qa: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], sa: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], qb: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], sb: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], limit: float) -> bool:
    """
    RelativeWithin (plan.h): b's box within limit, in a's frame, of its planned pose relative to a.
    """

def plan_deviation(points: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pos_a: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mat_a: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], pos_b: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mat_b: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], frame_of: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
    """
    (r, n): each point's deviation between two poses of its geom (in the frame of geom frame_of[i] when given), row by row: the plans' one measure (PoseDeviation, RelativePose, plan.h).
    """

def plugin_clear_plan(model: object, data: object, instance: int) -> int: ...

def plugin_deactivate_contacts(model: object, data: object, instance: int) -> int: ...

class Schedule:
    """A schedule's state and kernels (dua_mujoco.core.schedules wraps it)."""

    def __init__(self, kind: int, dt: float, latency: int, tau0: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], active: object | None = None, slots_per_bucket: int = 1, cap: int = 0, max_interval: int = 1024, backoff: int = 8, threshold: float = 0.0, alarm_horizon: float | None = None) -> None: ...

    def select(self, n: int) -> int: ...

    def reinsert(self, n: int, count: int) -> int: ...

    def restore(self, n: int, count: int) -> None: ...

    def switch(self, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], on: bool, n_next: int) -> int: ...

    def make_due(self, p: int, n: int) -> None: ...

    def select_made_due(self, groups: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], start: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], members: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], n: int) -> int:
        """
        make_due of the members of each of groups (group g: members[start[g]:start[g + 1]]), in order, then select(n), as the native step runs them (one pass).
        """

    def horizon_of(self, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]: ...

    def next_due(self, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]:
        """
        The step each pair is next evaluated at (-1: a deadline pair switched off).
        """

    @property
    def intervals(self) -> NDArray[numpy.int64]:
        """The rank schedule's revisit interval of each bucket, steps."""

    @property
    def kind(self) -> int: ...

    @property
    def dt(self) -> float: ...

    @property
    def latency(self) -> int: ...

    @property
    def alarm_horizon(self) -> float:
        """The alarm horizon, seconds (one period by default)."""

    @property
    def step_count(self) -> int: ...

    @step_count.setter
    def step_count(self, arg: int, /) -> None: ...

    @property
    def activation_changes(self) -> int: ...

    @activation_changes.setter
    def activation_changes(self, arg: int, /) -> None: ...

    @property
    def last_tau(self) -> NDArray[numpy.float64]: ...

    @property
    def active(self) -> NDArray[numpy.bool_]: ...

    @property
    def ints(self) -> NDArray[numpy.int64]: ...

    @property
    def slots(self) -> NDArray[numpy.int64]: ...

    @property
    def horizon(self) -> NDArray[numpy.float64]: ...

    @property
    def queue(self) -> NDArray[numpy.int64]: ...

    @property
    def params(self) -> NDArray[numpy.int64]: ...

    @property
    def work(self) -> NDArray[numpy.int64]: ...

    @property
    def w_tau(self) -> NDArray[numpy.float64]: ...

class Alarms:
    """The alarms of one predictor step (read-only views of the alarm log)."""

    @property
    def step(self) -> int:
        """Predictor step (0 for the initial classification)."""

    @property
    def time(self) -> float:
        """data.time when read."""

    @property
    def deferred(self) -> int:
        """
        Pairs due this step but left for a later one (max_evals_per_step reached).
        """

    @property
    def pairs(self) -> Annotated[NDArray[numpy.int64], dict(writable=False)]:
        """(k,) sphere-pair ids that raised an alarm."""

    @property
    def tau(self) -> Annotated[NDArray[numpy.float64], dict(writable=False)]:
        """(k,) their tau (seconds)."""

    @property
    def new(self) -> Annotated[NDArray[numpy.bool_], dict(writable=False)]:
        """
        (k,) bool: alarms this step raised, as opposed to ones standing from before.
        """

    @property
    def geom1(self) -> Annotated[NDArray[numpy.int32], dict(writable=False)]:
        """(k,) first geom of each alarmed pair."""

    @property
    def geom2(self) -> Annotated[NDArray[numpy.int32], dict(writable=False)]:
        """(k,) second geom (a plane geom for half-space pairs)."""

    @property
    def sphere1(self) -> Annotated[NDArray[numpy.int32], dict(writable=False)]:
        """(k,) first sphere of each alarmed pair."""

    @property
    def sphere2(self) -> Annotated[NDArray[numpy.int32], dict(writable=False)]:
        """(k,) second sphere, -1 for half-space and static shape pairs."""

    @property
    def names(self) -> list:
        """Geom names of each alarmed pair (geom<id> for unnamed geoms)."""

    @property
    def geom_pairs(self) -> set:
        """The distinct alarmed geom pairs (g1, g2), g1 < g2."""

    def __len__(self) -> int: ...

    def __repr__(self) -> str: ...

class StepError(RuntimeError):
    pass

class Mocap:
    """
    The velocities of a model's mocap bodies, by mocap id: backward differences of their poses (mocap.h), or given.
    """

    def __init__(self, model: object) -> None: ...

    def update(self, data: object) -> None:
        """
        Difference the poses of data against the latest record (the first call records).
        """

    def reset(self) -> None:
        """Forget the poses; differenced velocities zero."""

    def set_velocity(self, mocap: int, linear: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], angular: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> None: ...

    def clear_velocity(self, mocap: int) -> None: ...

    @property
    def bodies(self) -> NDArray[numpy.int64]:
        """(nmocap,) the body of each mocap id."""

    @property
    def linear(self) -> NDArray[numpy.float64]:
        """(nmocap, 3) linear velocities of the bodies' origins (a copy)."""

    @property
    def angular(self) -> NDArray[numpy.float64]:
        """(nmocap, 3) angular velocities (a copy)."""

    @property
    def twist(self) -> Annotated[NDArray[numpy.float64], dict(writable=False)]:
        """
        (nbody, 6) [angular; linear] of each mocap body's tree, zero elsewhere (a view).
        """

    @property
    def updates(self) -> int:
        """Records since the last start (the start's included)."""

class Tables:
    """A model's predictor tables, checked against the model."""

    @staticmethod
    def build(model: object, arrays: dict) -> Tables:
        """
        The tables from a dict of float64 arrays (dua_mujoco/runtime/table_arrays.py), checked.
        """

    @staticmethod
    def free(arrays: dict) -> Tables:
        """
        Free spheres' tables (FreeTables: 'config' and 'reach'; core/spheres.py), checked.
        """

    @staticmethod
    def load(model: object, prefix: str) -> Tables:
        """The tables in a model's text fields, as the plugin reads them."""

    @property
    def pruned(self) -> bool: ...

    @property
    def exact(self) -> bool: ...

    @property
    def nsphere(self) -> int: ...

class Runtime:
    """The predictor at run time (runtime.h), on one MjData or free spheres."""

    def __init__(self, tables: Tables, model: object | None, names: object | None, log_steps: int = 4, log_min: int = 16384) -> None: ...

    def bind(self, data: object) -> None:
        """Read the state from this MjData (of the runtime's model) from now on."""

    def classify(self) -> Alarms:
        """The initial classification of the bound MjData's state."""

    def step(self) -> Alarms:
        """One predictor step on the bound MjData, one period after the last."""

    def watch_info(self, names: list, cost: str, horizon: float, cost_key: str) -> None:
        """
        Watch for the gym wrapper: step_info and observe_info write its info (names: one str a geom; cost: 'alarm', 'new' or 'horizon', below horizon seconds; cost_key: the key of the cost term).
        """

    def observe_info(self, info: object) -> None:
        """
        info['alarm_pairs'] (the counted geom pairs standing, named) and info['min_tau'] of the latest step or classification.
        """

    def step_info(self, info: object) -> float:
        """
        step, then the wrapper's info (observe_info, the cost term under cost_key, added to info['cost']): one call a step for the gym wrapper; returns the cost.
        """

    def classify_spheres(self, centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]:
        """
        Free spheres: the initial classification at centres and velocities (n, 3); the pairs (i, j) standing in alarm, (k, 2) in increasing order.
        """

    def step_spheres(self, centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]:
        """
        Free spheres: one step at centres and velocities (n, 3), one period after the last; the pairs (i, j) standing in alarm, (k, 2) in increasing order.
        """

    @property
    def held_records(self) -> NDArray[numpy.float64]:
        """(held pairs, 8) the held pairs' records, in held order: a copy."""

    def clock_of(self, arg: float, /) -> int: ...

    def switch(self, pairs: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], on: bool) -> None: ...

    def pairs_between_bodies(self, body_a: int, body_b: int) -> NDArray[numpy.int64]: ...

    def geom_pair_ids(self, g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]: ...

    def deactivate_contacts(self) -> int: ...

    def set_plan(self, qpos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], deviation: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], start: float, bodies: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], mocap_pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_quat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rel_bodies: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], rel_deviation: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """
        Follow a flight plan (Runtime::SetPlan); returns each body's departure time from the plan it replaces (inf: none).
        """

    def check_plan(self) -> NDArray[numpy.int64]:
        """
        Check the plan at the bound MjData's state between steps: the bodies found beyond their deviation (counted, their pairs due at the next step).
        """

    def basis_of(self, pairs: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.uint8]:
        """
        (n, 2): what the latest verdict of each sphere pair, and the one before, rested on (bit 0: its first geom's side on the plan, bit 1: its second's; 0 for a pair not held).
        """

    def plan_query(self, qpos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], deviation: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], start: float, bodies: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], mocap_pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_quat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rel_bodies: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], rel_deviation: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.int64]:
        """
        Each geom pair's first knot of a candidate plan at which its contact cannot be excluded (Runtime::PlanQuery); the plan is not followed.
        """

    def clear_plan(self) -> None: ...

    @property
    def has_plan(self) -> bool: ...

    @property
    def plan_breaks(self) -> int: ...

    @property
    def plan_relative_rises(self) -> NDArray[numpy.bool_]:
        """
        (nrel,) per relative pair of the plan (sorted by body pair) whether min(D_a + D_b, D_ab), as the walk reads them, never falls (Plan::Relative); for tests.
        """

    @property
    def plan_tolerance(self) -> float:
        """
        The tolerance the plan followed declared (Plan::tolerance; 0 without a plan).
        """

    @property
    def plan_query_tolerance(self) -> float:
        """
        The tolerance the latest plan_query's candidate declared (Plan::tolerance); for tests.
        """

    @property
    def plan_queries(self) -> int: ...

    @property
    def exact_queries(self) -> int: ...

    @property
    def plan_ok(self) -> NDArray[numpy.bool_]:
        """(nbody,) bodies still within their deviation (a copy)."""

    @property
    def plan_span(self) -> tuple:
        """(start, step, knots) of the plan followed, () for none."""

    def plan_broken(self) -> object:
        """
        The bodies of the bound MjData's state beyond their deviation at its knot (None: no plan covers it); checks only.
        """

    def plan_broken_relative(self) -> NDArray[numpy.int64]:
        """
        (n, 2) the relative pairs (body ids a < b) of the bound MjData's state beyond their relative deviation, of the plan and its shadows; checks only.
        """

    def sphere_states(self, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """
        (n, 6) centres and velocities of covering spheres ids on the bound MjData.
        """

    def watch(self, ignored_geoms: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu', writable=False)], ignored_pairs: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> None:
        """
        Count, from now on, the geom pairs with no ignored geom and not ignored themselves.
        """

    @property
    def watched(self) -> tuple:
        """
        (counted geom pairs whose alarm started at the latest step, the least time a counted pair's latest verdict still vouches for: its tau less the time since, at least 0; the version of the set of counted geom pairs standing).
        """

    def exact_only(self, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], coarse: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], query_below: float) -> NDArray[numpy.float64]:
        """
        For tests: the exact level alone on held pairs ids (records as built), nothing kept.
        """

    def check_bodies_copy(self, lanes: bool) -> tuple:
        """
        For tests: the violation check of the bound MjData on a copy of its state: (flagged rows, the state after, (ceil(nbody / 4), 42, 4) flat).
        """

    def set_escape_check(self, on: bool) -> None:
        """For tests: pruned pairs without the escape check (what it guards)."""

    @property
    def classified(self) -> bool: ...

    @property
    def step_count(self) -> int: ...

    @property
    def last_time(self) -> float: ...

    @property
    def schedule(self) -> Schedule: ...

    @property
    def ids(self) -> NDArray[numpy.int64]: ...

    @property
    def held_version(self) -> int: ...

    @property
    def universe_version(self) -> int: ...

    @property
    def npair(self) -> int: ...

    def universe(self) -> dict:
        """
        The pairs known now (copies): records, geom pairs and the exact level's records.
        """

    @property
    def on(self) -> NDArray[numpy.bool_]: ...

    @property
    def standing(self) -> NDArray[numpy.int64]:
        """Model pair ids standing in alarm now, sorted."""

    @property
    def nstanding(self) -> int: ...

    @property
    def min_tau(self) -> float: ...

    @property
    def evaluated(self) -> int: ...

    @property
    def deferred(self) -> int: ...

    @property
    def flagged_bodies(self) -> NDArray[numpy.int64]: ...

    @property
    def flagged(self) -> int: ...

    @property
    def violation_events(self) -> int: ...

    @property
    def rebuilds(self) -> int: ...

    @property
    def renewals(self) -> int: ...

    @property
    def anchor_steps(self) -> NDArray[numpy.int64]: ...

    @property
    def exact_records(self) -> NDArray[numpy.float64]:
        """The exact level's records with the directions learnt: a copy."""

    @property
    def exact_witness(self) -> NDArray[numpy.float64]:
        """
        The exact level's witness points of each held pair's latest query, first geom's then second's, each in its geom's frame (NaN before the first): a copy.
        """

    def reaches(self) -> dict:
        """
        Pruned pairs: each sphere's anchor (n, 3), reach (n,), anchor step (n,), and the largest contact distance beyond the radii (copies).
        """

    @property
    def mocap(self) -> Mocap:
        """The mocap bodies' velocities, differenced at each step (or given)."""

def static_records(model: object, geoms: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
    """
    The static guard's records (n, STATIC_NCOL) of static geoms: geom, pose as mj_kinematics places it, geom_size, digest of its height field or mesh.
    """

def static_mismatch(model: object, records: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> str:
    """
    The first static geom the model no longer places, sizes or shapes as static_records recorded it, and how (empty: none).
    """

def knot_kinematics(model: object, geoms: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], qpos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_quat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], exact: bool = False) -> tuple:
    """
    KnotKinematics (kinematics.h) on one row: (bodies, xpos, xquat, xmat, geom_xpos, geom_xmat), the bodies computed and the geoms given, as mj_kinematics computes them (exact=True: bit for bit; else a hinge by the knots' polynomials).
    """

def knot_kinematics_rows(model: object, geoms: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], qpos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_pos: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mocap_quat: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], lanes: bool = True, fault: bool = False, exact: bool = False) -> tuple:
    """
    KnotKinematics::RunKnots (kinematics.h) on n rows, as set_plan calls it: (geom_xpos (n, ngeom, 3), geom_xmat (n, ngeom, 9), whether lanes computed them, the tolerance the plan adds to its deviations); lanes=False computes one knot at a time, fault=True flips a bit of the lanes' first pose (the self-check then turns lanes off), exact=True computes every hinge by libmujoco's call.
    """

def half_angle_sincos(x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], lanes: bool = True) -> tuple:
    """
    The knots' hinges' (sin x, cos x), |x| <= HALF_ANGLE_MAX, four at a time in lanes or one at a time.
    """

HALF_ANGLE_MAX: float = 64.0

SIN_COS_ERROR: float = 8.881784197001252e-16

TOLERANCE_UNIT: float = 2.2737367544323206e-13

WORLD_REACH: float = 1000.0

def tau_pairs(pairs: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], planes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple[NDArray[numpy.float64], int]:
    """
    tau of pairs ids (n,) of free spheres, checking the records of ids only: (tau (n,), the first k whose state is not finite or -1).
    """

def step_free(schedule: Schedule, pairs: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], planes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
    """
    Schedule.step_points checking the selected pairs' records only: (alarms, bad pair or -1, evaluated).
    """

def stands(schedule: Schedule, ids: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.bool_]:
    """
    (n,) bool: whether each pair stands in alarm, by the schedule's own rule.
    """

def grid_plan(reach: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], margin: float, lo: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], hi: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> dict:
    """
    The candidate grid's plan (cell edge, bucket map, held-out ids) as a dict.
    """

class FreeStep:
    """
    step_free bound to a schedule and its pairs' records, planes and shapes.
    """

    def __init__(self, schedule: object, pairs: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], planes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shapes: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> None: ...

    def step(self, centers: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], velocities: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> int:
        """
        One fused step: its number of alarms, or -1 - p for a pair p whose state is not finite (the step undone).
        """

class Failsafe:
    """
    A failsafe's robot: its brake's actuators, DOFs and bodies (Brake, Evade).
    """

    @property
    def dofs(self) -> list[int]: ...

    @property
    def bodies(self) -> list[int]: ...

    @property
    def actuators(self) -> list[int]: ...

class Brake(Failsafe):
    """The shield's brake (brake.h) on a scratch MjData."""

    def __init__(self, model: object, actuators: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], time_constant: float) -> None: ...

    def compute(self, data: object, target: object | None = None) -> NDArray[numpy.float64]:
        """
        (nu,) controls at data's state: data.ctrl with the robot's actuators braking (or driving toward target, joint velocities of the braked DOFs).
        """

    @property
    def time_constant(self) -> float: ...

class Evade(Failsafe):
    """The evasive failsafe (brake.h) on a scratch MjData."""

    def __init__(self, model: object, actuators: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], time_constant: float, x: int, y: int, obstacles: Sequence[int], radius: Sequence[float], room: Sequence[float], gain: float, still: float, sideways: bool) -> None: ...

    def compute(self, data: object) -> NDArray[numpy.float64]:
        """(nu,) controls at data's state (its bodies' positions read from it)."""

class Shield:
    """The safety shield (shield.h)."""

    def __init__(self, tables: object, model: object, rolled: object, roll: object, scratch: object, actuators: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], bodies: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g1: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], g2: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], period: int, deviation: float, rest_speed: float, stop_time: float, stop_distance: float, screen: bool, time_constant: float, policy: object | None, view: object | None = None, evade: object | None = None) -> None: ...

    def reset(self, data: object) -> None:
        """Start over at data's state."""

    def control(self, data: object, intended: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """(nu,) the controls for the step about to start from data."""

    @property
    def guaranteed(self) -> bool: ...

    @property
    def intervening(self) -> bool: ...

    @property
    def counts(self) -> dict: ...

    @property
    def interventions(self) -> int: ...

    @property
    def plan_knots(self) -> int: ...

    @property
    def plan_rest(self) -> int: ...
