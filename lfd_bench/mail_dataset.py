"""MAIL's optimised student demonstrations, measured as a benchmark row.

MAIL's stage 3 turns a teacher demonstration (``n`` pickers) into a student action sequence
(``m`` pickers) with CEM; the thesis reports how good those sequences are on their own (the
"optimised dataset" row of its MAIL ablations, beside the one-picker and teacher demos).
:class:`MAILDatasetAgent` measures the same thing on the harness's *evaluation* episodes: at the
start of every episode it reads the episode's start state, lets the scripted teacher expert
solve that same start with ``teacher_pickers`` pickers, converts the teacher's actions with the
pipeline's CEM (:meth:`lfd_agents.mail.MAIL.optimise_demo`, warm-started with the teacher's
picks executed in turn) and then plays the optimised student sequence open loop. It trains
nothing (``needs_training = False``); its p̂ is that of the student dataset MAIL would build
from those episodes (without MAIL's keep-threshold, which only drops bad ones).

Suite cell::

    "agents": {"mail_dataset": {"teacher_pickers": 2, "population": 32}}
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["MAILDatasetAgent", "mail_dataset"]


class MAILDatasetAgent:
    """Plays MAIL's CEM conversion of the teacher expert's solution of each episode (module docstring).

    Args:
        env: the student env (made with ``gym.make``; pick_place particle task).
        seed: CEM seed (episode ``i`` of an evaluation uses ``seed + i``).
        teacher_pickers: picker count of the teacher expert.
        backend: ``"simulator"`` (batched true simulator; default) or ``"learned"``.
        population, iterations, horizon, simulator_worlds: CEM settings (:class:`CEMConfig`,
            :class:`MAILConfig`); the defaults are those of the ``mail`` agent.
        random_transitions, dynamics_epochs: learned backend only.
        workdir: folder of the pipeline's files (default: a new temporary folder).
    """

    needs_training = False

    def __init__(self, env: gym.Env, seed: int = 0, teacher_pickers: int = 2, backend: str = "simulator",
                 population: int = 32, iterations: int = 1, horizon: int = 1, simulator_worlds: int = 32,
                 random_transitions: int = 300, dynamics_epochs: int = 40, workdir: str | Path | None = None) -> None:
        if env.spec is None:
            raise ValueError("MAILDatasetAgent needs an env made with gym.make (its id and kwargs define the student)")
        kwargs = dict(env.spec.kwargs or {})
        if kwargs.get("action_mode", "pick_place") != "pick_place":
            raise ValueError(f"MAIL students act in pick_place mode, got action_mode={kwargs['action_mode']!r}")
        if isinstance(teacher_pickers, bool) or not isinstance(teacher_pickers, int) or teacher_pickers < 1:
            raise ValueError(f"teacher_pickers must be an integer >= 1, got {teacher_pickers!r}")
        from lfd_agents.mail import CEMConfig, MAILConfig

        self.env_id = env.spec.id
        self.seed = int(seed)
        self.teacher_pickers = int(teacher_pickers)
        self.student_kwargs = {**kwargs, "action_mode": "pick_place"}
        self.config = MAILConfig(backend=backend, random_transitions=int(random_transitions),
                                 dynamics_epochs=int(dynamics_epochs), simulator_worlds=int(simulator_worlds),
                                 cem=CEMConfig(population=int(population), iterations=int(iterations),
                                               horizon=int(horizon)), seed=self.seed)
        self.workdir = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="lfd-mail-dataset-"))
        teacher_kwargs = {**self.student_kwargs, "num_pickers": self.teacher_pickers, "obs_mode": "particles"}
        self.teacher_env = gym.make(self.env_id, **teacher_kwargs)
        self._env: gym.Env | None = None
        self._mail: Any = None
        self._backend: Any = None
        self._plan: np.ndarray | None = None
        self._t = 0
        self.episodes = 0
        #: final p̂ of the teacher expert on each episode played (the teacher demos' quality)
        self.teacher_finals: list[float] = []

    @classmethod
    def for_benchmark(cls, env: gym.Env, seed: int = 0, **kwargs: Any) -> "MAILDatasetAgent":
        return cls(env, seed=seed, **kwargs)

    # ------------------------------------------------------------------ harness API
    def learn(self, total_timesteps: int = 0, **kwargs: Any) -> "MAILDatasetAgent":
        """Nothing to train (the conversion happens per episode)."""
        return self

    def bind(self, env: gym.Env) -> None:
        """Play on ``env`` (its start states are read at the first ``predict`` of each episode)."""
        self._env = env
        self.reset()

    def reset(self) -> None:
        self._plan, self._t = None, 0

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        if self._env is None:
            raise RuntimeError("bind(env) before predict(): the agent reads the episode's start state from it")
        if self._plan is None:
            self._plan = self.student_plan(self._env.unwrapped.get_state())
            self._t = 0
        action = self._plan[min(self._t, len(self._plan) - 1)]
        self._t += 1
        return action.copy(), None

    # ------------------------------------------------------------------ conversion
    def _pipeline(self):
        """The MAIL pipeline object (built once; it needs a teacher dataset on disk: one expert episode)."""
        if self._mail is None:
            from lfd_agents.mail import MAIL
            from lfd_envs import datasets

            teacher_kwargs = {**self.student_kwargs, "num_pickers": self.teacher_pickers, "obs_mode": "state"}
            teacher = datasets.collect(self.env_id, 1, self.workdir / "teacher", env_kwargs=teacher_kwargs,
                                       seed=self.seed, progress=False, name="teacher", overwrite=True)
            self._mail = MAIL(self.env_id, teacher, self.workdir / "mail", self.student_kwargs, self.config)
            self._mail.env.reset(seed=0)  # optimise_demo steps the pipeline's own student env
            self._backend = self._mail._backend()
        return self._mail

    def teacher_demo(self, student_state: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """The teacher expert's actions ``(T, 6n)`` and final particle positions from the object
        state of ``student_state`` (same variant; the teacher's pickers at their start)."""
        from lfd_envs.experts import make_expert

        split = "train" if int(student_state["episode/split"]) == 0 else "eval"
        env = self.teacher_env
        env.reset(seed=0, options={"split": split, "variant": int(student_state["episode/variant"])})
        state = env.unwrapped.get_state()
        for key, value in student_state.items():
            if "picker" in key or "grasp" in key or key not in state:
                continue
            if np.shape(value) == np.shape(state[key]):
                state[key] = np.array(value, dtype=np.asarray(state[key]).dtype)
        env.unwrapped.set_state(state)
        expert = make_expert(env)
        if hasattr(expert, "reset"):
            expert.reset()
        obs, actions, done, info = None, [], False, {}
        while not done:
            action = np.asarray(expert.predict(obs, deterministic=True)[0], dtype=np.float32)
            obs, _, terminated, truncated, info = env.step(action)
            actions.append(action)
            done = terminated or truncated
        self.teacher_finals.append(float(info.get("normalized_performance", np.nan)))
        return np.asarray(actions), np.asarray(env.unwrapped.particle_positions, dtype=np.float64)

    def student_plan(self, student_state: dict[str, np.ndarray]) -> np.ndarray:
        """CEM-optimised student actions ``(H, 6m)`` for the episode starting in ``student_state``."""
        mail = self._pipeline()
        teacher_actions, goal = self.teacher_demo(student_state)
        steps = self.config.student_steps or mail.env.unwrapped.horizon
        plan = mail.teacher_plan(teacher_actions, steps) if self.config.teacher_warm_start else None
        out = mail.optimise_demo(self._backend, student_state, goal, steps, seed=self.seed + self.episodes, plan=plan)
        self.episodes += 1
        return out


def mail_dataset(env: gym.Env, seed: int = 0, **kwargs: Any) -> MAILDatasetAgent:
    """Harness factory (``"mail_dataset"``): :class:`MAILDatasetAgent`."""
    return MAILDatasetAgent(env, seed=seed, **kwargs)
