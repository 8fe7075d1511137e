"""MJCF scene of the NIST task-board peg insertion (``NistBoardInsert-v0``).

Geometry (metres, z up, board centred at the origin):

* a table plane at z = 0 and a board of thickness ``BOARD_BASE + HOLE_DEPTH``; its top is at
  :data:`BOARD_TOP`. The four round holes (tiny 4, small 8, medium 12, large 16 mm nominal)
  sit on a 2×2 grid (:data:`HOLE_XY`) and are blind: their bottom is the base slab.
* MuJoCo collides meshes as their convex hull, so each hole is a ring of boxes whose inner
  faces are tangent to the hole circle: the hole is the regular polygon with that inradius, with
  enough sides (:func:`ring_segments`) that its corners lie at most 20 µm outside the circle. The ring
  boxes are long enough to cover their whole grid cell, and a frame of four boxes closes the
  board's top layer. All geoms have zero margin, so clearances down to tens of micrometres
  are resolved (SPEC §5; reference note §4.3).
* the end effector is a body on three slide joints (x, y, z) driven by position servos with
  force limits: a Cartesian impedance whose contact force cannot exceed :data:`FORCE_LIMIT`.
  The body origin is the peg tip, so the joint positions are the tip position. It carries one
  peg geom per size (only the task's peg collides and is drawn; the others are moved to the
  hidden geom group :data:`HIDDEN_GROUP`), two visual fingers and the ``wrist`` camera.
* a static ``workspace`` camera looks at the board from the front and above.
"""

from __future__ import annotations

import numpy as np

#: size names in increasing order (instructions use them: "insert small peg in large hole")
SIZE_NAMES: tuple[str, ...] = ("tiny", "small", "medium", "large")
#: diameters (m) per fit: loose = nominal sizes; tight = NIST ATB1 / IndustReal values
PEG_DIAMETERS: dict[str, tuple[float, ...]] = {
    "loose": (0.004, 0.008, 0.012, 0.016),
    "tight": (0.003988, 0.007986, 0.011983, 0.015983),
}
HOLE_DIAMETERS: dict[str, tuple[float, ...]] = {
    "loose": (0.004, 0.008, 0.012, 0.016),
    "tight": (0.0041, 0.0081, 0.0122, 0.0165),
}
#: hole centres on the board (same order as SIZE_NAMES)
HOLE_XY: tuple[tuple[float, float], ...] = ((0.025, -0.025), (-0.025, -0.025), (0.025, 0.025), (-0.025, 0.025))
CELL = 0.05  #: grid cell of one hole (m)
HOLE_DEPTH = 0.015
BOARD_BASE = 0.012
BOARD_TOP = BOARD_BASE + HOLE_DEPTH
BOARD_HALF = 0.075  #: half side of the square board
RING_WIDTH = 0.0025  #: radial width of the ring of boxes around a hole (to the square's edge)
MARGIN = 1e-5  #: contact margin of the board (keeps resting contacts detected; holes are widened by it)
MAX_POLYGON_EXCESS = 2e-5  #: the polygonal hole's corners lie at most 20 µm outside the circle
PEG_LENGTH = 0.05
FORCE_LIMIT = 20.0  #: N, per axis
KP = 2000.0  #: N/m, Cartesian stiffness per axis
KV = 60.0  #: N·s/m, damping (about critical for the 0.5 kg carriage)
EE_MASS = 0.5
TIMESTEP = 0.002
HIDDEN_GROUP = 4

_CONTACT = 'solref="0.004 1" solimp="0.99 0.999 0.0001 0.5 2" gap="0"'
_BOARD_RGBA = "0.66 0.68 0.70 1"
_HOLE_RGBA = "0.08 0.08 0.1 1"
_PEG_RGBA = ("0.85 0.35 0.25 1", "0.25 0.55 0.85 1", "0.95 0.7 0.2 1", "0.35 0.7 0.35 1")


def _look_at(pos: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 0.0, 1.0])) -> str:
    """MJCF ``xyaxes`` of a camera at ``pos`` looking at ``target``."""
    forward = target - pos
    forward = forward / np.linalg.norm(forward)
    x = np.cross(forward, up)
    x = x / np.linalg.norm(x)
    y = np.cross(x, forward)
    return " ".join(f"{v:.6f}" for v in (*x, *y))


def ring_segments(radius: float) -> int:
    """Sides of the polygonal hole of inradius ``radius`` (corners ≤ MAX_POLYGON_EXCESS outside)."""
    n = np.pi / np.arccos(radius / (radius + MAX_POLYGON_EXCESS))
    return max(16, int(np.ceil(n)))


def _ring(name: str, cx: float, cy: float, radius: float) -> list[str]:
    """Top layer of one hole's grid cell: a ring of boxes tangent to the hole circle (made
    ``MARGIN`` wider to cancel the contact margin) inside a square, and four boxes filling the
    cell around that square."""
    segments = ring_segments(radius)
    inner = radius + MARGIN
    half_square = radius + RING_WIDTH
    outer = half_square * np.sqrt(2.0) + 0.0002
    half_len = 0.5 * (outer - inner)
    half_w = outer * np.tan(np.pi / segments)
    z = BOARD_BASE + 0.5 * HOLE_DEPTH
    hz = 0.5 * HOLE_DEPTH
    geoms = []
    for k in range(segments):
        a = 2.0 * np.pi * k / segments
        c = inner + half_len
        geoms.append(
            f'<geom name="{name}_ring{k}" class="board" type="box" size="{half_len:.7f} {half_w:.7f} {hz:.7f}" '
            f'pos="{cx + c * np.cos(a):.7f} {cy + c * np.sin(a):.7f} {z:.7f}" euler="0 0 {a:.7f}"/>')
    half_cell = 0.5 * CELL
    strip = 0.5 * (half_cell - half_square)
    mid = half_square + strip
    fills = [  # (centre offset, half sizes): strips above/below span the cell, left/right the square
        ((0.0, mid), (half_cell, strip)), ((0.0, -mid), (half_cell, strip)),
        ((mid, 0.0), (strip, half_square)), ((-mid, 0.0), (strip, half_square)),
    ]
    for k, ((ox, oy), (hx, hy)) in enumerate(fills):
        geoms.append(f'<geom name="{name}_fill{k}" class="board" type="box" size="{hx:.7f} {hy:.7f} {hz:.7f}" '
                     f'pos="{cx + ox:.7f} {cy + oy:.7f} {z:.7f}"/>')
    return geoms


def _frame() -> list[str]:
    """Four boxes closing the board's top layer around the 2×2 grid of hole cells."""
    inner = CELL  # the grid spans [-CELL, CELL]²
    w = 0.5 * (BOARD_HALF - inner)
    z = BOARD_BASE + 0.5 * HOLE_DEPTH
    hz = 0.5 * HOLE_DEPTH
    c = inner + w
    return [
        f'<geom name="frame_px" class="board" type="box" size="{w} {BOARD_HALF} {hz}" pos="{c} 0 {z}"/>',
        f'<geom name="frame_nx" class="board" type="box" size="{w} {BOARD_HALF} {hz}" pos="{-c} 0 {z}"/>',
        f'<geom name="frame_py" class="board" type="box" size="{inner} {w} {hz}" pos="0 {c} {z}"/>',
        f'<geom name="frame_ny" class="board" type="box" size="{inner} {w} {hz}" pos="0 {-c} {z}"/>',
    ]


def _pegs(fit: str) -> list[str]:
    geoms = []
    for i, name in enumerate(SIZE_NAMES):
        r = 0.5 * PEG_DIAMETERS[fit][i]
        geoms.append(
            f'<geom name="peg_{name}" class="peg" type="cylinder" size="{r:.7f} {0.5 * PEG_LENGTH}" '
            f'pos="0 0 {0.5 * PEG_LENGTH}" rgba="{_PEG_RGBA[i]}"/>')
    return geoms


def scene_xml(fit: str) -> str:
    """MJCF of the whole scene for ``fit`` ("loose" or "tight")."""
    holes = []
    for i, name in enumerate(SIZE_NAMES):
        holes += _ring(f"hole_{name}", *HOLE_XY[i], 0.5 * HOLE_DIAMETERS[fit][i])
    ws_pos = np.array([0.0, -0.26, 0.30])
    ws_cam = _look_at(ws_pos, np.array([0.0, 0.0, BOARD_TOP + 0.035]))
    wr_pos = np.array([0.0, -0.075, 0.085])
    wr_cam = _look_at(wr_pos, np.array([0.0, 0.0, -0.012]))
    finger = 'class="visual" type="box" size="0.003 0.009 0.012" rgba="0.2 0.2 0.22 1"'
    actuator = (f'kp="{KP}" kv="{KV}" forcelimited="true" forcerange="-{FORCE_LIMIT} {FORCE_LIMIT}" '
                f'ctrllimited="false"')
    lines = "\n      ".join
    return f"""
<mujoco model="nist_board_insert">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{TIMESTEP}" integrator="implicitfast" cone="pyramidal">
    <flag multiccd="disable"/>
  </option>
  <visual>
    <global offwidth="640" offheight="512"/>
    <quality shadowsize="0" offsamples="0"/>
    <headlight ambient="0.3 0.3 0.3" diffuse="0.35 0.35 0.35" specular="0.05 0.05 0.05"/>
  </visual>
  <default>
    <default class="board">
      <geom contype="1" conaffinity="1" friction="0.5 0.005 0.0001" rgba="{_BOARD_RGBA}" margin="{MARGIN}"
            {_CONTACT}/>
    </default>
    <default class="peg">
      <geom contype="2" conaffinity="1" friction="0.5 0.005 0.0001" density="8000" margin="0" {_CONTACT}/>
    </default>
    <default class="visual">
      <geom contype="0" conaffinity="0" group="1" mass="0"/>
    </default>
  </default>
  <worldbody>
    <light name="key" pos="0.15 -0.25 0.6" dir="-0.25 0.4 -1" directional="true" castshadow="false"
           diffuse="0.35 0.35 0.35"/>
    <geom name="table" type="plane" size="0.5 0.5 0.01" rgba="0.45 0.36 0.28 1" contype="0" conaffinity="0"/>
    <geom name="board_base" class="board" type="box" size="{BOARD_HALF} {BOARD_HALF} {0.5 * BOARD_BASE}"
          pos="0 0 {0.5 * BOARD_BASE}" rgba="{_HOLE_RGBA}"/>
      {lines(_frame())}
      {lines(holes)}
    <camera name="workspace" pos="{ws_pos[0]} {ws_pos[1]} {ws_pos[2]}" xyaxes="{ws_cam}" fovy="45"/>
    <body name="ee" pos="0 0 0" gravcomp="1">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0.06" mass="{EE_MASS}" diaginertia="0.001 0.001 0.001"/>
      {lines(_pegs(fit))}
      <geom name="palm" class="visual" type="box" size="0.022 0.012 0.008" pos="0 0 0.058"
            rgba="0.25 0.25 0.28 1"/>
      <geom name="finger_l" {finger} pos="0.01 0 0.038"/>
      <geom name="finger_r" {finger} pos="-0.01 0 0.038"/>
      <camera name="wrist" pos="{wr_pos[0]} {wr_pos[1]} {wr_pos[2]}" xyaxes="{wr_cam}" fovy="60"/>
    </body>
  </worldbody>
  <actuator>
    <position name="ax" joint="x" {actuator}/>
    <position name="ay" joint="y" {actuator}/>
    <position name="az" joint="z" {actuator}/>
  </actuator>
</mujoco>
"""


__all__ = ["scene_xml", "ring_segments", "SIZE_NAMES", "PEG_DIAMETERS", "HOLE_DIAMETERS", "HOLE_XY", "HOLE_DEPTH",
           "BOARD_TOP", "PEG_LENGTH", "FORCE_LIMIT", "KP", "TIMESTEP", "HIDDEN_GROUP"]
