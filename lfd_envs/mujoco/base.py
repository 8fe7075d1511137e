"""Base class of the MuJoCo envs: model, servo control, observations, state, rendering.

A task subclasses :class:`MujocoEnv` (and usually
:class:`~lfd_envs.mujoco.planning.PlanningMixin`, listed first) and writes::

    class MyEnv(PlanningMixin, MujocoEnv):
        task_name = "MyTask"
        camera = "frontview"                 # camera for images; -1 = free camera
        goal_dim = 3                         # only for goal-conditioned support

        def __init__(self, obs_mode="state", image_size=84, render_mode=None, horizon=250,
                     goal_conditioned=False):
            super().__init__(obs_mode=obs_mode, image_size=image_size,
                             render_mode=render_mode, horizon=horizon)
            self._init_mujoco(XML, arm_joint_names=[...], dq_step=0.05, frame_skip=75,
                              timestep=0.002, servo_kp=[...], gravity_compensation="gravcomp",
                              init_arm_qpos=[...], goal_conditioned=goal_conditioned)
            self.state_space = spaces.Box(-np.inf, np.inf, (n,), np.float32)
            self._finish_init()

        def _setup_variant(self, rng):      # rng: the variant's generator
            self._reset_sim()                # arm at init pose + noise (env's seeded RNG)
            ...place objects / goal from rng...
            self._forward()

        def _state_obs(self): ...
        def _task_reward(self): ...          # per-step reward (documented per task)
        def _is_success(self): ...
        def _performance(self): ...

Control (MoPA-RL): the action's first ``d = len(arm_joint_names)`` entries are
joint-position deltas in [-1, 1] scaled by ``dq_step`` (rad); the servo set-point is
``clip(q_ref + a * dq_step, joint_limits)`` where ``q_ref`` is the measured arm position
at the start of the step (or the previous waypoint while :meth:`execute_path` runs, i.e.
open-loop chaining as in MoPA-RL). The set-point is held for ``frame_skip`` physics steps of
``timestep`` seconds. Further action dimensions (e.g. a gripper) are passed to
:meth:`_apply_extra_action`. Out-of-range actions are clipped to [-1, 1].

Gravity compensation (``gravity_compensation``):
    ``"none"``: the model is used as is (MJCF ``gravcomp`` attributes still act);
    ``"gravcomp"``: MuJoCo's native body gravity compensation is switched on for every body
    that moves with the arm (exact, inside every substep; fastest: one ``mj_step`` call);
    ``"bias"``: MoPA-RL's scheme, ``qfrc_applied[arm dofs] = qfrc_bias[arm dofs]`` before
    every substep (gravity + Coriolis; needs the Euler or implicit integrator).

Observations: ``obs_mode`` ``"state"`` (``_state_obs``), ``"image"`` (uint8 RGB H×W×3,
**default 84×84 for MuJoCo envs**, from ``camera``), ``"state+image"`` (Dict). With
``goal_conditioned=True`` (``obs_mode="state"`` only) the env is a ``gymnasium_robotics.core.GoalEnv``
instance, the observation is the ``GoalEnv`` Dict ``{"observation", "achieved_goal",
"desired_goal"}`` and ``compute_reward`` is vectorised for SB3's ``HerReplayBuffer``. Without it
the env has no ``compute_reward`` at all (SB3's ``check_env`` would take it for a goal env).

Episodes: terminated on success (MoPA-RL), truncated after ``horizon`` low-level steps.
"""

from __future__ import annotations

import contextlib
import inspect
import io
from typing import Any, ClassVar, Sequence

import mujoco
import numpy as np
from gymnasium import spaces

from lfd_envs.core.base_env import LfdEnv
from lfd_envs.core.errors import check_bool, check_choice
from lfd_envs.core.state import check_range
from lfd_envs.mujoco.rendering import make_renderer
from lfd_envs.mujoco.state_values import check_mujoco_state

with contextlib.redirect_stderr(io.StringIO()):  # gymnasium-robotics prints a notice about its own envs
    from gymnasium_robotics.core import GoalEnv

#: bounds used for hinge joints without limits (documented in ``joint_limits``)
CONTINUOUS_JOINT_RANGE = (-2.0 * np.pi, 2.0 * np.pi)
GRAVITY_COMPENSATION_MODES = ("none", "gravcomp", "bias")
#: data fields saved by ``get_state`` (besides the task's own extras)
_STATE_FIELDS = ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "qfrc_applied", "xfrc_applied",
                 "mocap_pos", "mocap_quat")


def _load_model(model: str | mujoco.MjModel, assets: dict[str, bytes] | None) -> mujoco.MjModel:
    if isinstance(model, mujoco.MjModel):
        return model
    if not isinstance(model, str):
        raise TypeError(f"model must be an MJCF string or a mujoco.MjModel, got {type(model).__name__}")
    return mujoco.MjModel.from_xml_string(model, assets or {})


class MujocoEnv(LfdEnv):
    """Base of every MuJoCo env (see the module docstring for the subclass recipe).

    Attributes set by :meth:`_init_mujoco`:
        model, data: the ``mujoco.MjModel`` / live ``mujoco.MjData``.
        arm_joint_names: names of the controlled arm joints (action order).
        joint_limits: ``(d, 2)`` float64 bounds of the arm joints; unlimited hinges get
            :data:`CONTINUOUS_JOINT_RANGE` (±2π) and are flagged in ``continuous_joints``.
        continuous_joints: ``(d,)`` bool, True for arm joints without limits.
        dq_step: joint displacement (rad) of a full action (|a_i| = 1).
        frame_skip: physics steps per env step; ``dt`` = ``frame_skip * timestep``.
        n_extra_actions: action dims after the arm dims (gripper ...).
        goal_conditioned: whether observations are ``GoalEnv`` Dicts.
    """

    terminate_on_success: ClassVar[bool] = True
    #: camera (name or id; -1 = MuJoCo's free camera) used for image observations and render()
    camera: ClassVar[str | int] = -1
    #: multisample anti-aliasing of the offscreen renderer (0 = off: ~2.5x faster on software GL)
    render_multisamples: ClassVar[int] = 0
    #: length of achieved/desired goal vectors; 0 = task has no goal-conditioned variant
    goal_dim: ClassVar[int] = 0
    #: info keys (floats) that :meth:`_goal_reward` needs besides the goals. Avoid if possible:
    #: SB3's ``HerReplayBuffer`` passes empty infos unless ``copy_info_dict=True``
    reward_info_keys: ClassVar[tuple[str, ...]] = ()

    def __new__(cls, *args: Any, **kwargs: Any) -> "MujocoEnv":
        """Instances made with ``goal_conditioned=True`` are of a subclass that is also a
        ``gymnasium_robotics.core.GoalEnv`` (:func:`goal_env_class`); the others have no
        ``compute_reward`` (so tools do not take them for goal envs)."""
        if cls.goal_dim > 0 and not issubclass(cls, GoalEnvMixin) and _wants_goal(cls, args, kwargs):
            cls = goal_env_class(cls)
        return super().__new__(cls, *args, **kwargs)

    # ------------------------------------------------------------------ construction
    def _init_mujoco(
        self,
        model: str | mujoco.MjModel,
        *,
        arm_joint_names: Sequence[str],
        dq_step: float,
        frame_skip: int,
        timestep: float | None = None,
        servo_kp: Sequence[float] | None = None,
        servo_kv: Sequence[float] | None = None,
        gravity_compensation: str = "none",
        init_arm_qpos: Sequence[float] | None = None,
        init_noise: str = "normal",
        init_noise_scale: float = 0.02,
        n_extra_actions: int = 0,
        goal_conditioned: bool = False,
        assets: dict[str, bytes] | None = None,
    ) -> None:
        """Load the model and set up control. Call after ``super().__init__(...)``.

        Args:
            model: MJCF string (``assets`` maps file names to bytes) or a compiled model.
            arm_joint_names: controlled hinge/slide joints, in action order. Each must be driven
                by exactly one actuator with a joint transmission (a position servo).
            dq_step: rad per unit action (0.05 for Sawyer, 0.1 for 2D Push).
            frame_skip: physics steps per env step (75 for Sawyer).
            timestep: physics step (s); overrides the MJCF value when given.
            servo_kp / servo_kv: per-joint position gain / velocity damping written into the arm
                actuators (``gainprm[0]=kp, biasprm[1]=-kp, biasprm[2]=-kv``); None keeps the MJCF.
            gravity_compensation: ``"none"``, ``"gravcomp"`` or ``"bias"`` (module docstring).
            init_arm_qpos: nominal start pose of the arm (default: the model's ``qpos0``).
            init_noise / init_noise_scale: start-pose noise per joint, ``"normal"`` N(0, scale)
                or ``"uniform"`` U(-scale, scale), drawn from the env's seeded RNG.
            n_extra_actions: action dims after the arm (handled by ``_apply_extra_action``).
            goal_conditioned: ``GoalEnv`` Dict observations (needs ``goal_dim > 0``).
        """
        if int(frame_skip) < 1:
            raise ValueError(f"frame_skip must be >= 1, got {frame_skip}")
        if not float(dq_step) > 0:
            raise ValueError(f"dq_step must be > 0, got {dq_step}")
        self.gravity_compensation = check_choice("gravity_compensation", gravity_compensation,
                                                 GRAVITY_COMPENSATION_MODES)
        self.model = _load_model(model, assets)
        self._init_arm(list(arm_joint_names))
        if self.gravity_compensation == "gravcomp" and not np.all(self.model.body_gravcomp[self._arm_body_mask] == 1):
            self.model = self._compile_with_gravcomp(model, assets)
        if timestep is not None:
            self.model.opt.timestep = float(timestep)
        self.data = mujoco.MjData(self.model)
        self.frame_skip = int(frame_skip)
        self.dq_step = float(dq_step)
        self.n_extra_actions = int(n_extra_actions)
        self._init_servos(servo_kp, servo_kv)
        if self.gravity_compensation == "bias" and int(self.model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
            raise ValueError("gravity_compensation='bias' needs the Euler or an implicit integrator, not RK4")
        q0 = self.model.qpos0[self._arm_qadr] if init_arm_qpos is None else np.asarray(init_arm_qpos, np.float64)
        if q0.shape != (self.n_arm,):
            raise ValueError(f"init_arm_qpos must have shape ({self.n_arm},), got {q0.shape}")
        self.init_arm_qpos = q0.copy()
        self.init_noise = check_choice("init_noise", init_noise, ("normal", "uniform"))
        self.init_noise_scale = float(init_noise_scale)
        self.goal_conditioned = check_bool("goal_conditioned", goal_conditioned)
        if self.goal_conditioned:
            if self.goal_dim <= 0:
                raise ValueError(f"{type(self).__name__} has no goal-conditioned variant")
            if self.obs_mode != "state":
                raise ValueError(f"goal_conditioned=True needs obs_mode='state', got {self.obs_mode!r}")
        self.action_space = spaces.Box(-1.0, 1.0, (self.n_arm + self.n_extra_actions,), np.float32)
        self._path_reference: np.ndarray | None = None
        self._renderers: dict[tuple[int, int], Any] = {}

    def _init_arm(self, names: list[str]) -> None:
        m = self.model
        if not names:
            raise ValueError("arm_joint_names must name at least one joint")
        ids = []
        for name in names:
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                raise ValueError(f"arm joint {name!r} not in the model")
            if int(m.jnt_type[jid]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                raise ValueError(f"arm joint {name!r} must be a hinge or slide joint")
            ids.append(jid)
        self.arm_joint_names = list(names)
        self.n_arm = len(ids)
        self._arm_jid = np.array(ids)
        self._arm_qadr = m.jnt_qposadr[self._arm_jid].copy()
        self._arm_dofadr = m.jnt_dofadr[self._arm_jid].copy()
        limited = m.jnt_limited[self._arm_jid].astype(bool)
        self.continuous_joints = ~limited
        self.joint_limits = np.where(limited[:, None], m.jnt_range[self._arm_jid], np.array(CONTINUOUS_JOINT_RANGE))
        act = []
        for name, jid in zip(names, ids):
            hits = np.flatnonzero((m.actuator_trntype == int(mujoco.mjtTrn.mjTRN_JOINT)) & (m.actuator_trnid[:, 0] == jid))
            if len(hits) != 1:
                raise ValueError(f"arm joint {name!r} needs exactly one joint actuator, found {len(hits)}")
            act.append(int(hits[0]))
        self._arm_act = np.array(act)
        # bodies that move with the arm: the subtree of the first arm joint's body
        root = m.jnt_bodyid[self._arm_jid].min()
        self._arm_body_mask = self._subtree_mask(int(root))

    def _compile_with_gravcomp(self, model: str | mujoco.MjModel, assets: dict[str, bytes] | None) -> mujoco.MjModel:
        """Recompile the MJCF with ``gravcomp=1`` on every body that moves with the arm.

        (MuJoCo decides at compile time whether gravity compensation runs at all, so setting
        ``model.body_gravcomp`` afterwards would have no effect.)
        """
        if not isinstance(model, str):
            raise ValueError("gravity_compensation='gravcomp' needs the MJCF string (or gravcomp=\"1\" on the arm "
                             "bodies of the compiled model)")
        spec = mujoco.MjSpec.from_string(model, assets=assets or {})
        for body, moves in zip(spec.bodies, self._arm_body_mask):
            if moves:
                body.gravcomp = 1.0
        return spec.compile()

    def _subtree_mask(self, root: int) -> np.ndarray:
        """Bool mask over bodies: ``root`` and all its descendants."""
        m = self.model
        mask = np.zeros(m.nbody, bool)
        mask[root] = True
        for b in range(root + 1, m.nbody):  # parents always precede children
            mask[b] = mask[m.body_parentid[b]]
        return mask

    def _init_servos(self, kp: Sequence[float] | None, kv: Sequence[float] | None) -> None:
        m, act = self.model, self._arm_act
        if kp is not None:
            kp = np.broadcast_to(np.asarray(kp, np.float64), (self.n_arm,))
            m.actuator_gainprm[act, 0] = kp
            m.actuator_biasprm[act, 1] = -kp
            m.actuator_biastype[act] = mujoco.mjtBias.mjBIAS_AFFINE
            m.actuator_gaintype[act] = mujoco.mjtGain.mjGAIN_FIXED
        if kv is not None:
            m.actuator_biasprm[act, 2] = -np.broadcast_to(np.asarray(kv, np.float64), (self.n_arm,))

    def _finish_init(self) -> None:
        """Build ``observation_space`` (GoalEnv Dict when goal-conditioned). Call last in ``__init__``."""
        super()._finish_init()
        if self.goal_conditioned:
            goal = spaces.Box(-np.inf, np.inf, (self.goal_dim,), np.float32)
            self.observation_space = spaces.Dict(
                {"observation": self.state_space, "achieved_goal": goal, "desired_goal": goal})

    @property
    def dt(self) -> float:
        """Seconds of simulated time per env step."""
        return float(self.model.opt.timestep * self.frame_skip)

    # ------------------------------------------------------------------ simulation helpers
    def arm_qpos(self) -> np.ndarray:
        """Current arm configuration ``(d,)`` (a copy) from the live simulation."""
        return self.data.qpos[self._arm_qadr].copy()

    def arm_qvel(self) -> np.ndarray:
        """Current arm joint velocities ``(d,)`` (a copy)."""
        return self.data.qvel[self._arm_dofadr].copy()

    @property
    def arm_actuators(self) -> np.ndarray:
        """Actuator ids of the arm's joint servos ``(d,)`` in arm joint order (a copy)."""
        return self._arm_act.copy()

    def _reset_sim(self) -> None:
        """``mj_resetData``; arm at ``init_arm_qpos`` + noise (env RNG), servos holding it.

        Call at the start of ``_setup_variant``; place objects afterwards, then ``_forward()``.
        """
        mujoco.mj_resetData(self.model, self.data)
        rng, s = self.np_random, self.init_noise_scale
        noise = rng.normal(0.0, s, self.n_arm) if self.init_noise == "normal" else rng.uniform(-s, s, self.n_arm)
        q = np.clip(self.init_arm_qpos + noise, self.joint_limits[:, 0], self.joint_limits[:, 1])
        self.data.qpos[self._arm_qadr] = q
        self.data.ctrl[self._arm_act] = q
        self._path_reference = None

    def _forward(self) -> None:
        """Recompute derived quantities (positions, contacts) of the live data."""
        mujoco.mj_forward(self.model, self.data)

    def _apply_action(self, action: np.ndarray) -> None:
        arm = action[: self.n_arm].astype(np.float64)
        ref = self.data.qpos[self._arm_qadr] if self._path_reference is None else self._path_reference
        target = np.clip(ref + arm * self.dq_step, self.joint_limits[:, 0], self.joint_limits[:, 1])
        self.data.ctrl[self._arm_act] = target
        if self.n_extra_actions:
            self._apply_extra_action(action[self.n_arm:])
        self._simulate()
        self._after_simulate()

    def _apply_extra_action(self, extra: np.ndarray) -> None:
        """Handle action dims after the arm (e.g. set the gripper ctrl). Override if any."""
        raise NotImplementedError(f"{type(self).__name__} declares extra actions but does not handle them")

    def _simulate(self) -> None:
        """Run ``frame_skip`` physics steps with the current controls."""
        m, d = self.model, self.data
        if self.gravity_compensation != "bias":
            mujoco.mj_step(m, d, nstep=self.frame_skip)
            return
        dofs = self._arm_dofadr
        for _ in range(self.frame_skip):
            mujoco.mj_step1(m, d)
            d.qfrc_applied[dofs] = d.qfrc_bias[dofs]
            mujoco.mj_step2(m, d)

    def _after_simulate(self) -> None:
        """Hook run after the physics steps of every env step (default: nothing)."""

    # ------------------------------------------------------------------ rewards and goals
    def _task_reward(self) -> float:
        """Reward of the current step (documented per task). Subclasses implement."""
        raise NotImplementedError

    def _reward(self, performance: float, prev_performance: float) -> float:
        """``_task_reward()``; with ``goal_conditioned`` the GoalEnv reward of the current goals
        (so ``reward == compute_reward(achieved_goal, desired_goal, info)`` holds exactly)."""
        if self.goal_conditioned:
            return float(self.compute_reward(self._achieved_goal(), self._desired_goal(), self._reward_info()))
        return float(self._task_reward())

    def _reward_info(self) -> dict[str, float]:
        """Extra floats added to every ``info`` (must contain ``reward_info_keys``)."""
        return {}

    def _info(self, performance: float) -> dict[str, Any]:
        info = super()._info(performance)
        info.update(self._reward_info())
        return info

    def _achieved_goal(self) -> np.ndarray:
        """Achieved goal ``(goal_dim,)`` of the current state (goal-conditioned tasks)."""
        raise NotImplementedError

    def _desired_goal(self) -> np.ndarray:
        """Desired goal ``(goal_dim,)`` of the episode (goal-conditioned tasks)."""
        raise NotImplementedError

    def _goal_reward(self, achieved: np.ndarray, desired: np.ndarray, extras: dict[str, np.ndarray]) -> np.ndarray:
        """Vectorised reward: ``achieved``/``desired`` ``(n, goal_dim)``, ``extras[key]`` ``(n,)`` → ``(n,)``.

        With ``goal_conditioned`` this *is* the step reward; it may differ from
        :meth:`_task_reward` by goal-independent shaping terms (documented per task).
        """
        raise NotImplementedError

    def _goal_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """Vectorised success ``(n,)`` bool for goals ``(n, goal_dim)``."""
        raise NotImplementedError

    # ------------------------------------------------------------------ observations
    def _observation(self) -> Any:
        if self.goal_conditioned:
            return {"observation": self._state_obs(),
                    "achieved_goal": np.asarray(self._achieved_goal(), np.float32),
                    "desired_goal": np.asarray(self._desired_goal(), np.float32)}
        return super()._observation()

    def _render(self, height: int, width: int) -> np.ndarray:
        key = (int(height), int(width))
        renderer = self._renderers.get(key)
        if renderer is None:
            self.model.vis.quality.offsamples = int(self.render_multisamples)
            renderer = self._renderers[key] = make_renderer(self.model, *key)
        renderer.update_scene(self.data, camera=self.camera)
        return renderer.render().copy()

    def close(self) -> None:
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
        super().close()

    # ------------------------------------------------------------------ state
    def _get_sim_state(self) -> dict[str, np.ndarray]:
        d = self.data
        state = {name: getattr(d, name).copy() for name in _STATE_FIELDS}
        state["time"] = np.array(d.time, np.float64)
        for key, value in self._get_task_state().items():
            state[f"task/{key}"] = np.array(value, copy=True)
        return state

    def _set_sim_state(self, state: dict[str, np.ndarray]) -> None:
        d = self.data
        expected = {name: getattr(d, name).shape for name in _STATE_FIELDS}
        expected["time"] = ()
        for name, shape in expected.items():
            if name not in state:
                raise ValueError(f"state is missing 'sim/{name}'; pass a dict from get_state()")
            if np.shape(state[name]) != shape:
                raise ValueError(f"state 'sim/{name}' must have shape {shape}, got {np.shape(state[name])}")
        self._set_task_state({k[5:]: v for k, v in state.items() if k.startswith("task/")})
        for name in _STATE_FIELDS:
            getattr(d, name)[...] = state[name]
        d.time = float(state["time"])
        self._path_reference = None
        mujoco.mj_forward(self.model, d)

    def _check_sim_state(self, sim: dict[str, np.ndarray]) -> None:
        check_range("sim/time", sim["time"], 0.0)
        check_mujoco_state(self.model, sim)

    def _get_task_state(self) -> dict[str, np.ndarray]:
        """Task extras saved with the simulator state (e.g. the goal). Default: none."""
        return {}

    def _set_task_state(self, state: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`_get_task_state` returned (keys without the ``task/`` prefix)."""


def _wants_goal(cls: type, args: tuple, kwargs: dict) -> bool:
    """Whether constructor arguments ask for ``goal_conditioned=True`` (bad arguments: False, so
    that ``__init__`` reports them)."""
    try:
        bound = inspect.signature(cls.__init__).bind(None, *args, **kwargs)
    except TypeError:
        return False
    return bound.arguments.get("goal_conditioned", False) is True or bound.arguments.get(
        "goal_conditioned", False) is np.True_


class GoalEnvMixin(GoalEnv):
    """The ``GoalEnv`` side of a goal-conditioned :class:`MujocoEnv` (see :func:`goal_env_class`)."""

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> np.ndarray | float:
        """GoalEnv reward for (batches of) goals; ``info`` is a dict or an array/list of dicts.

        Equals the step reward for the goals and info of a real step, so SB3's
        ``HerReplayBuffer`` can relabel goals. Returns a float for unbatched input, else an
        array of shape ``achieved_goal.shape[:-1]``.
        """
        ag = np.asarray(achieved_goal, np.float64)
        dg = np.asarray(desired_goal, np.float64)
        batch = ag.shape[:-1]
        n = int(np.prod(batch)) if batch else 1
        extras = {k: self._info_values(info, k, n) for k in self.reward_info_keys}
        r = self._goal_reward(ag.reshape(n, -1), dg.reshape(n, -1), extras)
        return float(r[0]) if not batch else np.asarray(r, np.float32).reshape(batch)

    @staticmethod
    def _info_values(info: Any, key: str, n: int) -> np.ndarray:
        try:
            if isinstance(info, dict):
                values = np.asarray(info[key], np.float64).reshape(-1)
                return np.broadcast_to(values, (n,)) if values.size == 1 else values
            return np.array([i[key] for i in np.asarray(info, dtype=object).reshape(-1)], np.float64)
        except (KeyError, TypeError):
            raise ValueError(
                f"compute_reward needs info[{key!r}] (the step's info dict, or an array of them); with SB3's "
                "HerReplayBuffer pass replay_buffer_kwargs={'copy_info_dict': True}") from None

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> np.ndarray | bool:
        """GoalEnv termination: success (episodes end on success)."""
        ag = np.asarray(achieved_goal, np.float64)
        dg = np.asarray(desired_goal, np.float64)
        batch = ag.shape[:-1]
        done = self._goal_success(ag.reshape(-1, ag.shape[-1]), dg.reshape(-1, dg.shape[-1]))
        return bool(done[0]) if not batch else np.asarray(done).reshape(batch)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> np.ndarray | bool:
        """GoalEnv truncation does not depend on goals (the horizon is counted by the env)."""
        batch = np.asarray(achieved_goal).shape[:-1]
        return False if not batch else np.zeros(batch, bool)



_GOAL_CLASSES: dict[type, type] = {}


def goal_env_class(cls: type) -> type:
    """The goal-conditioned subclass of a :class:`MujocoEnv` task class: the same name and
    behaviour, plus :class:`GoalEnvMixin` (``compute_reward`` & co., a ``GoalEnv`` instance)."""
    if cls not in _GOAL_CLASSES:
        _GOAL_CLASSES[cls] = type(cls.__name__, (cls, GoalEnvMixin),
                                  {"__module__": cls.__module__, "__qualname__": cls.__qualname__,
                                   "__doc__": cls.__doc__})
    return _GOAL_CLASSES[cls]


__all__ = ["MujocoEnv", "GoalEnvMixin", "goal_env_class", "CONTINUOUS_JOINT_RANGE", "GRAVITY_COMPENSATION_MODES"]
