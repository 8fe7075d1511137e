"""MAIL as a benchmark agent: teacher demos → MAIL conversion → DMfD student.

``python -m lfd_bench.run`` builds agents as ``factory(env, seed, **kwargs)`` and calls
``learn(total_timesteps)`` in chunks, then ``predict(obs)``. :class:`MAILAgent` does, on the
first ``learn``:

1. teacher demonstrations: the task's scripted expert with ``teacher_pickers`` pickers
   (pick_place mode, ``teacher_episodes`` episodes, seeded by ``seed``);
2. the MAIL pipeline for the harness env (the student): ``random_data`` + ``dynamics`` when
   ``backend="learned"``, then ``convert`` (CEM + replay + threshold) into ``workdir``;
3. DMfD on the student dataset without reference-state initialisation,

and every ``learn`` call continues DMfD training. ``predict`` is DMfD's, or with
``select_episodes > 0`` that of the best checkpoint: after every ``learn`` call the student is
scored on ``select_episodes`` held-out training variants and the best-scoring policy so far
acts (:class:`lfd_agents.selection.BestCheckpoint`; its episodes count as env steps). With a fixed
``workdir`` every stage resumes from disk (a temporary folder is used otherwise).

Config cell example (``lfd_bench/configs/paper-mail.json``)::

    "agents": {"mail": {"teacher_pickers": 2, "backend": "simulator"}}
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import gymnasium as gym

from lfd_agents.mail.cem import CEMConfig
from lfd_agents.mail.dynamics import DynamicsConfig
from lfd_agents.mail.pipeline import MAIL, MAILConfig
from lfd_agents.selection import BestCheckpoint

__all__ = ["MAILAgent"]


class MAILAgent:
    """Harness agent running MAIL then DMfD (module docstring).

    Args:
        env: the student env (any obs mode; must be a particle task in ``pick_place`` mode).
        seed: seed of the teacher demos, CEM and DMfD.
        teacher_pickers: picker count of the teacher demonstrations (e.g. 2 → 1, 3 → 2).
        teacher_episodes: number of teacher demonstrations.
        backend: ``"simulator"`` (batched true simulator) or ``"learned"`` (CNN-LSTM model).
        workdir: folder of the stages (resumable); default a new temporary folder.
        population, iterations, horizon: CEM settings (see :class:`CEMConfig`).
        random_transitions, dynamics_epochs: learned-backend data and training.
        threshold: keep converted episodes whose final p̂ exceeds this (MAIL: 0.3).
        simulator_worlds: batched worlds of the simulator backend.
        select_episodes: validation episodes per ``learn`` call for checkpoint selection
            (0: the last policy acts).
        select_first_variant: first training variant of the validation set (the teacher
            demonstrations reset on random training variants, so a few may coincide).
        policy: DMfD policy name; ``dmfd_kwargs`` go to :class:`lfd_agents.dmfd.DMfD`.
    """

    def __init__(self, env: gym.Env, seed: int = 0, teacher_pickers: int = 2, teacher_episodes: int = 10,
                 backend: str = "simulator", workdir: str | Path | None = None, population: int = 32,
                 iterations: int = 1, horizon: int = 1, random_transitions: int = 300, dynamics_epochs: int = 40,
                 threshold: float = 0.3, simulator_worlds: int = 32, select_episodes: int = 0,
                 select_first_variant: int = 400, policy: str = "MlpPolicy", **dmfd_kwargs: Any):
        if env.spec is None:
            raise ValueError("MAILAgent needs an env made with gym.make (its id and kwargs define the student)")
        kwargs = dict(env.spec.kwargs or {})
        if kwargs.get("action_mode", "pick_place") != "pick_place":
            raise ValueError(f"MAIL students act in pick_place mode, got action_mode={kwargs['action_mode']!r}")
        self.env = env
        self.seed = int(seed)
        self.env_id = env.spec.id
        self.student_kwargs = {**kwargs, "action_mode": "pick_place"}
        self.teacher_pickers = int(teacher_pickers)
        self.teacher_episodes = int(teacher_episodes)
        self.workdir = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="lfd-mail-"))
        self.config = MAILConfig(
            backend=backend, random_transitions=int(random_transitions), dynamics_epochs=int(dynamics_epochs),
            dynamics=DynamicsConfig(), threshold=float(threshold), simulator_worlds=int(simulator_worlds),
            cem=CEMConfig(population=int(population), iterations=int(iterations), horizon=int(horizon)),
            seed=self.seed)
        self.policy = policy
        self.dmfd_kwargs = dmfd_kwargs
        self.selector = (BestCheckpoint(env, int(select_episodes), int(select_first_variant), seed=self.seed)
                         if int(select_episodes) > 0 else None)
        self.mail: MAIL | None = None
        self.stats: dict[str, Any] | None = None
        self.model: Any = None

    @classmethod
    def for_benchmark(cls, env: gym.Env, seed: int = 0, **kwargs: Any) -> "MAILAgent":
        """Factory used by ``lfd_bench.agents`` (``"mail"``)."""
        return cls(env, seed=seed, **kwargs)

    # ------------------------------------------------------------------ stages
    def teacher_dataset(self) -> Path:
        """Expert demonstrations with ``teacher_pickers`` pickers (collected once)."""
        from lfd_envs import datasets

        root = self.workdir / "teacher"
        found = sorted(p.parent for p in root.rglob("data")) if root.exists() else []
        if found:
            return found[0]
        env_kwargs = {**self.student_kwargs, "num_pickers": self.teacher_pickers, "obs_mode": "state"}
        return datasets.collect(self.env_id, self.teacher_episodes, root, env_kwargs=env_kwargs, seed=self.seed,
                                progress=False, name="teacher")

    def prepare(self) -> dict[str, Any]:
        """Teacher demos and the MAIL conversion (resumes from ``workdir``); returns its statistics."""
        if self.stats is None:
            self.mail = MAIL(self.env_id, self.teacher_dataset(), self.workdir / "mail", self.student_kwargs,
                             self.config)
            if self.config.backend == "learned":
                self.mail.dynamics()
            self.stats = self.mail.convert()
        return self.stats

    def _build_student(self) -> Any:
        from lfd_agents.dmfd import DMfD

        self.prepare()
        assert self.mail is not None
        data = self.mail.student_dataset()
        kwargs = {"rsi_prob": 0.0, **self.dmfd_kwargs}
        return DMfD(self.policy, self.env, demonstrations=None if data is None else str(data), seed=self.seed,
                    **kwargs)

    # ------------------------------------------------------------------ SB3-style API
    def learn(self, total_timesteps: int, reset_num_timesteps: bool = True, **kwargs: Any) -> "MAILAgent":
        """First call: MAIL conversion and the DMfD student; every call: DMfD training."""
        if self.model is None:
            self.model = self._build_student()
            reset_num_timesteps = True
        self.model.learn(total_timesteps, reset_num_timesteps=reset_num_timesteps, **kwargs)
        if self.selector is not None:
            self.selector.update(self.model.policy)
        return self

    @property
    def validation_env_steps(self) -> int:
        """Env steps of the checkpoint-selection episodes (0 without selection)."""
        return 0 if self.selector is None else self.selector.env_steps

    def close(self) -> None:
        """Close the checkpoint-selection env (if any)."""
        if self.selector is not None:
            self.selector.close()

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        if self.model is None:
            raise RuntimeError("call learn() before predict()")
        if self.selector is not None:
            return self.selector.predict(obs, state, episode_start, deterministic)
        return self.model.predict(obs, state, episode_start, deterministic)
