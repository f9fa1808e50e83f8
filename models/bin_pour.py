"""The ``bin_pour`` scene: hundreds of loose objects poured into a bin.

Bin picking and granular piles are ordinary MuJoCo work: a walled bin on the floor, and above
it a hopper of free objects (boxes, spheres, capsules, cylinders, ellipsoids, a few centimetres
each) stacked in layers that fall in under gravity, the lowest first, and settle into a pile.
Nothing is actuated, so every collision comes from gravity and the pile's own impacts: a scene
where the bounds are broken by impacts all the time (docs/theory.md, section 6), and where
almost every pair is far apart at any moment (the case pruned pairs are for).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from dua_mujoco.exceptions import InvalidInputError

__all__ = ["BIN_POUR_DEFAULT", "bin_pour_spec"]

BIN_POUR_DEFAULT = 300
"""Objects in the bundled ``bin_pour`` scene (``bin_pour:N`` for another count)."""

_SIZE = 0.02  # an object's half-extent (m)
_PITCH = 0.065  # distance between objects in the hopper (m): they start apart
_WALL = 0.01  # half-thickness of the bin's walls (m)

_TYPES = (
    (mujoco.mjtGeom.mjGEOM_BOX, (1.0, 0.7, 0.5)),
    (mujoco.mjtGeom.mjGEOM_SPHERE, (0.9, 0.0, 0.0)),
    (mujoco.mjtGeom.mjGEOM_CAPSULE, (0.55, 0.9, 0.0)),
    (mujoco.mjtGeom.mjGEOM_CYLINDER, (0.8, 0.7, 0.0)),
    (mujoco.mjtGeom.mjGEOM_ELLIPSOID, (1.0, 0.75, 0.6)),
)


def bin_pour_spec(n: int = BIN_POUR_DEFAULT, *, seed: int = 0) -> mujoco.MjSpec:
    """A bin on the floor and ``n`` free objects in a hopper above it.

    The bin's floor area grows with ``n`` so that the pile stays a few layers deep; the hopper
    is a square of ``k x k`` objects a layer, as many layers as it takes.

    Args:
        n: Number of objects (>= 1).
        seed: Seed of the objects' shapes, orientations and colours.

    Returns:
        An uncompiled ``MjSpec``; ``spec.compile()`` gives the model.

    Raises:
        InvalidInputError: ``n`` < 1.
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise InvalidInputError(f"n = {n!r} is invalid: pass an int >= 1 (objects in the bin).")
    rng = np.random.default_rng(seed)
    # About four layers of settled objects (side 2 * _SIZE) fill the bin.
    inner = max(0.2, 2.2 * _SIZE * math.sqrt(n / 4))  # side of the bin's floor (m)
    half = 0.5 * inner
    k = max(1, int(inner / _PITCH))  # objects a side of a hopper layer
    layers = math.ceil(n / (k * k))
    wall_height = 0.5 * max(0.12, 2.2 * _SIZE * 4)

    spec = mujoco.MjSpec()
    spec.modelname = f"bin_pour_{n}"
    spec.option.timestep = 0.002
    spec.option.gravity = [0.0, 0.0, -9.81]
    # Conjugate gradient: Newton's Hessian over a pile of hundreds of free bodies costs 40x more
    # a step (measured: 101 ms against 2.7 ms for 300 objects in contact).
    spec.option.solver = mujoco.mjtSolver.mjSOL_CG
    spec.option.iterations = 30
    # The pile holds about six contacts an object: size the arena for them (MuJoCo's default
    # arena is sized for small scenes and stops a large one with "could not allocate memory").
    spec.memory = int(64e6 + 40e3 * n)
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    top = 2 * wall_height + (layers + 1) * _PITCH
    spec.stat.center = [0.0, 0.0, 0.5 * top]
    spec.stat.extent = max(inner, top)

    world = spec.worldbody
    world.add_light(pos=[0.0, -0.5 * inner, 2.0 * top], dir=[0.0, 0.2, -1.0])
    world.add_geom(
        name="floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[2 * inner, 2 * inner, 0.05],
        rgba=[0.3, 0.32, 0.35, 1.0],
    )
    for name, axis, sign in (("x-", 0, -1), ("x+", 0, 1), ("y-", 1, -1), ("y+", 1, 1)):
        pos = np.zeros(3)
        pos[axis] = sign * (half + _WALL)
        pos[2] = wall_height
        size = [half + 2 * _WALL, half + 2 * _WALL, wall_height]
        size[axis] = _WALL
        world.add_geom(
            name=f"wall {name}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=pos,
            size=size,
            rgba=[0.55, 0.55, 0.6, 0.5],
        )

    offset = 0.5 * (k - 1) * _PITCH
    for i in range(n):
        layer, cell = divmod(i, k * k)
        row, col = divmod(cell, k)
        # Odd layers shifted by half a pitch: the layers do not fall straight onto each other.
        shift = 0.25 * _PITCH * (layer % 2)
        at = [
            col * _PITCH - offset + shift,
            row * _PITCH - offset + shift,
            2 * wall_height + (layer + 1) * _PITCH,
        ]
        kind, scale = _TYPES[int(rng.integers(len(_TYPES)))]
        quat = rng.normal(size=4)
        body = world.add_body(name=f"object{i}", pos=at, quat=quat / np.linalg.norm(quat))
        body.add_freejoint()
        body.add_geom(
            name=f"object{i}",
            type=kind,
            size=[_SIZE * s for s in scale],
            density=500.0,
            friction=[0.8, 0.01, 0.001],
            rgba=[*rng.uniform(0.25, 0.95, size=3), 1.0],
        )
    return spec
