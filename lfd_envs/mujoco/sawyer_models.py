"""MJCF composition for the Sawyer obstructed-manipulation scenes.

robosuite 1.5 is used **only** as a model library: its ``Sawyer`` arm, ``RethinkGripper`` and
``RethinkMount`` classes compose an MJCF fragment (with absolute mesh paths into the installed
package) that compiles with plain ``mujoco``. Everything else -- actuators, joint dynamics,
simulator options, the scene (tables, tunnel, bin, furniture, objects) -- is written here and
in the task modules, following the MoPA-RL parameters (SPEC §5):

* the arm's torque motors are replaced by position servos, kp = (500, 500, 200, 200, 50, 50, 50),
  force limits (100, 100, 75, 75, 50, 50, 50) N·m, joint damping (50, 50, 25, 25, 10, 10, 10),
  armature 0.1, no joint friction;
* every robot body (and anything attached to the gripper) has MuJoCo's body ``gravcomp=1``:
  gravity is cancelled inside every 2 ms physics substep;
* the robot's collision cylinders become capsules (analytic collisions, MoPA-RL's choice);
* the robot base sits at ``ROBOT_BASE_POS`` = (0, 0, 0.95), as in MoPA-RL.

Names in the compiled model keep robosuite's prefixes (``robot0_right_j0`` ...,
``gripper0_right_grip_site``, ``fixed_mount0_*``).
"""

from __future__ import annotations

import copy
import functools
import logging
from collections import defaultdict
import warnings
import xml.etree.ElementTree as ET
from typing import Sequence

import mujoco
import numpy as np

ROBOT_BASE_POS = (0.0, 0.0, 0.95)
ARM_JOINTS = tuple(f"robot0_right_j{i}" for i in range(7))
FINGER_JOINTS = ("gripper0_right_l_finger_joint", "gripper0_right_r_finger_joint")
GRIP_SITE = "gripper0_right_grip_site"
GRIPPER_BODY = "gripper0_right_gripper_base"
EEF_BODY = "gripper0_right_eef"
LEFT_FINGER_GEOMS = ("gripper0_right_l_finger_g0", "gripper0_right_l_finger_g1",
                     "gripper0_right_l_fingertip_g0", "gripper0_right_l_fingerpad_g0")
RIGHT_FINGER_GEOMS = ("gripper0_right_r_finger_g0", "gripper0_right_r_finger_g1",
                      "gripper0_right_r_fingertip_g0", "gripper0_right_r_fingerpad_g0")

#: MoPA-RL servo gains, force limits and joint damping (SPEC §5, mopa_sawyer_nist.md §1.1)
ARM_KP = (500.0, 500.0, 200.0, 200.0, 50.0, 50.0, 50.0)
ARM_FORCE_LIMIT = (100.0, 100.0, 75.0, 75.0, 50.0, 50.0, 50.0)
ARM_DAMPING = (50.0, 50.0, 25.0, 25.0, 10.0, 10.0, 10.0)
ARM_ARMATURE = 0.1
#: finger opening (slide joint) that counts as "closed" / "open" for the left finger;
#: the right finger mirrors it (negated)
FINGER_CLOSED, FINGER_OPEN = -0.0115, 0.020833


def _import_robosuite_models():
    """Import robosuite's model classes without its start-up warnings reaching users."""
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from robosuite.models.bases import robot_base_factory
            from robosuite.models.grippers import gripper_factory
            from robosuite.models.robots import Sawyer
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("the Sawyer tasks need robosuite>=1.5 for the arm/gripper models: "
                          "pip install robosuite") from exc
    finally:
        logging.disable(previous)
    logging.getLogger("robosuite_logs").setLevel(logging.ERROR)
    return Sawyer, gripper_factory, robot_base_factory


@functools.lru_cache(maxsize=None)
def robosuite_sawyer_xml() -> str:
    """MJCF string of robosuite's Sawyer + RethinkMount + RethinkGripper (cached per process)."""
    Sawyer, gripper_factory, robot_base_factory = _import_robosuite_models()
    robot = Sawyer()
    robot.add_base(robot_base_factory("RethinkMount", idn=0))
    robot.add_gripper(gripper_factory("RethinkGripper", idn="0_right"), robot.eef_name["right"])
    return robot.get_xml()


#: colours of the robot's collision primitives (drawn when ``robot_visual="primitive"``)
_PRIMITIVE_RGBA = defaultdict(lambda: "0.78 0.12 0.1 1", {"fixed": "0.2 0.2 0.22 1", "gripper0": "0.18 0.18 0.2 1"})


def fmt(values: Sequence[float]) -> str:
    """Numbers as an MJCF attribute string."""
    return " ".join(f"{float(v):.6g}" for v in values)


def _arm_actuators(gripper_kp: float) -> str:
    lines = []
    for name, kp, f in zip(ARM_JOINTS, ARM_KP, ARM_FORCE_LIMIT):
        lines.append(f'<position name="{name}_servo" joint="{name}" kp="{kp:g}" '
                     f'forcelimited="true" forcerange="{-f:g} {f:g}" ctrllimited="false"/>')
    lo, hi = FINGER_CLOSED, FINGER_OPEN
    lines.append(f'<position name="gripper_l_servo" joint="{FINGER_JOINTS[0]}" kp="{gripper_kp:g}" '
                 f'ctrlrange="{lo:g} {hi:g}" forcerange="-20 20"/>')
    lines.append(f'<position name="gripper_r_servo" joint="{FINGER_JOINTS[1]}" kp="{gripper_kp:g}" '
                 f'ctrlrange="{-hi:g} {-lo:g}" forcerange="-20 20"/>')
    return "\n".join(lines)


def _prepare_robot(root: ET.Element, attach_to_eef: str) -> ET.Element:
    """Return the robot's root body with MoPA joint dynamics and hidden collision geoms."""
    worldbody = root.find("worldbody")
    assert worldbody is not None
    bodies = list(worldbody)
    robot_body = next(b for b in bodies if b.tag == "body" and b.get("name") == "robot0_base")
    robot_body.set("pos", fmt(ROBOT_BASE_POS))
    damping = dict(zip(ARM_JOINTS, ARM_DAMPING))
    for joint in root.iter("joint"):
        name = joint.get("name", "")
        if name in damping:
            joint.set("damping", f"{damping[name]:g}")
            joint.set("armature", f"{ARM_ARMATURE:g}")
            joint.set("frictionloss", "0")
    for geom in robot_body.iter("geom"):  # collision geoms: group 3 (hidden in renders)
        if geom.get("contype", "1") != "0" or geom.get("conaffinity", "1") != "0":
            geom.set("group", "3")
            geom.set("rgba", _PRIMITIVE_RGBA[geom.get("name", "").split("_")[0]])
            if geom.get("type") == "cylinder":  # capsules as in MoPA-RL: analytic, faster contacts
                radius, half = (float(v) for v in geom.get("size").split()[:2])
                geom.set("type", "capsule")
                geom.set("size", f"{radius:g} {max(half - radius, 1e-3):g}")
    for site in robot_body.iter("site"):  # robosuite's marker sites: hidden
        site.set("group", "4")
    if attach_to_eef:
        eef = next(b for b in robot_body.iter("body") if b.get("name") == EEF_BODY)
        for child in ET.fromstring(f"<wrap>{attach_to_eef}</wrap>"):
            eef.append(child)
    # MuJoCo sizes its gravity-compensation pass at compile time (``ngravcomp``), so the flag
    # must be in the MJCF: setting ``body_gravcomp`` on a compiled model without any has no effect.
    for body in robot_body.iter("body"):
        body.set("gravcomp", "1")
    return robot_body


def _strip_visual_geoms(root: ET.Element, robot_body: ET.Element) -> None:
    """Remove the robot's visual-only geoms (group 1) and the mesh assets nobody uses any more."""
    for parent in robot_body.iter("body"):
        for geom in [g for g in parent.findall("geom") if g.get("group") == "1"]:
            parent.remove(geom)
    used = {g.get("mesh") for g in robot_body.iter("geom")}
    assets = root.find("asset")
    if assets is not None:
        for mesh in [a for a in assets.findall("mesh") if a.get("name") not in used]:
            assets.remove(mesh)


_SCENE_TEMPLATE = """
<mujoco model="{name}">
  <compiler angle="radian" autolimits="true" inertiafromgeom="auto"/>
  <option timestep="0.002" integrator="implicitfast" cone="elliptic" impratio="{impratio}"
          iterations="50" tolerance="1e-8" noslip_iterations="{noslip}"/>
  <size memory="20M"/>
  <visual><global offwidth="640" offheight="640"/><quality shadowsize="0"/>
    <headlight ambient="0.45 0.45 0.45" diffuse="0.5 0.5 0.5" specular="0.1 0.1 0.1"/></visual>
  <default>
    <default class="scene"><geom rgba="0.72 0.6 0.45 1" friction="1 0.005 0.0001"/></default>
    <default class="obstacle"><geom rgba="0.55 0.6 0.7 1" friction="1 0.005 0.0001"/></default>
    {defaults}
  </default>
  <asset>
    <texture name="floor_tex" type="2d" builtin="checker" rgb1="0.82 0.82 0.8" rgb2="0.7 0.7 0.68"
             width="64" height="64"/>
    <material name="floor_mat" texture="floor_tex" texrepeat="6 6"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1" material="floor_mat" contype="1" conaffinity="1"/>
    <light name="key" pos="0.6 -0.6 3" dir="0 0.2 -1" directional="true" diffuse="0.5 0.5 0.5" castshadow="false"/>
    {cameras}
    {scene}
  </worldbody>
  <contact>{excludes}</contact>
  <actuator>{actuators}</actuator>
</mujoco>
"""


def compose_scene_xml(
    name: str,
    scene: str,
    cameras: str,
    *,
    attach_to_eef: str = "",
    excludes: Sequence[tuple[str, str]] = (),
    gripper_kp: float = 1000.0,
    impratio: float = 1.0,
    noslip_iterations: int = 0,
    defaults: str = "",
    robot_meshes: bool = True,
) -> str:
    """Full MJCF of a Sawyer scene.

    Args:
        name: model name.
        scene: MJCF ``<body>``/``<geom>`` elements added to the world body (tables, obstacles, objects).
        cameras: MJCF ``<camera>`` elements in the world body.
        attach_to_eef: MJCF elements appended to the gripper's ``eef`` body (e.g. a held tool).
        excludes: body-name pairs whose contacts are excluded.
        gripper_kp: finger servo stiffness.
        impratio, noslip_iterations: solver options (friction-heavy scenes raise them).
        defaults: extra MJCF ``<default class=...>`` elements (classes ``scene`` and ``obstacle`` exist).
        robot_meshes: keep robosuite's visual meshes of the robot (≈280k triangles). Without them
            the robot is drawn with its collision primitives, the model compiles faster and each
            physics step is ~10 % cheaper (fewer geoms in the broad phase).
    """
    robot_root = ET.fromstring(robosuite_sawyer_xml())
    robot_body = _prepare_robot(robot_root, attach_to_eef)
    if not robot_meshes:
        _strip_visual_geoms(robot_root, robot_body)
    base_excl = [("robot0_right_arm_base_link", "robot0_right_l0"), ("robot0_base", "robot0_right_l0")]
    excl = "".join(f'<exclude body1="{a}" body2="{b}"/>' for a, b in [*base_excl, *excludes])
    xml = _SCENE_TEMPLATE.format(
        name=name, impratio=impratio, noslip=int(noslip_iterations), cameras=cameras,
        scene=scene, excludes=excl, defaults=defaults, actuators=_arm_actuators(gripper_kp))
    root = ET.fromstring(xml)
    assets = root.find("asset")
    for element in robot_root.find("asset") or []:
        assets.append(element)
    root.find("worldbody").append(robot_body)
    return ET.tostring(root, encoding="unicode")


@functools.lru_cache(maxsize=None)
def _compiled(xml: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(xml)


def load_model(xml: str) -> mujoco.MjModel:
    """Compile ``xml`` (cached per process) and return a private copy of the model."""
    return copy.deepcopy(_compiled(xml))


def ids(model: mujoco.MjModel, kind: mujoco.mjtObj, names: Sequence[str]) -> np.ndarray:
    """Ids of named objects, with a clear error for a missing name."""
    out = []
    for n in names:
        i = mujoco.mj_name2id(model, kind, n)
        if i < 0:
            raise KeyError(f"model has no {kind.name[6:].lower()} named {n!r}")
        out.append(i)
    return np.asarray(out, dtype=np.int64)


def body_geoms(model: mujoco.MjModel, body_names: Sequence[str], collidable_only: bool = True) -> list[int]:
    """Geom ids of the given bodies (optionally only those that can collide)."""
    bodies = set(ids(model, mujoco.mjtObj.mjOBJ_BODY, body_names).tolist())
    out = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] in bodies:
            if not collidable_only or model.geom_contype[g] or model.geom_conaffinity[g]:
                out.append(g)
    return out


def subtree_bodies(model: mujoco.MjModel, root_name: str) -> list[int]:
    """Ids of ``root_name`` and every body below it."""
    root = int(ids(model, mujoco.mjtObj.mjOBJ_BODY, [root_name])[0])
    out = []
    for b in range(model.nbody):
        a = b
        while a > 0 and a != root:
            a = model.body_parentid[a]
        if a == root:
            out.append(b)
    return out


def box(name: str, pos: Sequence[float], half: Sequence[float], cls: str = "obstacle", **attrs: str) -> str:
    """MJCF of a box geom."""
    extra = "".join(f' {k}="{v}"' for k, v in attrs.items())
    return f'<geom name="{name}" class="{cls}" type="box" pos="{fmt(pos)}" size="{fmt(half)}"{extra}/>'


def work_table(pos: Sequence[float], half: Sequence[float], name: str = "table") -> str:
    """A table body: a top box whose upper face is at ``pos[2] + half[2]``, plus four legs."""
    hx, hy, hz = half
    leg_half = (pos[2] - hz) / 2
    legs = "".join(
        f'<geom name="{name}_leg{i}" class="scene" type="cylinder" size="0.025 {leg_half:.4f}" '
        f'pos="{sx * (hx - 0.04):.4f} {sy * (hy - 0.04):.4f} {-hz - leg_half:.4f}" '
        f'contype="0" conaffinity="0"/>'
        for i, (sx, sy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)])) if leg_half > 0.005 else ""
    top = box(f"{name}_top", (0, 0, 0), half, cls="scene")
    return f'<body name="{name}" pos="{fmt((pos[0], pos[1], pos[2]))}">{top}{legs}</body>'
