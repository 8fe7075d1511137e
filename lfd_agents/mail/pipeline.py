"""MAIL: learn from demonstrations made by a robot with a different number of pickers.

Stages (each saves its output in ``workdir`` and is skipped when that output exists, so a run
can be resumed or a stage re-run by deleting its output):

1. ``random_data``  — random pick-and-place transitions of the *student*, collected in batched
   worlds (``random.npz``, see :mod:`lfd_agents.mail.data`);
2. ``dynamics``     — train the CNN-LSTM particle dynamics model on them (``dynamics.pt``);
3. ``convert``      — for every teacher demonstration, CEM finds the student action sequence
   whose predicted final object state matches the teacher's final state; the sequence is
   replayed in the true simulator from the teacher's start state, and episodes whose p̂
   exceeds ``threshold`` form the student dataset (Minari, ``student/``);
4. ``student``      — DMfD trained on the student dataset without reference-state
   initialisation (``student_policy.zip``).

The dynamics backend of stage 3 is pluggable: ``"learned"`` (the model of stage 2) or
``"simulator"`` (batched true simulator; no stage 1–2 needed).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from lfd_agents.mail.backends import LearnedBackend, SimulatorBackend, particles_of
from lfd_agents.mail.cem import CEM, CEMConfig
from lfd_agents.mail.data import collect_transitions, load_transitions, save_transitions
from lfd_agents.mail.dynamics import DynamicsConfig, LearnedDynamics

STAGES = ("random_data", "dynamics", "convert", "student")


@dataclass
class MAILConfig:
    """Settings of a MAIL run (defaults sized for a CPU; the paper's in the thesis Table D.8)."""

    backend: str = "learned"  #: "learned" or "simulator"
    random_transitions: int = 300  #: MAIL: 60k (10k episodes of 6 steps)
    random_worlds: int = 16  #: batched worlds while collecting them
    explore: float = 0.25  #: fraction of random picks perturbed by Gaussian noise (missed grasps)
    uniform: float = 0.1  #: fraction of fully uniform random actions
    dynamics_epochs: int = 60
    dynamics: DynamicsConfig = field(default_factory=DynamicsConfig)
    cem: CEMConfig = field(default_factory=CEMConfig)
    student_steps: int | None = None  #: student actions per teacher demo (default: student horizon)
    threshold: float = 0.3  #: keep student episodes with final p̂ above this (MAIL: 0.3)
    simulator_worlds: int = 32
    teacher_warm_start: bool = True  #: CEM means start from the teacher's picks/places, executed in turn
    seed: int = 0


class MAIL:
    """The MAIL pipeline for one (teacher dataset, student env) pair.

    Args:
        student_env_id: particle task id, e.g. ``"ClothFold-v0"``.
        teacher_dataset: folder of a Minari dataset from :func:`lfd_envs.datasets.collect` made
            with the teacher's picker count (pick_place mode).
        workdir: where stages save their outputs.
        student_kwargs: student env kwargs (e.g. ``{"num_pickers": 1}``); pick_place is forced.
        config: :class:`MAILConfig`.
    """

    def __init__(self, student_env_id: str, teacher_dataset: str | Path, workdir: str | Path,
                 student_kwargs: dict[str, Any] | None = None, config: MAILConfig | None = None):
        from lfd_envs import datasets

        self.config = config or MAILConfig()
        if self.config.backend not in ("learned", "simulator"):
            raise ValueError(f"backend must be 'learned' or 'simulator', got {self.config.backend!r}")
        self.student_env_id = student_env_id
        self.student_kwargs = {**(student_kwargs or {}), "action_mode": "pick_place"}
        #: obs mode of the student dataset and policy (the particles are read from env states)
        self.obs_mode = str(self.student_kwargs.pop("obs_mode", "state"))
        if self.obs_mode == "particles":
            self.obs_mode = "state"
        self.teacher_path = Path(teacher_dataset)
        self.teacher = datasets.load(self.teacher_path)
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.env = gym.make(student_env_id, **{**self.student_kwargs, "obs_mode": "particles"})
        self.num_particles = int(self.env.unwrapped.particle_positions.shape[0])
        self.timings: dict[str, float] = {}

    # ------------------------------------------------------------------ paths
    @property
    def random_path(self) -> Path:
        return self.workdir / "random.npz"

    @property
    def dynamics_path(self) -> Path:
        return self.workdir / "dynamics.pt"

    @property
    def student_path(self) -> Path:
        return self.workdir / "student"

    @property
    def policy_path(self) -> Path:
        return self.workdir / "student_policy.zip"

    def _dataset_dir(self, root: Path) -> Path | None:
        found = sorted(p.parent for p in root.rglob("data")) if root.exists() else []
        return found[0] if found else None

    def student_dataset(self) -> Path | None:
        """Folder of the student dataset written by :meth:`convert` (``None`` before / if none kept)."""
        return self._dataset_dir(self.student_path)

    # ------------------------------------------------------------------ stage 1
    def random_data(self) -> Path:
        """Random pick-and-place transitions of the student (the dynamics model's training data)."""
        if self.random_path.exists():
            return self.random_path
        c = self.config
        t0 = time.perf_counter()
        data = collect_transitions(self.student_env_id, self.student_kwargs, c.random_transitions,
                                   num_worlds=c.random_worlds, seed=c.seed + 1_000_000, explore=c.explore,
                                   uniform=c.uniform)
        save_transitions(data, self.random_path)
        self.timings["random_data"] = time.perf_counter() - t0
        return self.random_path

    # ------------------------------------------------------------------ stage 2
    def dynamics(self) -> LearnedDynamics:
        """Train (or load) the particle dynamics model on the random transitions."""
        if self.dynamics_path.exists():
            return LearnedDynamics.load(self.dynamics_path)
        data = load_transitions(self.random_data())
        model = LearnedDynamics.for_env(self.env, self.config.dynamics, seed=self.config.seed)
        t0 = time.perf_counter()
        model.fit(data["x"], data["actions"], data["x_next"], epochs=self.config.dynamics_epochs)
        self.timings["dynamics"] = time.perf_counter() - t0
        tmp = self.dynamics_path.with_suffix(".partial")
        model.save(tmp)
        tmp.replace(self.dynamics_path)
        return model

    # ------------------------------------------------------------------ stage 3
    def _backend(self):
        if self.config.backend == "simulator":
            return SimulatorBackend(self.student_env_id, self.student_kwargs, self.config.simulator_worlds)
        return LearnedBackend(self.dynamics())

    def student_start_state(self, teacher_state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The teacher's start state with the student's pickers (same variant, same object state)."""
        split = "train" if int(teacher_state["episode/split"]) == 0 else "eval"
        self.env.reset(seed=0, options={"split": split, "variant": int(teacher_state["episode/variant"])})
        state = self.env.unwrapped.get_state()
        for key, value in teacher_state.items():
            if "picker" in key or "grasp" in key or key not in state:
                continue
            if np.shape(value) == np.shape(state[key]):
                state[key] = np.array(value, dtype=np.asarray(state[key]).dtype)
        return state

    def teacher_plan(self, teacher_actions: np.ndarray, steps: int) -> np.ndarray:
        """Student warm-start plan from the teacher's pick-and-place actions.

        The teacher's pickers are executed in turn by the student's pickers: with ``n`` teacher
        and ``m`` student pickers, teacher step ``t`` becomes ``ceil(n / m)`` student steps.
        The plan is cut or padded (centre actions) to ``steps``.
        """
        m = int(self.student_kwargs.get("num_pickers") or self.env.unwrapped.num_pickers)
        plan = []
        for a in np.asarray(teacher_actions, dtype=np.float64):
            pairs = a.reshape(2, -1, 3)  # (pick/place, n, xyz)
            n = pairs.shape[1]
            for lo in range(0, n, m):
                chunk = pairs[:, lo:lo + m]
                if chunk.shape[1] < m:  # spare student pickers repeat the last pair
                    chunk = np.concatenate([chunk, np.repeat(chunk[:, -1:], m - chunk.shape[1], axis=1)], axis=1)
                plan.append(chunk.reshape(-1))
        d = 6 * m
        out = np.zeros((steps, d))
        plan_arr = np.array(plan[:steps]).reshape(-1, d) if plan else np.zeros((0, d))
        out[: len(plan_arr)] = plan_arr
        return out

    def optimise_demo(self, backend: Any, start: dict[str, np.ndarray], goal: np.ndarray, steps: int,
                      seed: int, plan: np.ndarray | None = None) -> np.ndarray:
        """CEM (receding horizon) for the student actions that bring the object to ``goal``.

        ``plan`` (steps, action_dim) warm-starts the CEM means (e.g. :meth:`teacher_plan`).
        """
        cfg = CEMConfig(**{**asdict(self.config.cem), "seed": seed})
        cfg.horizon = min(cfg.horizon, steps)
        action_dim = int(np.prod(self.env.action_space.shape))
        cem = CEM(action_dim, cfg)
        plan = np.zeros((steps, action_dim)) if plan is None else np.array(plan, dtype=np.float64)
        target = goal[backend.indices]
        state = start
        for t in range(steps):
            horizon = min(cfg.horizon, steps - t)

            def cost(samples: np.ndarray) -> np.ndarray:
                final = backend.final_particles(state, samples)
                return np.linalg.norm(final - target[None], axis=-1).mean(axis=-1)

            cem.config.horizon = horizon
            seq, _ = cem.optimize(cost, mean=plan[t:t + horizon])
            plan[t:t + horizon] = seq
            # advance the true state with the chosen first action (MPC)
            self.env.unwrapped.set_state(state)
            self.env.step(seq[0].astype(np.float32))
            state = self.env.unwrapped.get_state()
        return plan.astype(np.float32)

    def convert(self, max_demos: int | None = None) -> dict[str, Any]:
        """Turn teacher demonstrations into the student dataset; returns statistics."""
        from lfd_envs import datasets

        existing = self._dataset_dir(self.student_path)
        stats_path = self.workdir / "convert_stats.json"
        if existing is not None and stats_path.exists():
            return json.loads(stats_path.read_text())
        backend = self._backend()
        steps = self.config.student_steps or self.env.unwrapped.horizon
        record_env = gym.make(self.student_env_id, **{**self.student_kwargs, "obs_mode": self.obs_mode})
        kept, finals = [], []
        t0 = time.perf_counter()
        episodes = list(self.teacher.iterate_episodes())[: max_demos]
        for i, ep in enumerate(episodes):
            states = datasets.episode_states(ep)
            start = self.student_start_state(states[0])
            goal = particles_of(states[-1])
            plan = self.teacher_plan(ep.actions, steps) if self.config.teacher_warm_start else None
            actions = self.optimise_demo(backend, start, goal, steps, seed=self.config.seed + i, plan=plan)
            rec = datasets.run_episode(record_env, _Replay(actions), seed=i, options={"split": "train"},
                                       initial_state=self._retarget(start, record_env))
            final = float(rec.infos[-1]["normalized_performance"])
            finals.append(final)
            if final > self.config.threshold:
                kept.append(rec)
        elapsed = time.perf_counter() - t0
        stats = {"teacher_episodes": len(episodes), "kept": len(kept), "threshold": self.config.threshold,
                 "mean_final_normalized_performance": float(np.mean(finals)) if finals else float("nan"),
                 "finals": finals, "backend": self.config.backend, "wall_time_s": elapsed,
                 "seconds_per_demo": elapsed / max(1, len(episodes)),
                 "model_transitions": int(getattr(backend, "transitions", 0))}
        if kept:
            datasets.write_dataset(kept, record_env, self.student_env_id, self.student_path, name="mail-student",
                                   env_kwargs={**self.student_kwargs, "obs_mode": self.obs_mode},
                                   extra={"teacher": str(self.teacher_path)})
        stats_path.write_text(json.dumps(stats, indent=1))
        return stats

    @staticmethod
    def _retarget(state: dict[str, np.ndarray], env: gym.Env) -> dict[str, np.ndarray]:
        """``state`` is observation-mode independent; returned as is (hook for other layouts)."""
        return state

    # ------------------------------------------------------------------ stage 4
    def student(self, total_timesteps: int = 10_000, **dmfd_kwargs: Any):
        """Train DMfD on the student dataset without reference-state initialisation."""
        from lfd_agents.dmfd import DMfD

        if self.policy_path.exists():
            return DMfD.load(self.policy_path)
        data = self._dataset_dir(self.student_path)
        if data is None:
            raise RuntimeError("no student dataset: run convert() first (or lower the threshold)")
        env = gym.make(self.student_env_id, **{**self.student_kwargs, "obs_mode": self.obs_mode})
        policy = "MlpPolicy" if self.obs_mode == "state" else ("CnnPolicy" if self.obs_mode == "image" else "MultiInputPolicy")
        model = DMfD(policy, env, demonstrations=str(data), rsi_prob=0.0, seed=self.config.seed,
                     **dmfd_kwargs)
        model.learn(total_timesteps)
        model.save(self.policy_path)
        return model

    def run(self, total_timesteps: int = 10_000, max_demos: int | None = None, **dmfd_kwargs: Any) -> dict[str, Any]:
        """All stages (resuming from saved outputs); returns the statistics of :meth:`convert`.

        ``max_demos`` goes to :meth:`convert`, ``dmfd_kwargs`` to :meth:`student` (DMfD).
        """
        if self.config.backend == "learned":
            self.dynamics()
        stats = self.convert(max_demos)
        self.student(total_timesteps, **dmfd_kwargs)
        return stats


class _Replay:
    """Policy that replays a fixed action sequence (then repeats the last action)."""

    def __init__(self, actions: np.ndarray):
        self.actions = np.asarray(actions, dtype=np.float32)
        self.t = 0

    def reset(self) -> None:
        self.t = 0

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        a = self.actions[min(self.t, len(self.actions) - 1)]
        self.t += 1
        return a, None
