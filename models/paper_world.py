"""The paper's sphere world as a MuJoCo model: spheres in a box driven by bounded actuators."""

from __future__ import annotations

import copy
import math
from typing import Any

import mujoco
import numpy as np

from dua_mujoco._core import candidate_pairs
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


_Block = tuple[mujoco.MjSpec, Any]  # for _attach: a template (spec, None) or (spec, its frame)
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
    # Give up after this many rejections in a row: the free volume is then too fragmented.
    max_misses = 20_000
    # The sampler draws candidates 64 at a time and accepts each one no closer than min_dist to
    # every centre accepted before it. Whole chunks of those batches are judged at once (the grid
    # of candidate pairs finds the close ones; distances in the same operations, in the same
    # order, as the sampler took them one by one), then the chain of acceptances is followed
    # in order; the generator is advanced by the batches the sampler would have drawn. The
    # placement, and the generator's state after it, are the sequential sampler's.
    centres = np.zeros((0, 3))
    misses = 0
    while centres.shape[0] < n:
        placed = centres.shape[0]
        nbatch = min(-(-(n - placed) // 64) + 2, 1024)
        ahead = copy.deepcopy(rng)
        cand = ahead.uniform(lo, hi, size=(64 * nbatch, 3))
        accepted = _accepted(centres, cand, min_dist)
        take = np.flatnonzero(accepted)[: n - placed]
        judged = int(take[-1]) + 1 if take.size == n - placed else cand.shape[0]
        # Rejections in a row before each acceptance, and after the last one judged.
        runs = np.diff(np.concatenate([[-1 - misses], take, [judged]])) - 1
        if (runs > max_misses).any():
            first = int(np.argmax(runs > max_misses))
            raise InvalidInputError(
                f"Could not place {n} spheres of radius {radius} without overlap in a "
                f"cube of side {2 * half} (placed {placed + first}); use fewer spheres, a smaller "
                "radius or a larger box_size."
            )
        misses = int(runs[-1])
        rng.uniform(lo, hi, size=(64 * -(-judged // 64), 3))  # the batches the sampler drew
        centres = np.concatenate([centres, cand[take]])
    return centres


def _accepted(centres: np.ndarray, cand: np.ndarray, min_dist: float) -> np.ndarray:
    """``(m,)`` which of the candidates ``cand`` (m, 3), taken in order, the sampler accepts after
    ``centres`` (p, 3): those no closer than ``min_dist`` to any centre or accepted candidate."""
    p, m = centres.shape[0], cand.shape[0]
    pts = np.concatenate([centres, cand])
    pairs = candidate_pairs(pts, np.full(p + m, min_dist / 2), 0.0)  # every pair that close
    i, j = pairs[:, 0], pairs[:, 1]  # i < j: j a candidate, i a centre or an earlier candidate
    i, j = i[j >= p], j[j >= p]
    a, b = pts[i], pts[j]
    dx, dy, dz = a[:, 0] - b[:, 0], a[:, 1] - b[:, 1], a[:, 2] - b[:, 2]
    close = np.sqrt(dx * dx + dy * dy + dz * dz) < min_dist
    i, j = i[close], j[close] - p
    accepted = np.ones(m, dtype=bool)
    accepted[j[i < p]] = False
    among = i >= p
    first, second = i[among] - p, j[among]
    # In order of the later candidate: the earlier one's fate is settled when it is read.
    order = np.lexsort((first, second))
    for f, s in zip(first[order].tolist(), second[order].tolist(), strict=True):
        if accepted[f]:
            accepted[s] = False
    return accepted


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

    palette = rng.uniform(0.2, 0.9, size=(n, 3))

    # Adding spheres one by one to a spec (or parsing MJCF) is quadratic (37 s at 20,000); an
    # attach costs about 12 us a body of the parent and 20 a sphere attached. So the ids are cut
    # into decimal blocks whose names share a head and run over all k-digit tails (ids 1000-1999:
    # "sphere1" + "000" ... "999"), each attached once with its head as prefix (29 at 20,000).
    blocks = _SphereBlocks(centres, palette, radius=radius, mass=mass, ctrl=mass * accel_max)
    for head, k, count in _decimal_blocks(n):
        _attach(spec, blocks.spec(int(head[len("sphere") :] or 0) * 10**k, k, count), head)

    spec.add_key(name="init", qpos=np.zeros(3 * n), qvel=velocity.reshape(-1))
    spec.add_numeric(name=ACCEL_BOUND_NUMERIC, size=1, data=[paper_world_accel_bound(accel_max)])
    return spec


def _decimal_blocks(n: int) -> list[tuple[str, int, int]]:
    """Sphere ids ``0 .. n-1`` cut into blocks ``(prefix, k, count)``, in order: the block's
    spheres are named ``prefix`` followed by the ``k``-digit tails ``0 .. count-1`` (zero-padded),
    ``count = 10**k`` but for the last block of fewer than ten (``k = 1``). Each block is the
    largest that starts at the next id, is aligned to its size and keeps the ids' digit count."""
    out = []
    first = 0
    while first < n:
        digits = len(str(first))
        k = 1 if first == 0 else 0  # ids 0-9: the empty head, one digit
        while k + 1 < digits and first % 10 ** (k + 1) == 0 and first + 10 ** (k + 1) <= n:
            k += 1
        if k == 0 or first + 10**k > n:  # the last ids: fewer than ten after a multiple of ten
            k = 1
        count = min(10**k, n - first)
        out.append(("sphere" + str(first)[: digits - k] if first else "sphere", k, count))
        first += count
    return out


def _attach(parent: mujoco.MjSpec, child: _Block, prefix: str, into: Any = None) -> None:
    """Attach a block to ``parent``'s world in a frame (``into`` if given), names prefixed: a
    template ``(spec, None)`` is copied; ``(spec, frame)`` moved as the frame holding it all (a
    spec's attach scans its top elements once per element: docs/many-objects.md, quadratic).
    The child's main default, ``prefix + "main"``, is deleted: two make ``to_xml()`` unreadable."""
    spec, frame = child
    parent.copy_during_attach = frame is None
    into = into or parent.worldbody.add_frame()
    if frame is None:
        parent.attach(spec, prefix=prefix, frame=into)
    else:
        parent.worldbody.attach_frame(frame, prefix=prefix).set_frame(into)
    parent.copy_during_attach = False  # MjSpec's default (the flag can only be set)
    parent.delete(parent.find_default(prefix + "main"))


class _SphereBlocks:
    """Specs of the spheres of :func:`paper_world_spec` by decimal block, placed and coloured.

    A block of ``k <= 3`` digits is a template built once (the one of ``k = 1`` sphere by sphere,
    the others from ten copies of the one below, prefixed "0" ... "9"), its bodies listed once
    (MuJoCo lists a spec's bodies in quadratic time: 1.4 s for 10,000) and set to the spheres'
    positions and colours before each attach, which copies it. A larger block is built anew
    in one frame from ten blocks of ``k - 1`` digits, set as they are attached, and is moved.
    """

    TEMPLATE_DIGITS = 3

    def __init__(
        self, centres: np.ndarray, palette: np.ndarray, *, radius: float, mass: float, ctrl: float
    ) -> None:
        self._centres, self._palette = centres.tolist(), palette.tolist()
        self._radius, self._mass, self._ctrl = radius, mass, ctrl
        self._templates: dict[tuple[int, int], tuple[mujoco.MjSpec, list[Any], list[Any]]] = {}

    def spec(self, first: int, k: int, count: int) -> _Block:
        """The spheres ``first .. first + count - 1`` (``count = 10**k``, or fewer than ten for
        ``k = 1``) named by their last ``k`` digits: body and geom ``{tail}``, joint and motor
        ``{tail}_x`` (``_y``, ``_z``). A template's spec is shared: attach it before the next."""
        if k > self.TEMPLATE_DIGITS:
            spec = mujoco.MjSpec()
            frame = spec.worldbody.add_frame()
            step = 10 ** (k - 1)
            for digit in range(10):
                _attach(spec, self.spec(first + digit * step, k - 1, step), str(digit), into=frame)
            return spec, frame
        spec, bodies, geoms = self._template(k, count)
        for body, geom, i in zip(bodies, geoms, range(first, first + count), strict=True):
            body.pos, geom.rgba = self._centres[i], [*self._palette[i], 1.0]
        return spec, None

    def _template(self, k: int, count: int) -> tuple[mujoco.MjSpec, list[Any], list[Any]]:
        """The template of ``count`` spheres of ``k`` digits, its bodies and geoms in id order."""
        if (k, count) not in self._templates:
            spec = mujoco.MjSpec()
            if k > 1:
                below = self._template(k - 1, 10 ** (k - 1))[0]
                for digit in range(10):
                    _attach(spec, (below, None), str(digit))
            for i in range(count if k == 1 else 0):
                self._add_sphere(spec, str(i))
            bodies = spec.worldbody.bodies
            self._templates[k, count] = spec, bodies, [body.first_geom() for body in bodies]
        return self._templates[k, count]

    def _add_sphere(self, spec: mujoco.MjSpec, name: str) -> None:
        body = spec.worldbody.add_body(name=name)
        for axis_name, axis in zip("xyz", np.eye(3), strict=True):
            joint = f"{name}_{axis_name}"
            body.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
            spec.add_actuator(
                name=joint,
                target=joint,
                trntype=mujoco.mjtTrn.mjTRN_JOINT,
                ctrlrange=[-self._ctrl, self._ctrl],
                ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE,
            )
        body.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[self._radius, 0.0, 0.0],
            mass=self._mass,
        )


def paper_world_model(n: int, *, seed: int = 0, **kw: Any) -> mujoco.MjModel:
    """Compile :func:`paper_world_spec` (``kw`` are its keyword options).

    Returns:
        The compiled model with ``n`` spheres.
    """
    return paper_world_spec(n, seed=seed, **kw).compile()
