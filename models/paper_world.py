"""The paper's sphere world as a MuJoCo model: spheres in a box driven by bounded actuators."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.exceptions import InvalidInputError

__all__ = [
    "ACCEL_BOUND_NUMERIC",
    "paper_world_accel_bound",
    "paper_world_model",
    "paper_world_spec",
]

#: Custom ``<numeric>`` holding a scene's exact per-body acceleration-norm bound (m/s^2).
ACCEL_BOUND_NUMERIC = "dua_accel_bound"

# --------------------------------------------------------------------------------------------------
# The paper's sphere world.
# --------------------------------------------------------------------------------------------------


def paper_world_accel_bound(accel_max: float) -> float:
    """Acceleration-norm bound of one sphere of :func:`paper_world_spec` under its actuators.

    Each sphere has three orthogonal slide joints and no rotation, so its mass matrix is ``m I3``
    and a motor of force ``|f| <= m accel_max`` on each axis gives ``|a_axis| <= accel_max``; the
    norm is then at most ``sqrt(3) accel_max``. Contacts (sphere-sphere and walls) are the only
    other forces: gravity is off and the joints have no damping, stiffness, friction or armature.

    Args:
        accel_max: Per-axis acceleration bound (m/s^2), as passed to :func:`paper_world_spec`.

    Returns:
        The bound on ``|d^2 c / dt^2|`` of every sphere centre while it is out of contact.
    """
    return math.sqrt(3.0) * accel_max


def _quat_z_to(normal: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) rotating the z axis onto the unit vector ``normal``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, normal))
    if c < -1.0 + 1e-12:
        # Antiparallel: any axis orthogonal to z works; pick x.
        return np.array([0.0, 1.0, 0.0, 0.0])
    axis = np.cross(z, normal)
    q = np.array([1.0 + c, *axis])
    return q / np.linalg.norm(q)


_DEFAULT_ARENA_MAX = 2000
"""Spheres up to which MuJoCo's default arena holds the world (swarms of thousands measured)."""


def _place_spheres(
    n: int, rng: np.random.Generator, *, half: float, radius: float, clearance: float
) -> np.ndarray:
    """Rejection-sample ``n`` non-overlapping centres inside the cube ``[-half, half]^3``.

    Returns:
        Centres, shape ``(n, 3)``; pairwise distances ``>= 2 radius + clearance`` and every centre
        at least ``radius + clearance`` from every wall.

    Raises:
        InvalidInputError: If the cube is too crowded to place ``n`` spheres.
    """
    lo, hi = -half + radius + clearance, half - radius - clearance
    if hi <= lo:
        raise InvalidInputError(
            f"box_size {2 * half} is too small for spheres of radius {radius}; "
            "increase box_size or decrease radius."
        )
    min_dist = 2.0 * radius + clearance
    centres = np.empty((n, 3))
    placed = 0
    # Give up after this many rejections in a row: the free volume is then too fragmented.
    max_misses = 20_000
    misses = 0
    # Placed centres by grid cell of side min_dist: a candidate is checked against the 27 cells
    # around it only, O(n) in all (a swarm of 20,000 took 39 s checking against every centre).
    # The same candidates are accepted as against all: the placement is unchanged.
    cells: dict[tuple[int, int, int], list[int]] = {}
    offsets = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)]
    while placed < n:
        # Batches of candidates amortise the generator call.
        batch = rng.uniform(lo, hi, size=(64, 3))
        cells_of = map(tuple, np.floor(batch / min_dist).astype(int).tolist())
        for c, cell in zip(batch, cells_of, strict=True):
            near = [
                i
                for o in offsets
                for i in cells.get((cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]), ())
            ]
            if near and np.min(np.linalg.norm(centres[near] - c, axis=1)) < min_dist:
                misses += 1
                if misses > max_misses:
                    raise InvalidInputError(
                        f"Could not place {n} spheres of radius {radius} without overlap in a "
                        f"cube of side {2 * half} (placed {placed}); use fewer spheres, a smaller "
                        "radius or a larger box_size."
                    )
                continue
            centres[placed] = c
            cells.setdefault(cell, []).append(placed)
            placed += 1
            misses = 0
            if placed == n:
                break
    return centres


def paper_world_spec(
    n: int,
    *,
    seed: int = 0,
    box_size: float = 1.0,
    radius: float = 0.03,
    mass: float = 0.1,
    accel_max: float = 1.0,
    speed_max: float = 0.5,
    timestep: float = 0.002,
    integrator: mujoco.mjtIntegrator = mujoco.mjtIntegrator.mjINT_EULER,
) -> mujoco.MjSpec:
    """The paper's experimental world (sec. 8): ``n`` spheres with bounded accelerations in a cube.

    The cube ``[-box_size/2, box_size/2]^3`` is closed by six static planes facing inwards. Each
    sphere is a body with three slide joints ``sphere{i}_x``, ``_y``, ``_z`` (world x, y, z),
    each driven by a motor of the same name with ``ctrlrange = [-mass accel_max, mass
    accel_max]`` (N). Gravity is off and contacts between spheres (and with the walls) are on.
    Sphere ``i`` is body ``sphere{i}``, geom ``sphere{i}`` and starts at its body position
    (``qpos = 0``); the first keyframe ``init`` holds random initial velocities of norm
    ``<= speed_max``.

    Acceleration bound: out of contact, each centre satisfies ``|a_axis| <= accel_max`` on every
    axis, hence ``|a| <= sqrt(3) accel_max`` (:func:`paper_world_accel_bound`). The bound is stored
    in the model as the custom numeric ``dua_accel_bound`` (:func:`declared_accel_bound`). Random
    controls held for several steps (:func:`make_controller`) reproduce the paper's
    piecewise-constant bounded accelerations.

    Args:
        n: Number of spheres (>= 1).
        seed: Seed of the placement and initial velocities.
        box_size: Side of the cube (m).
        radius: Sphere radius (m).
        mass: Sphere mass (kg).
        accel_max: Per-axis acceleration bound (m/s^2) enforced by the motors' ``ctrlrange``.
        speed_max: Bound on the initial speed (m/s); the speed is not bounded afterwards.
        timestep: Physics timestep (s).
        integrator: MuJoCo integrator; semi-implicit Euler by default (docs/discrete-time.md).

    Returns:
        An uncompiled ``MjSpec``; ``spec.compile()`` gives the model.

    Raises:
        InvalidInputError: If an argument is out of range or the spheres do not fit.
    """
    if n < 1:
        raise InvalidInputError(f"n must be >= 1, got {n}.")
    for label, value, least in (
        ("box_size", box_size, "> 0"),
        ("radius", radius, "> 0"),
        ("mass", mass, "> 0"),
        ("timestep", timestep, "> 0"),
        ("accel_max", accel_max, ">= 0"),
        ("speed_max", speed_max, ">= 0"),
    ):
        if not (math.isfinite(value) and (value > 0 or (value == 0 and least == ">= 0"))):
            raise InvalidInputError(f"{label} must be finite and {least}, got {value}.")

    rng = np.random.default_rng(seed)
    half = 0.5 * box_size
    centres = _place_spheres(n, rng, half=half, radius=radius, clearance=0.25 * radius)
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    speed = rng.uniform(0.0, speed_max, size=(n, 1))
    velocity = direction * speed

    spec = mujoco.MjSpec()
    spec.modelname = f"paper_world_{n}"
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.timestep = timestep
    spec.option.integrator = int(integrator)
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    spec.stat.center = [0.0, 0.0, 0.0]
    spec.stat.extent = box_size
    if n > _DEFAULT_ARENA_MAX:
        # MuJoCo's default arena is sized for small models; its broadphase and collision pass
        # each take 2 (nbody + 1)^2 bytes of it (800 MB each at 20,000 spheres, measured:
        # "could not allocate memory" otherwise).
        spec.memory = int(64e6 + 4.4 * (n + 1) ** 2 + 20e3 * n)

    world = spec.worldbody
    world.add_light(pos=[0.0, 0.0, 2.0 * box_size], dir=[0.0, 0.0, -1.0])
    wall_names = ("floor", "ceiling", "wall_xneg", "wall_xpos", "wall_yneg", "wall_ypos")
    normals = np.array(
        [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=float
    )
    for name, normal in zip(wall_names, normals, strict=True):
        world.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            pos=-half * normal,
            quat=_quat_z_to(normal),
            size=[half, half, 0.05 * box_size],
            rgba=[0.6, 0.6, 0.7, 1.0 if name == "floor" else 0.08],
        )

    ctrl = mass * accel_max
    palette = rng.uniform(0.2, 0.9, size=(n, 3))

    # MuJoCo's spec lists its whole tree again on every element it adds and scans it on every
    # attach, so adding the spheres one by one is quadratic (37 s at 20,000). Leaves of 100
    # spheres are built apart, attached in groups of about sqrt(n / 100) leaves to a spec of
    # their own, the groups to the world: each attach meets a small spec or one of few.
    # Names come from the prefixes: leaf b > 0 holds its spheres' last two digits and is
    # attached with the prefix "b", the groups and leaf 0 (names 0-99) with "sphere".
    def sphere_specs(b: int) -> mujoco.MjSpec:
        ids = range(_LEAF * b, min(n, _LEAF * (b + 1)))
        names = [f"{i % _LEAF:02d}" if b else str(i) for i in ids]
        return _sphere_leaf(ids, names, centres, palette, radius=radius, mass=mass, ctrl=ctrl)

    leaves = -(-n // _LEAF)
    group = max(1, math.isqrt(leaves))
    _attach(spec, sphere_specs(0), "sphere")
    for first in range(1, leaves, group):
        part = mujoco.MjSpec()
        for b in range(first, min(leaves, first + group)):
            _attach(part, sphere_specs(b), str(b))
        _attach(spec, part, "sphere")

    spec.add_key(name="init", qpos=np.zeros(3 * n), qvel=velocity.reshape(-1))
    spec.add_numeric(name=ACCEL_BOUND_NUMERIC, size=1, data=[paper_world_accel_bound(accel_max)])
    return spec


_LEAF = 100
"""Spheres a leaf spec of :func:`paper_world_spec` holds (a power of ten: see its names)."""


def _attach(parent: mujoco.MjSpec, child: mujoco.MjSpec, prefix: str) -> None:
    """Attach ``child`` to ``parent``'s world, its names prefixed. The child's main default
    comes along as ``prefix + "main"``: deleted again, since a second one with the same name
    would make ``to_xml()`` unreadable."""
    parent.attach(child, prefix=prefix, frame=parent.worldbody.add_frame())
    parent.delete(parent.find_default(prefix + "main"))


def _sphere_leaf(
    ids: range,
    names: list[str],
    centres: np.ndarray,
    palette: np.ndarray,
    *,
    radius: float,
    mass: float,
    ctrl: float,
) -> mujoco.MjSpec:
    """The spheres ``ids`` of :func:`paper_world_spec` in a spec of their own, named ``names``
    (the prefixes attaching adds complete them): body and geom ``{name}``, joint and motor
    ``{name}_x`` (``_y``, ``_z``)."""
    spec = mujoco.MjSpec()
    for i, name in zip(ids, names, strict=True):
        body = spec.worldbody.add_body(name=name, pos=centres[i])
        for axis_name, axis in zip("xyz", np.eye(3), strict=True):
            joint = f"{name}_{axis_name}"
            body.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
            spec.add_actuator(
                name=joint,
                target=joint,
                trntype=mujoco.mjtTrn.mjTRN_JOINT,
                ctrlrange=[-ctrl, ctrl],
                ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE,
            )
        body.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[radius, 0.0, 0.0],
            mass=mass,
            rgba=[*palette[i], 1.0],
        )
    return spec


def paper_world_model(n: int, *, seed: int = 0, **kw: Any) -> mujoco.MjModel:
    """Compile :func:`paper_world_spec` (``kw`` are its keyword options).

    Returns:
        The compiled model with ``n`` spheres.
    """
    return paper_world_spec(n, seed=seed, **kw).compile()
