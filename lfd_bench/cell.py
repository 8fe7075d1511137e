"""One benchmark cell: train an agent on an env with a learning curve and checkpoints, then evaluate it.

:func:`run_cell` is what every executor runs for a :class:`Cell` (one env, agent and seed of a
suite). Training stops at every curve point and every ``checkpoint_steps`` env steps
(:func:`training_stops`); a learner with a training state (:mod:`lfd_agents.training_state`) is
saved there and rebuilt from the save (:mod:`lfd_bench.checkpoints`), so a killed cell resumes
exactly. Evaluation plays the env's *eval* variants (:func:`evaluate_episodes`).
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


@dataclass
class Cell:
    """One (env, agent, seed) training-and-evaluation run."""

    suite: str
    env_id: str
    env_kwargs: dict[str, Any]
    agent: str
    agent_kwargs: dict[str, Any]
    seed: int
    budget: int
    eval_episodes: int
    curve_points: int = 4
    tags: dict[str, Any] = field(default_factory=dict)
    cpus: int = 1  #: CPU cores the cell asks a cluster scheduler for
    deterministic: bool = True  #: evaluation acts with ``predict(obs, deterministic=...)``
    checkpoint_steps: int | None = None  #: a training stop (and checkpoint) every this many env steps

    @property
    def key(self) -> str:
        label = self.tags.get("label")
        env_dir = _safe(self.env_id.split(":")[-1]) + (f"__{_safe(label)}" if label else "")
        return f"{_safe(self.suite)}/{env_dir}/{_safe(self.agent)}/seed{self.seed}"


def _safe(name: str) -> str:
    """A file-name-safe version of ``name`` (letters, digits, ``._-``)."""
    from lfd_bench.storage import safe_name

    return safe_name(name)



#: final ``info`` numbers recorded per evaluation episode besides p̂ where an env reports them
#: (a quality measure the published metric does not capture; ``is_success``: the success rate),
#: with their table headings
REPORTED_METRICS: dict[str, str] = {"fold_quality": "fold quality", "is_success": "success"}


class SampledActions:
    """``agent`` acting with ``predict(obs, deterministic=False)``: actions drawn from its policy."""

    def __init__(self, agent: Any):
        self.agent = agent

    def reset(self) -> None:
        if hasattr(self.agent, "reset"):
            self.agent.reset()

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.agent.predict(obs, state, episode_start, deterministic=False)


def evaluate_episodes(agent: Any, env, episodes: int, seed: int, deterministic: bool = True) -> dict[str, list[float]]:
    """Final ``normalized_performance`` p̂(H) of ``agent`` on eval variants ``0..episodes-1``,
    plus every :data:`REPORTED_METRICS` key that the final info of every episode has
    (``{key: [one value per episode]}``). ``deterministic=False`` samples the agent's actions."""
    from lfd_envs.core.rollout import play_episode

    if hasattr(agent, "bind"):
        agent.bind(env)
    if not deterministic:
        agent = SampledActions(agent)
    n_eval = env.unwrapped.variants.size("eval") if hasattr(env.unwrapped, "variants") else episodes
    out: dict[str, list[float]] = {"normalized_performance": [], **{k: [] for k in REPORTED_METRICS}}
    for k in range(episodes):
        info = play_episode(env, agent, seed=seed * 100_003 + k, options={"split": "eval", "variant": k % n_eval})
        for key, values in out.items():
            if key in info:
                values.append(float(info[key]))
    return {k: v for k, v in out.items() if k == "normalized_performance" or len(v) == episodes}


def evaluate(agent: Any, env, episodes: int, seed: int) -> list[float]:
    """Final normalised performance p̂(H) of ``agent`` on eval variants ``0..episodes-1``."""
    return evaluate_episodes(agent, env, episodes, seed)["normalized_performance"]


def environment_info() -> dict[str, Any]:
    """Versions and hardware recorded in every result."""
    import importlib.metadata as md

    versions = {}
    for pkg in ("lfd-suite", "gymnasium", "stable-baselines3", "torch", "warp-lang", "mujoco", "numpy", "ompl", "minari"):
        try:
            versions[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"python": platform.python_version(), "platform": platform.platform(), "cpu": cpu,
            "cpu_count": os.cpu_count(), "versions": versions, "commit": git_commit()}


def git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def training_stops(budget: int, curve_points: int, checkpoint_steps: int | None = None) -> list[tuple[int, bool]]:
    """``(env steps, is a curve point)`` of every stop of a training run, in order: the
    ``curve_points`` evenly spaced curve points and every multiple of ``checkpoint_steps``."""
    points = max(1, int(curve_points))
    curve = [budget * (i + 1) // points for i in range(points)]
    extra = range(checkpoint_steps, budget, checkpoint_steps) if checkpoint_steps else ()
    stops = [(s, True) for s in curve] + [(s, False) for s in extra if s not in set(curve)]
    return sorted(stops, key=lambda stop: stop[0])


def stop_seed(seed: int, stop: int) -> int:
    """Seed of the generators when training goes on after stop ``stop`` of a run seeded ``seed``."""
    return int(np.random.SeedSequence([int(seed), int(stop)]).generate_state(1)[0])


@dataclass
class _Training:
    """The objects of one stretch of a cell's training (rebuilt at every checkpoint)."""

    env: Any
    eval_env: Any
    agent: Any
    recorder: Any = None

    def close(self) -> None:
        if self.recorder is not None:
            self.recorder.detach()
        close_agent = getattr(self.agent, "close", None)
        if callable(close_agent):  # agents that hold envs of their own (e.g. MAIL's validation env)
            close_agent()
        self.env.close()
        self.eval_env.close()


def _build_training(cell: Cell, factory: Any, kwargs: dict[str, Any]) -> _Training:
    import gymnasium as gym

    from lfd_bench.budget import StepCounter

    env = StepCounter(gym.make(cell.env_id, **cell.env_kwargs))
    recorder = None
    if cell.tags.get("coverage_steps"):  # end-effector positions of the first training steps
        from lfd_bench.coverage import EndEffectorRecorder

        recorder = EndEffectorRecorder(env, int(cell.tags["coverage_steps"]))
    eval_env = gym.make(cell.env_id, **cell.env_kwargs)
    return _Training(env, eval_env, factory(env, cell.seed, **kwargs), recorder)


def run_cell(cell: Cell, progress: bool = True, demo_cache: Path | None = None,
             checkpoints: Path | None = None) -> dict[str, Any]:
    """Train ``cell.agent`` for ``cell.budget`` steps with a learning curve, then evaluate it.

    ``demo_cache`` is the demonstration cache folder handed to the built-in demonstration
    agents (default ``results/_demos``). The result records what training spent:
    ``env_steps`` (steps in the training env), ``gradient_updates`` and ``demo_transitions``;
    ``final_metrics`` holds the per-episode :data:`REPORTED_METRICS` the env reports. A cell
    with ``coverage_steps`` N also records where the end-effector went during the first N
    training steps (``coverage``, :class:`lfd_bench.coverage.EndEffectorRecorder`). An agent that
    acts with its best checkpoint records each chunk's validation score (``validation_scores``).

    ``checkpoints`` (a folder, :class:`lfd_bench.checkpoints.CheckpointStore`): a learner with a
    training state (:func:`lfd_agents.training_state.supports_training_state`) saves it at every
    stop (:func:`training_stops`) and goes on from a fresh learner loaded from the save, so a
    re-run after a kill resumes from the newest save with the uninterrupted result. Without a
    folder the learner is still rebuilt at every stop (the same result), but nothing is saved.
    """
    from tqdm import tqdm

    import lfd_envs  # noqa: F401  (registers the ids; a worker process starts without them)
    from lfd_bench.agents import resolve_agent
    from lfd_bench.budget import spent
    from lfd_bench.checkpoints import CheckpointStore
    from lfd_agents.training_state import supports_training_state

    module = cell.env_id.rpartition(":")[0]
    if module:
        importlib.import_module(module)
    factory = resolve_agent(cell.agent)
    environment = environment_info()  # before training: the commit whose code the cell runs with
    kwargs = dict(cell.agent_kwargs)
    if demo_cache is not None and getattr(factory, "uses_demo_cache", False):
        kwargs.setdefault("demo_cache", str(demo_cache))
    store = CheckpointStore(Path(checkpoints)) if checkpoints is not None else None
    t0 = time.perf_counter()
    run = _build_training(cell, factory, kwargs)
    trains = getattr(run.agent, "needs_training", True)
    stops = training_stops(cell.budget, cell.curve_points, cell.checkpoint_steps) if trains else []
    resumable = trains and supports_training_state(run.agent) and _accepts_reset(run.agent)
    saved = store.load() if (store is not None and resumable) else None
    if saved is not None and (saved["cell"] != _cell_identity(cell) or saved["stop"] >= len(stops)):
        saved = None  # a save of another configuration of this cell: start again
    curve: list[dict[str, float]] = saved["curve"] if saved else []
    done_steps, first, earlier = (saved["steps"], saved["stop"] + 1, saved["train_time"]) if saved else (0, 0, 0.0)
    if saved:
        _restore(run, saved, first, cell.seed)
    curve_episodes = max(1, min(cell.eval_episodes, 5))
    first_steps, started = done_steps, time.time()
    bar = tqdm(total=cell.budget, initial=done_steps, desc=f"{cell.agent}@{cell.env_id} s{cell.seed}",
               disable=not progress or not stops, leave=False, file=sys.stderr, unit="step")
    for k in range(first, len(stops)):
        target, is_point = stops[k]
        if target > done_steps:
            continuing = k > 0 and _accepts_reset(run.agent)
            run.agent.learn(total_timesteps=target - done_steps, **({"reset_num_timesteps": False} if continuing else {}))
            bar.update(target - done_steps)
            done_steps = target
        if is_point:
            scores = evaluate_episodes(run.agent, run.eval_env, curve_episodes, seed=10_000 + cell.seed,
                                       deterministic=cell.deterministic)
            point = {"steps": done_steps, "mean_normalized_performance": float(np.mean(scores["normalized_performance"]))}
            if "is_success" in scores:
                point["success_rate"] = float(np.mean(scores["is_success"]))
            curve.append(point)
        if resumable and k + 1 < len(stops):  # save, then go on from a learner loaded from the save
            state = _capture(run, cell, k, done_steps, curve, earlier + time.perf_counter() - t0)
            if store is not None:  # both paths go on from what was written, so a resumed run matches
                store.write_progress(steps=done_steps, budget=cell.budget, started=started,
                                     rate=(done_steps - first_steps) / max(time.perf_counter() - t0, 1e-9))
                store.save(state)
                state = store.load()
            run.close()
            run = _build_training(cell, factory, kwargs)
            _restore(run, state, k + 1, cell.seed)
    bar.close()
    train_time = earlier + time.perf_counter() - t0
    t1 = time.perf_counter()
    final = evaluate_episodes(run.agent, run.eval_env, cell.eval_episodes, seed=cell.seed,
                              deterministic=cell.deterministic)
    finals = final.pop("normalized_performance")
    eval_time = time.perf_counter() - t1
    result = {
        "cell": {k: v for k, v in cell.__dict__.items()},
        "final_normalized_performance": finals,
        "final_metrics": final,  # REPORTED_METRICS the env has, one value per episode
        "learning_curve": curve,
        "train_wall_time_s": train_time,
        "eval_wall_time_s": eval_time,
        "trained_steps": done_steps if trains else 0,
        **spent(run.agent, run.env),
        **_validation_scores(run.agent),
        **({"coverage": run.recorder.summary()} if run.recorder is not None else {}),
        "environment": environment,
        "finished_at": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    if saved:
        result["resumed_at_steps"] = saved["steps"]
    run.close()
    return result


def _cell_identity(cell: Cell) -> dict[str, Any]:
    """The settings a checkpoint belongs to (a save of other settings is not resumed)."""
    return json.loads(json.dumps({k: v for k, v in cell.__dict__.items() if k != "tags"}, default=str))


def _capture(run: _Training, cell: Cell, stop: int, steps: int, curve: list[dict[str, float]],
             train_time: float) -> dict[str, Any]:
    """What a checkpoint after stop ``stop`` holds: the learner's training state and the cell's counters."""
    from lfd_agents.training_state import get_training_state

    return {"cell": _cell_identity(cell), "stop": stop, "steps": steps, "curve": curve, "train_time": train_time,
            "env_steps": run.env.env_steps, "agent": get_training_state(run.agent),
            "recorder": run.recorder.get_state() if run.recorder is not None else None}


def _restore(run: _Training, state: dict[str, Any], stop: int, seed: int) -> None:
    """Load a :func:`_capture` into a freshly built ``run`` and seed what goes on after ``stop - 1``."""
    from lfd_agents.training_state import reseed, set_training_state

    set_training_state(run.agent, state["agent"])
    run.env.env_steps = int(state["env_steps"])
    if run.recorder is not None and state.get("recorder") is not None:
        run.recorder.set_state(state["recorder"])
    reseed(run.agent, stop_seed(seed, stop))


def _validation_scores(agent: Any) -> dict[str, list[float]]:
    """``{"validation_scores": [...]}``: the checkpoint-selection score of every training chunk
    (agents that act with their best checkpoint), else ``{}``."""
    scores = getattr(getattr(agent, "selector", None), "scores", None)
    return {"validation_scores": [float(x) for x in scores]} if scores else {}


def _accepts_reset(agent: Any) -> bool:
    import inspect

    try:
        return "reset_num_timesteps" in inspect.signature(agent.learn).parameters
    except (TypeError, ValueError):
        return False
