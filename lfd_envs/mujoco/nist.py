"""``NistBoardInsert-v0``: last-inch peg insertion on a NIST-style task board (thesis ch. 6).

The peg is already held by an end effector that moves in Cartesian space with compliance
(position servos with force limits on three slide joints; see :mod:`lfd_envs.mujoco.nist_board`
for the scene). A language instruction names the peg and the hole, e.g.
``"insert medium peg in large hole"``.

Tasks (``instruction=``): one instruction, a list of them, ``"all"`` (every pair the fit allows) or
``None`` = :data:`TRAIN_TASKS`, the thesis' two training tasks. :data:`HELDOUT_TASKS` holds the
unseen combination ``"insert small peg in large hole"``. Pegs and holes are tiny / small /
medium / large = 4 / 8 / 12 / 16 mm. ``fit="loose"`` uses these nominal diameters (a peg only
fits a larger hole); ``fit="tight"`` uses the NIST ATB1 clearances (pegs 3.988 / 7.986 / 11.983 /
15.983 mm, holes 4.1 / 8.1 / 12.2 / 16.5 mm), which adds the same-size pairs such as
``"insert medium peg in medium hole"`` (0.11 mm radial clearance). The task can also be chosen
per episode with ``reset(options={"instruction": "insert small peg in large hole"})``.

Observations (``obs_mode``):
    * ``"image"`` (default): ``Dict`` with one uint8 RGB image per camera in ``cameras``
      (``"workspace"``: static, ``"wrist"``: moves with the end effector; ``image_size`` = (H, W),
      default 128×160, 512×640 as in the thesis) and the instruction: ``"instruction"``
      (``gymnasium.spaces.Text``) with ``instruction_encoding="text"`` (the class default), or
      ``"instruction_tokens"`` = (peg size, hole size) indices, ``MultiDiscrete([4, 4])``, with
      ``instruction_encoding="tokens"`` (the default of ``gym.make("NistBoardInsert-v0")``: SB3
      policies cannot read ``Text``; :func:`instruction_from_tokens` turns them back into text).
    * ``"state+image"``: the same plus ``"state"`` (the vector below).
    * ``"state"``: float32 vector of 14: peg-tip position (3), tip velocity (3), compliance
      deflection = commanded target − tip (3), centre of the target hole's top (3), peg and hole
      diameters (2). No images are rendered.

Actions: ``action_mode="continuous"``: ``Box(-1, 1, (3,))`` Cartesian deltas of the commanded
tip position, scaled by ``max_delta`` (3 mm) per control step; ``action_mode="tokens"``:
``MultiDiscrete([n, n, n])`` with bins of ``ACTION_BIN`` = 0.3 mm per axis (token ``k`` moves
``(k - n // 2) · 0.3 mm``; n = 21 for the default ``max_delta``). Each env step applies the
action ``action_repeat`` times; one control step is 20 physics steps of 2 ms. The commanded
target is kept within the workspace and within 1 cm of the tip, so the contact force is at most
20 N per axis. Out-of-range actions are clipped (tokens to ``[0, n-1]``; tokens must be integers).

Episodes: the tip starts uniformly in a 12×12×8 cm box around the target hole (±6 cm in x and y,
1–9 cm above the board; x and y are snapped to the lattice of ``0.3 mm · action_repeat`` around
the hole, so that token actions can align exactly). Success: the peg tip is within 2 mm (laterally) of
the hole axis and within 1 mm of the hole bottom (15 mm deep). The episode terminates on success
and is truncated after ``horizon`` steps.

Contact model: the peg is a flat-bottomed cylinder that cannot tilt; holes are polygons of
boxes (see :mod:`lfd_envs.mujoco.nist_board`). A peg laterally off the hole axis by more than the
radial clearance lands on the board and stays there under the full 20 N press; at the full
descent speed (about 7.5 cm/s) the soft contacts act like a chamfer of roughly 0.05–0.15 mm, so
offsets up to about clearance + 0.1 mm may still slide in (tests use clearance + 0.3 mm).

Reward: the change of performance ``p = -‖tip − hole bottom centre‖`` (metres) per step, plus
``success_bonus`` (1.0) on the step that succeeds. ``info["is_success"]`` is always present.
"""

from __future__ import annotations

import re
import string
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np
from gymnasium import spaces

from lfd_envs.core.base_env import LfdEnv, check_seed, reset_options_dict
from lfd_envs.core.errors import as_real_array, check_bool, check_choice, check_float, check_int_range, check_str
from lfd_envs.core.state import check_range
from lfd_envs.mujoco import nist_board as board
from lfd_envs.mujoco.rendering import configure_gl_backend, make_renderer
from lfd_envs.mujoco.state_values import check_mujoco_state

configure_gl_backend()
import mujoco  # noqa: E402  (after the GL backend is chosen)

ACTION_BIN = 0.0003  #: token bin width (m), thesis §6.2.2
FRAME_SKIP = 20  #: physics steps per control step (0.04 s)
MAX_ACTION_REPEAT = 1000  #: largest ``action_repeat`` (40 s of physics per env step)
MAX_TARGET_ERROR = 0.01  #: commanded target stays within this distance (per axis) of the tip
START_HALF_XY = 0.06
START_Z = (0.01, 0.09)  #: start height range above the board top
SUCCESS_LATERAL = 0.002
SUCCESS_DEPTH_TOL = 0.001
WORKSPACE_LOW = np.array([-0.12, -0.12, board.BOARD_BASE - 0.01])
WORKSPACE_HIGH = np.array([0.12, 0.12, board.BOARD_TOP + 0.15])
CAMERAS = ("workspace", "wrist")
#: ``"text"``: ``obs["instruction"]`` is the instruction (``spaces.Text``); ``"tokens"``:
#: ``obs["instruction_tokens"]`` = (peg size, hole size) indices (``MultiDiscrete([4, 4])``, SB3-friendly)
INSTRUCTION_ENCODINGS = ("text", "tokens")
INSTRUCTION_CHARSET = string.ascii_lowercase + " "
_INSTRUCTION_RE = re.compile(r"^insert (\w+) peg in (\w+) hole$")


@dataclass(frozen=True)
class NistTask:
    """One peg/hole pair, named by its instruction."""

    instruction: str
    peg: int  #: index into ``nist_board.SIZE_NAMES``
    hole: int


def parse_task(instruction: str, fit: str = "loose") -> NistTask:
    """Parse ``"insert <size> peg in <size> hole"``; ``ValueError`` if it does not fit."""
    match = _INSTRUCTION_RE.match(str(instruction).strip().lower())
    names = board.SIZE_NAMES
    if match is None or match.group(1) not in names or match.group(2) not in names:
        raise ValueError(f"instruction must read 'insert <size> peg in <size> hole' with sizes {names}, "
                         f"got {instruction!r}; valid tasks for fit={fit!r}: {all_tasks(fit)}")
    peg, hole = names.index(match.group(1)), names.index(match.group(2))
    if board.PEG_DIAMETERS[fit][peg] >= board.HOLE_DIAMETERS[fit][hole]:
        raise ValueError(f"{instruction!r}: the peg does not fit the hole with fit={fit!r}; "
                         f"valid tasks: {all_tasks(fit)}")
    return NistTask(f"insert {names[peg]} peg in {names[hole]} hole", peg, hole)


def instruction_tokens(instruction: str) -> np.ndarray:
    """``(peg, hole)`` size indices (into ``nist_board.SIZE_NAMES``) of an instruction, int64."""
    match = _INSTRUCTION_RE.match(str(instruction).strip().lower())
    names = board.SIZE_NAMES
    if match is None or match.group(1) not in names or match.group(2) not in names:
        raise ValueError(f"instruction must read 'insert <size> peg in <size> hole' with sizes {names}, "
                         f"got {instruction!r}")
    return np.array([names.index(match.group(1)), names.index(match.group(2))], dtype=np.int64)


def instruction_from_tokens(tokens: Any) -> str:
    """The instruction of ``(peg, hole)`` size indices (inverse of :func:`instruction_tokens`)."""
    names = board.SIZE_NAMES
    peg, hole = (int(t) for t in np.asarray(tokens).reshape(2))
    if not (0 <= peg < len(names) and 0 <= hole < len(names)):
        raise ValueError(f"instruction tokens must be two size indices in [0, {len(names)}), got {tokens!r}")
    return f"insert {names[peg]} peg in {names[hole]} hole"


def all_tasks(fit: str = "loose") -> tuple[str, ...]:
    """Every instruction whose peg fits its hole for ``fit``."""
    out = []
    for h, hole in enumerate(board.SIZE_NAMES):
        for p, peg in enumerate(board.SIZE_NAMES):
            if board.PEG_DIAMETERS[fit][p] < board.HOLE_DIAMETERS[fit][h]:
                out.append(f"insert {peg} peg in {hole} hole")
    return tuple(out)


#: the thesis' training tasks and its held-out combination
TRAIN_TASKS = ("insert medium peg in large hole", "insert small peg in medium hole")
HELDOUT_TASKS = ("insert small peg in large hole",)


class NistBoardInsertEnv(LfdEnv):
    """Peg insertion into a NIST-style board with a compliant Cartesian end effector.

    See the module docstring for observations, actions, tasks, reward and success.

    Args:
        instruction: an instruction, a list of them, ``"all"`` or ``None`` (= :data:`TRAIN_TASKS`);
            each episode's task is drawn from the list by the variant generator.
        fit: ``"loose"`` (nominal diameters) or ``"tight"`` (NIST clearances).
        obs_mode: ``"image"``, ``"state+image"`` or ``"state"``.
        action_mode: ``"continuous"`` or ``"tokens"``.
        image_size: ``(height, width)`` of each camera image (or an int for square images).
        cameras: which of ``("workspace", "wrist")`` to render: a sequence of these names, or one
            name as a plain string (``"wrist"`` means ``("wrist",)``, like ``instruction``).
        action_repeat: control steps per env step (the same delta each time; at most
            :data:`MAX_ACTION_REPEAT`).
        max_delta: largest commanded motion per control step and axis (m).
        horizon: env steps before truncation.
        success_bonus: reward added on the successful step.
        antialias: 4× multisampling of camera images (about 3× slower with software OpenGL).
        render_mode: ``"rgb_array"`` (workspace camera at ``render_size``) or ``None``.
        render_size: ``(height, width)`` (or an int) of ``render()`` frames (default 256×320).
        instruction_encoding: ``"text"`` (``obs["instruction"]``, a ``spaces.Text``) or ``"tokens"``
            (``obs["instruction_tokens"]``, see :data:`INSTRUCTION_ENCODINGS`; the default of
            ``gym.make("NistBoardInsert-v0")``, since Stable-Baselines3 has no ``Text`` support).
    """

    task_name: ClassVar[str] = "NistBoardInsert"
    supported_obs_modes: ClassVar[tuple[str, ...]] = ("image", "state+image", "state")
    terminate_on_success: ClassVar[bool] = True
    render_size = (256, 320)

    def __init__(
        self,
        instruction: str | Sequence[str] | None = None,
        fit: str = "loose",
        obs_mode: str = "image",
        action_mode: str = "continuous",
        image_size: int | tuple[int, int] = (128, 160),
        cameras: Sequence[str] = CAMERAS,
        action_repeat: int = 1,
        max_delta: float = 0.003,
        horizon: int = 100,
        success_bonus: float = 1.0,
        antialias: bool = False,
        render_mode: str | None = None,
        render_size: int | tuple[int, int] | None = None,
        instruction_encoding: str = "text",
    ) -> None:
        super().__init__(obs_mode=obs_mode, image_size=image_size, render_mode=render_mode, horizon=horizon,
                         render_size=render_size)
        self.fit = check_choice("fit", fit, ("loose", "tight"))
        self.action_mode = check_choice("action_mode", action_mode, ("continuous", "tokens"))
        self.cameras = self._check_cameras(cameras)
        self.action_repeat = check_int_range("action_repeat", action_repeat, 1, MAX_ACTION_REPEAT)
        self.max_delta = check_float("max_delta", max_delta, ACTION_BIN, MAX_TARGET_ERROR)
        self.success_bonus = check_float("success_bonus", success_bonus)
        antialias = check_bool("antialias", antialias)
        self.instruction_encoding = check_choice("instruction_encoding", instruction_encoding, INSTRUCTION_ENCODINGS)
        self.tasks = self._check_tasks(instruction)
        self._task_list = tuple(parse_task(n, self.fit) for n in all_tasks(self.fit))
        self.num_bins = 2 * int(round(self.max_delta / ACTION_BIN)) + 1

        self.model = mujoco.MjModel.from_xml_string(board.scene_xml(self.fit))
        self.model.vis.quality.offsamples = 4 if antialias else 0
        self.data = mujoco.MjData(self.model)
        self._peg_geoms = [self.model.geom(f"peg_{n}").id for n in board.SIZE_NAMES]
        self._fingers = [self.model.geom("finger_l").id, self.model.geom("finger_r").id]
        self._renderers: dict[tuple[int, int], Any] = {}
        self._scene_option = mujoco.MjvOption()
        self._scene_option.geomgroup[board.HIDDEN_GROUP] = 0
        self._target = np.zeros(3)
        self._task_index = 0
        self._forced_task: NistTask | None = None

        if self.action_mode == "continuous":
            self.action_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
        else:
            self.action_space = spaces.MultiDiscrete(np.full(3, self.num_bins, dtype=np.int64))
        self.state_space = spaces.Box(-np.inf, np.inf, (14,), np.float32)
        self._finish_init()

    # ------------------------------------------------------------------ argument checks
    @staticmethod
    def _check_cameras(cameras: Sequence[str]) -> tuple[str, ...]:
        try:
            cams = (cameras,) if isinstance(cameras, str) else tuple(cameras)
        except TypeError:
            cams = ()
        if not cams or not all(isinstance(c, str) for c in cams) or len(set(cams)) != len(cams) \
                or any(c not in CAMERAS for c in cams):
            raise ValueError(f"cameras must be a non-empty subset of {CAMERAS}, got {cameras!r}")
        return cams

    def _check_tasks(self, instruction: str | Sequence[str] | None) -> tuple[NistTask, ...]:
        if instruction is None:
            names: Sequence[str] = TRAIN_TASKS
        elif isinstance(instruction, str):
            names = all_tasks(self.fit) if instruction == "all" else (instruction,)
        elif isinstance(instruction, (list, tuple)):
            names = tuple(check_str("instruction", n) for n in instruction)
        else:
            raise ValueError(f"instruction must be a str, a list of str, 'all' or None, got {instruction!r}")
        if not names:
            raise ValueError("instruction must name at least one task")
        return tuple(parse_task(n, self.fit) for n in names)

    # ------------------------------------------------------------------ spaces
    def _observation_space_for(self, obs_mode: str) -> spaces.Space:
        if obs_mode == "state":
            return self.state_space
        h, w = self.image_size
        obs: dict[str, spaces.Space] = {c: spaces.Box(0, 255, (h, w, 3), np.uint8) for c in self.cameras}
        if self.instruction_encoding == "text":
            obs["instruction"] = spaces.Text(max_length=64, min_length=1, charset=INSTRUCTION_CHARSET)
        else:
            n = len(board.SIZE_NAMES)
            obs["instruction_tokens"] = spaces.MultiDiscrete(np.array([n, n], dtype=np.int64))
        if obs_mode == "state+image":
            obs["state"] = self.state_space
        return spaces.Dict(obs)

    # ------------------------------------------------------------------ task geometry
    @property
    def task(self) -> NistTask:
        """The current episode's task."""
        return self._task_list[self._task_index]

    @property
    def instruction(self) -> str:
        return self.task.instruction

    @property
    def peg_diameter(self) -> float:
        return board.PEG_DIAMETERS[self.fit][self.task.peg]

    @property
    def hole_diameter(self) -> float:
        return board.HOLE_DIAMETERS[self.fit][self.task.hole]

    @property
    def clearance(self) -> float:
        """Radial clearance between the peg and its hole (m)."""
        return 0.5 * (self.hole_diameter - self.peg_diameter)

    @property
    def hole_top(self) -> np.ndarray:
        """Centre of the target hole's opening (x, y, board top)."""
        x, y = board.HOLE_XY[self.task.hole]
        return np.array([x, y, board.BOARD_TOP])

    @property
    def hole_depth(self) -> float:
        return board.HOLE_DEPTH

    @property
    def hole_bottom(self) -> np.ndarray:
        x, y = board.HOLE_XY[self.task.hole]
        return np.array([x, y, board.BOARD_TOP - board.HOLE_DEPTH])

    @property
    def tip_position(self) -> np.ndarray:
        """Peg tip position (the carriage's joint positions)."""
        return self.data.qpos[:3].copy()

    @property
    def commanded_target(self) -> np.ndarray:
        """The compliance controller's target position of the tip."""
        return self._target.copy()

    def set_commanded_target(self, position: np.ndarray) -> None:
        """Set the compliance controller's target (and the carriage servos' controls) to
        ``position`` ``(3,)``, e.g. after placing the tip by hand in ``data.qpos``."""
        self._target = np.array(position, dtype=float)
        self.data.ctrl[:] = self._target

    def _apply_task(self, index: int) -> None:
        """Make the task's peg the only colliding, visible peg and fit the fingers to it."""
        self._task_index = int(index)
        task = self.task
        for i, gid in enumerate(self._peg_geoms):
            active = i == task.peg
            self.model.geom_contype[gid] = 2 if active else 0
            self.model.geom_conaffinity[gid] = 1 if active else 0
            self.model.geom_group[gid] = 0 if active else board.HIDDEN_GROUP
        half = 0.5 * self.peg_diameter + 0.003
        self.model.geom_pos[self._fingers[0], 0] = half
        self.model.geom_pos[self._fingers[1], 0] = -half

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Gymnasium reset; ``options`` may also hold ``"instruction"`` (the task of this episode).
        Every option is checked before anything (the seed included) changes."""
        self._check_open("reset")
        check_seed(seed)
        options = reset_options_dict(options)
        forced = options.pop("instruction", None)
        task = None if forced is None else parse_task(check_str("options['instruction']", forced), self.fit)
        self._check_reset(options)
        self._forced_task = task
        return super().reset(seed=seed, options=options)

    def _setup_variant(self, rng: np.random.Generator) -> None:
        choice = self.tasks[int(rng.integers(len(self.tasks)))]
        offset_xy = rng.uniform(-START_HALF_XY, START_HALF_XY, 2)
        height = rng.uniform(*START_Z)
        task = self._forced_task or choice
        self._apply_task(self._task_list.index(task))
        hole = self.hole_top
        start = np.empty(3)
        lattice = ACTION_BIN * self.action_repeat  # reachable by token actions, see the module docstring
        start[:2] = hole[:2] + np.round(offset_xy / lattice) * lattice
        start[2] = hole[2] + height
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = start
        self._target = start.copy()
        self.data.ctrl[:] = start
        mujoco.mj_forward(self.model, self.data)

    def delta_from_action(self, action: np.ndarray) -> np.ndarray:
        """Commanded motion (m) of one control step for a validated action."""
        if self.action_mode == "continuous":
            return np.asarray(action, dtype=np.float64) * self.max_delta
        return (np.asarray(action, dtype=np.float64) - self.num_bins // 2) * ACTION_BIN

    def action_from_delta(self, delta: np.ndarray) -> np.ndarray:
        """The action of this env's ``action_mode`` closest to a commanded motion ``delta`` (m)."""
        delta = np.asarray(delta, dtype=np.float64)
        if self.action_mode == "continuous":
            return np.clip(delta / self.max_delta, -1.0, 1.0).astype(np.float32)
        half = self.num_bins // 2
        return (np.clip(np.round(delta / ACTION_BIN), -half, half) + half).astype(np.int64)

    def _apply_action(self, action: np.ndarray) -> None:
        delta = self.delta_from_action(action)
        for _ in range(self.action_repeat):
            tip = self.data.qpos[:3]
            target = np.clip(self._target + delta, WORKSPACE_LOW, WORKSPACE_HIGH)
            self._target = np.clip(target, tip - MAX_TARGET_ERROR, tip + MAX_TARGET_ERROR)
            self.data.ctrl[:] = self._target
            mujoco.mj_step(self.model, self.data, nstep=FRAME_SKIP)
        if not np.all(np.isfinite(self.data.qpos)):
            raise RuntimeError("NistBoardInsert simulation diverged (non-finite state)")

    def validate_action(self, action: Any) -> np.ndarray:
        """Box actions as in :class:`LfdEnv`; tokens: 3 integers, clipped to ``[0, num_bins-1]``."""
        if self.action_mode == "continuous":
            return super().validate_action(action)
        shape = (3,)
        arr = as_real_array("action (integer tokens)", action, shape).reshape(-1)
        if arr.shape != shape:
            raise ValueError(f"action must have shape {shape} (tokens), got shape {np.shape(action)}")
        if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise ValueError(f"action must be finite integer tokens of shape {shape}, got {action!r}")
        return np.clip(arr, 0, self.num_bins - 1).astype(np.int64)

    # ------------------------------------------------------------------ observations
    def _state_obs(self) -> np.ndarray:
        tip = self.data.qpos[:3]
        return np.concatenate([
            tip, self.data.qvel[:3], self._target - tip, self.hole_top,
            [self.peg_diameter, self.hole_diameter],
        ]).astype(np.float32)

    def _renderer(self, height: int, width: int) -> Any:
        key = (int(height), int(width))
        if key not in self._renderers:
            self._renderers[key] = make_renderer(self.model, *key)
        return self._renderers[key]

    def camera_image(self, camera: str, height: int | None = None, width: int | None = None) -> np.ndarray:
        """RGB uint8 image of ``camera`` (default size: ``image_size``)."""
        check_choice("camera", camera, CAMERAS)
        h, w = self.image_size if height is None else (height, width or height)
        renderer = self._renderer(h, w)
        renderer.update_scene(self.data, camera=camera, scene_option=self._scene_option)
        return renderer.render()

    def _observation(self) -> Any:
        if self.obs_mode == "state":
            return self._state_obs()
        obs: dict[str, Any] = {c: self.camera_image(c) for c in self.cameras}
        if self.instruction_encoding == "text":
            obs["instruction"] = self.instruction
        else:
            obs["instruction_tokens"] = instruction_tokens(self.instruction)
        if self.obs_mode == "state+image":
            obs["state"] = self._state_obs()
        return obs

    def _render(self, height: int, width: int) -> np.ndarray:
        return self.camera_image("workspace", height, width)

    # ------------------------------------------------------------------ task metrics
    def _performance(self) -> float:
        return -float(np.linalg.norm(self.data.qpos[:3] - self.hole_bottom))

    def _is_success(self) -> bool:
        tip = self.data.qpos[:3]
        bottom = self.hole_bottom
        lateral = float(np.linalg.norm(tip[:2] - bottom[:2]))
        return lateral <= SUCCESS_LATERAL and tip[2] <= bottom[2] + SUCCESS_DEPTH_TOL

    def _reward(self, performance: float, prev_performance: float) -> float:
        bonus = self.success_bonus if self._is_success() else 0.0
        return float(performance - prev_performance) + bonus

    # ------------------------------------------------------------------ state
    def _get_sim_state(self) -> dict[str, np.ndarray]:
        d = self.data
        return {
            "qpos": d.qpos.copy(), "qvel": d.qvel.copy(), "ctrl": d.ctrl.copy(),
            "qacc_warmstart": d.qacc_warmstart.copy(), "time": np.array(d.time),
            "target": self._target.copy(), "task": np.array(self._task_index, dtype=np.int64),
        }

    def _task_identity(self) -> dict[str, Any]:
        return {"task": self.task_name, "fit": self.fit, "instruction": tuple(t.instruction for t in self.tasks)}

    def _check_sim_state(self, sim: dict[str, np.ndarray]) -> None:
        check_range("sim/task", sim["task"], 0, len(self._task_list) - 1)
        check_range("sim/time", sim["time"], 0.0)
        check_mujoco_state(self.model, sim)
        target = sim["target"]
        if np.any(target < WORKSPACE_LOW - 1e-9) or np.any(target > WORKSPACE_HIGH + 1e-9):
            raise ValueError(f"state['sim/target'] must lie in the workspace [{WORKSPACE_LOW}, {WORKSPACE_HIGH}], "
                             f"got {target}")

    def _set_sim_state(self, state: dict[str, np.ndarray]) -> None:
        required = {"qpos", "qvel", "ctrl", "qacc_warmstart", "time", "target", "task"}
        missing = sorted(required - set(state))
        if missing:
            raise ValueError(f"NistBoardInsert state is missing {missing}; pass a dict from get_state()")
        task = int(state["task"])
        if not 0 <= task < len(self._task_list):
            raise ValueError(f"state task index {task} is out of range for fit={self.fit!r}")
        self._apply_task(task)
        d = self.data
        d.qpos[:] = state["qpos"]
        d.qvel[:] = state["qvel"]
        d.ctrl[:] = state["ctrl"]
        d.time = float(state["time"])
        self._target = np.array(state["target"], dtype=np.float64)
        mujoco.mj_forward(self.model, d)
        d.qacc_warmstart[:] = state["qacc_warmstart"]

    def close(self) -> None:
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
        super().close()


__all__ = ["NistBoardInsertEnv", "NistTask", "parse_task", "all_tasks", "instruction_tokens", "instruction_from_tokens", "TRAIN_TASKS", "HELDOUT_TASKS",
           "ACTION_BIN", "CAMERAS"]
