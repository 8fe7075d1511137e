"""Train and evaluate agents on envs, one JSON per cell, then rewrite ``leaderboard.md``.

Usage::

    python -m benchmarks.run --suite smoke
    python -m benchmarks.run --suite paper-dmfd --seeds 0 1 2 --budget 200000
    python -m benchmarks.run --suite smoke --agent mypkg.agents:make_agent   # third-party agent
    python -m benchmarks.run --suite path/to/suite.json --out results/

A suite (``benchmarks/configs/<name>.json``) lists cells: an env id with its kwargs, the
agents to run on it (name -> kwargs), a training budget (env steps), seeds and the number
of evaluation episodes (acting with ``predict(deterministic=True)``, or sampled actions where a
cell or the suite sets ``"deterministic": false``). Each (env, agent, seed) cell is trained, evaluated on the env's
*eval* variants and saved as JSON; cells whose JSON exists and reads back are skipped (resume);
a corrupt one is reported by path and re-run.

Cells run one after another (``--executor local``), in ``--jobs N`` local processes, or as
tasks on a Ray cluster (``--executor ray --address HOST:PORT``); see :mod:`benchmarks.executors`.
Expert demonstrations are cached under ``<out>/_demos`` (:mod:`benchmarks.demo_cache`).
"""

from __future__ import annotations

import argparse
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
CONFIGS = Path(__file__).resolve().parent / "configs"
DEFAULT_OUT = Path(__file__).resolve().parent / "results"


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
    from benchmarks.storage import safe_name

    return safe_name(name)


# ---------------------------------------------------------------------- suites
def available_suites() -> list[str]:
    return sorted(p.stem for p in CONFIGS.glob("*.json"))


def load_suite(name: str) -> dict[str, Any]:
    """Load a suite by name (``benchmarks/configs``) or path to a JSON file."""
    path = Path(name)
    if not path.suffix:
        path = CONFIGS / f"{name}.json"
    if not path.exists():
        raise ValueError(f"unknown suite {name!r}; valid suites are {available_suites()} or a path to a .json file")
    try:
        suite = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"suite {path} is not valid JSON: {exc}") from exc
    suite.setdefault("name", path.stem)
    check_suite(suite, path)
    return suite


_STATS = ("mean", "std", "p25", "median", "p75")


def check_suite(suite: dict[str, Any], path: Path | str = "suite") -> None:
    """Raise ``ValueError`` naming ``path`` and the entry if the suite is wrong (before any training):
    the schema of :mod:`benchmarks.suite_schema`, the agents' kwargs and the reference rows."""
    from benchmarks.suite_schema import check_agent_kwargs, validate_suite

    def bad(what: str) -> ValueError:
        return ValueError(f"{path}: {what}")

    validate_suite(suite, path)  # every key (unknown ones refused), type and range
    check_agent_kwargs(suite, path)
    refs = suite.get("reference", {})
    if not isinstance(refs, dict):
        raise bad("'reference' must map env ids to {source, rows}")
    for env, ref in refs.items():
        if not isinstance(ref, dict) or not isinstance(ref.get("source"), str) or not isinstance(ref.get("rows"), dict):
            raise bad(f"reference[{env!r}] needs a 'source' string and a 'rows' object {{agent: {{{', '.join(_STATS)}}}}}")
        for agent, row in ref["rows"].items():
            if not isinstance(row, dict) or not row:
                raise bad(f"reference[{env!r}].rows[{agent!r}] must be an object with some of {list(_STATS)}")
            valid = list(_STATS) + list(REPORTED_METRICS)  # p̂ statistics, or the mean of a reported metric
            unknown = sorted(set(row) - set(valid))
            if unknown:
                raise bad(f"reference[{env!r}].rows[{agent!r}] has unknown keys {unknown}; valid: {valid}")
            if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in row.values()):
                raise bad(f"reference[{env!r}].rows[{agent!r}] values must be numbers")


def expand_cells(suite: dict[str, Any], *, agents: list[str] | None = None, envs: list[str] | None = None,
                 seeds: list[int] | None = None, budget: int | None = None, device: str | None = None,
                 extra_agents: list[str] | None = None) -> list[Cell]:
    """The grid of cells of ``suite`` after command-line filters and overrides."""
    from benchmarks import recipes
    from benchmarks.agents import REFERENCE_AGENTS, resolve_agent
    from benchmarks.suite_schema import check_env_kwargs

    import gymnasium as gym
    import lfd_envs  # noqa: F401

    if budget is not None and (isinstance(budget, bool) or not isinstance(budget, int) or budget < 1):
        raise ValueError(f"budget must be an integer >= 1, got {budget!r}")
    if seeds is not None and not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
        raise ValueError(f"seeds must be non-negative integers, got {seeds!r}")
    cells: list[Cell] = []
    known_envs = [c["env"] for c in suite["cells"]]
    suite_agents = {name for c in suite["cells"] for name in c.get("agents", {})}
    if envs:
        bad = [e for e in envs if e not in known_envs]
        if bad:
            raise ValueError(f"env(s) {bad} not in suite {suite['name']!r}; valid: {sorted(set(known_envs))}")
    for spec in suite["cells"]:
        env_id = spec["env"]
        if envs and env_id not in envs:
            continue
        module, _, bare_id = env_id.rpartition(":")
        if module:
            try:
                importlib.import_module(module)
            except ImportError as exc:
                raise ValueError(f"cannot import {module!r} for env {env_id!r}: {exc}") from exc
        if bare_id not in gym.registry:
            raise ValueError(f"unknown env {env_id!r}; registered lfd envs: {sorted(lfd_envs.ENV_SPECS)}")
        check_env_kwargs(env_id, dict(spec.get("env_kwargs", {})), f"suite {suite.get('name', '?')!r}, env {env_id!r}")
        cell_agents: dict[str, dict] = dict(spec.get("agents", {}))
        for extra in extra_agents or []:
            cell_agents.setdefault(extra, {})
        if agents:  # names some cell of the suite lists run only where listed; others run everywhere
            cell_agents = {a: cell_agents.get(a, {}) for a in agents if a in cell_agents or a not in suite_agents}
        for name in cell_agents:
            resolve_agent(name)  # fail early with the list of valid agents
        for agent, kwargs in cell_agents.items():
            kwargs, recipe = recipes.resolve(agent, kwargs)
            tags = {k: spec[k] for k in ("label", "notes", "coverage_steps", "headline") if k in spec}
            if recipe:
                tags["recipe"] = recipe
            if device and agent not in REFERENCE_AGENTS:
                kwargs["device"] = device
            for seed in seeds if seeds is not None else spec.get("seeds", suite.get("seeds", [0])):
                cells.append(Cell(
                    suite=suite["name"], env_id=env_id, env_kwargs=dict(spec.get("env_kwargs", {})),
                    agent=agent, agent_kwargs=kwargs, seed=int(seed),
                    budget=int(budget if budget is not None else spec.get("budget", suite.get("budget", 1000))),
                    eval_episodes=int(spec.get("eval_episodes", suite.get("eval_episodes", 10))),
                    curve_points=int(spec.get("curve_points", suite.get("curve_points", 4))),
                    tags=dict(tags),
                    cpus=int(spec.get("cpus", suite.get("cpus", 1))),
                    deterministic=bool(spec.get("deterministic", suite.get("deterministic", True))),
                    checkpoint_steps=spec.get("checkpoint_steps", suite.get("checkpoint_steps")),
                ))
    if not cells and agents:
        raise ValueError(f"no cell of suite {suite['name']!r}{' for env(s) ' + str(envs) if envs else ''} lists "
                         f"agent(s) {agents}; agents listed per env: "
                         f"{sorted({(c['env'], a) for c in suite['cells'] for a in c.get('agents', {})})}")
    return cells


# ---------------------------------------------------------------------- running
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

    from benchmarks.budget import StepCounter

    env = StepCounter(gym.make(cell.env_id, **cell.env_kwargs))
    recorder = None
    if cell.tags.get("coverage_steps"):  # end-effector positions of the first training steps
        from benchmarks.coverage import EndEffectorRecorder

        recorder = EndEffectorRecorder(env, int(cell.tags["coverage_steps"]))
    eval_env = gym.make(cell.env_id, **cell.env_kwargs)
    return _Training(env, eval_env, factory(env, cell.seed, **kwargs), recorder)


def run_cell(cell: Cell, progress: bool = True, demo_cache: Path | None = None,
             checkpoints: Path | None = None) -> dict[str, Any]:
    """Train ``cell.agent`` for ``cell.budget`` steps with a learning curve, then evaluate it.

    ``demo_cache`` is the demonstration cache folder handed to the built-in demonstration
    agents (default ``benchmarks/results/_demos``). The result records what training spent:
    ``env_steps`` (steps in the training env), ``gradient_updates`` and ``demo_transitions``;
    ``final_metrics`` holds the per-episode :data:`REPORTED_METRICS` the env reports. A cell
    with ``coverage_steps`` N also records where the end-effector went during the first N
    training steps (``coverage``, :class:`benchmarks.coverage.EndEffectorRecorder`). An agent that
    acts with its best checkpoint records each chunk's validation score (``validation_scores``).

    ``checkpoints`` (a folder, :class:`benchmarks.checkpoints.CheckpointStore`): a learner with a
    training state (:func:`lfd_agents.training_state.supports_training_state`) saves it at every
    stop (:func:`training_stops`) and goes on from a fresh learner loaded from the save, so a
    re-run after a kill resumes from the newest save with the uninterrupted result. Without a
    folder the learner is still rebuilt at every stop (the same result), but nothing is saved.
    """
    from tqdm import tqdm

    import lfd_envs  # noqa: F401  (registers the ids; a worker process starts without them)
    from benchmarks.agents import resolve_agent
    from benchmarks.budget import spent
    from benchmarks.checkpoints import CheckpointStore
    from lfd_agents.training_state import get_training_state, reseed, set_training_state, supports_training_state

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
        _restore(run, saved, first, cell.seed, set_training_state, reseed)
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
            state = {"cell": _cell_identity(cell), "stop": k, "steps": done_steps, "curve": curve,
                     "train_time": earlier + time.perf_counter() - t0, "env_steps": run.env.env_steps,
                     "agent": get_training_state(run.agent),
                     "recorder": run.recorder.get_state() if run.recorder is not None else None}
            if store is not None:  # both paths go on from what was written, so a resumed run matches
                store.write_progress(steps=done_steps, budget=cell.budget, started=started,
                                     rate=(done_steps - first_steps) / max(time.perf_counter() - t0, 1e-9))
                store.save(state)
                state = store.load()
            run.close()
            run = _build_training(cell, factory, kwargs)
            _restore(run, state, k + 1, cell.seed, set_training_state, reseed)
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


def _restore(run: _Training, state: dict[str, Any], stop: int, seed: int, set_state: Any, reseed: Any) -> None:
    """Load a saved training state into a freshly built ``run`` and seed what goes on after ``stop - 1``."""
    set_state(run.agent, state["agent"])
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


def run_grid(cells: list[Cell], out: Path, progress: bool = True, force: bool = False, *, executor: str = "local",
             jobs: int = 1, address: str | None = None) -> list[Path]:
    """Run every cell whose JSON is missing or corrupt (all with ``force``); return the result paths.

    Raises :class:`benchmarks.executors.CellsFailed` after the other cells finished if any
    cell failed (their results are written all the same).
    """
    from benchmarks.checkpoints import CHECKPOINT_DIRNAME, CheckpointStore
    from benchmarks.demo_cache import CACHE_DIRNAME
    from benchmarks.executors import run_cells
    from benchmarks.storage import CorruptResult, check_writable, read_result, write_result

    out = check_writable(out)
    paths, todo = [], []
    for cell in cells:
        path = out / f"{cell.key}.json"
        paths.append(path)
        if force:  # a forced cell starts from zero, not from an earlier run's checkpoint
            CheckpointStore.for_cell(out, cell.key).remove()
        elif path.exists():
            try:
                read_result(path)
                continue
            except CorruptResult as exc:
                print(f"warning: {exc}; running the cell again", file=sys.stderr)
        todo.append(cell)

    def done(cell: Cell, result: dict[str, Any]) -> None:
        write_result(out / f"{cell.key}.json", result)  # atomic: a kill never leaves half a file
        CheckpointStore.for_cell(out, cell.key).remove()

    run_cells(todo, done, executor=executor, jobs=jobs, address=address, demo_cache=out / CACHE_DIRNAME,
              progress=progress, checkpoints=out / CHECKPOINT_DIRNAME)
    return paths


# ---------------------------------------------------------------------- CLI
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m benchmarks.run", description=__doc__.split("\n")[0])
    p.add_argument("--suite", required=True, help=f"suite name {available_suites()} or path to a .json file")
    p.add_argument("--agents", nargs="+", help="only these agents (names or package.module:factory); a name that some cell lists runs only in the cells that list it")
    p.add_argument("--agent", action="append", default=[], help="add a third-party agent package.module:factory")
    p.add_argument("--envs", nargs="+", help="only these env ids")
    p.add_argument("--seeds", nargs="+", type=int, help="override the suite's seeds")
    p.add_argument("--budget", type=int, help="override training budget (env steps)")
    p.add_argument("--device", help="torch device for learning agents (cpu, cuda)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="results folder (one JSON per cell)")
    p.add_argument("--leaderboard", default=str(ROOT / "leaderboard.md"), help="markdown file to rewrite")
    p.add_argument("--plot-dir", help="folder of the leaderboard's plots (default: docs/leaderboard beside it)")
    p.add_argument("--force", action="store_true", help="re-run finished cells")
    p.add_argument("--executor", choices=["local", "ray"], default="local",
                   help="local: this machine (see --jobs); ray: one task per cell on a Ray cluster")
    p.add_argument("--jobs", type=int, default=1, help="local executor: cells run in parallel processes")
    p.add_argument("--address", help="ray executor: cluster address (as printed by `ray start --head`); "
                                     "default: start a local Ray instance")
    p.add_argument("--preflight", action="store_true",
                   help="only check that every (env, agent) pair runs: tiny budgets, results in a temporary "
                        "folder, no leaderboard (minutes instead of hours)")
    p.add_argument("--report", action="store_true",
                   help="train nothing: rewrite the suite's leaderboard section from the cells already finished "
                        "in --out (the command it shows leaves --report out)")
    p.add_argument("--no-progress", action="store_true")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from benchmarks.leaderboard import write_leaderboard

    args = parse_args(argv)
    try:
        suite = load_suite(args.suite)
        cells = expand_cells(suite, agents=args.agents, envs=args.envs, seeds=args.seeds, budget=args.budget,
                             device=args.device, extra_agents=args.agent)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from benchmarks.executors import CellsFailed
    from benchmarks.storage import check_writable

    out = Path(args.out)
    try:
        if args.jobs < 1:
            raise ValueError(f"--jobs must be >= 1, got {args.jobs}")
        if args.address and args.executor != "ray":
            raise ValueError("--address needs --executor ray")
        if args.device and args.device.startswith("cuda") and args.executor == "local":
            import torch

            if not torch.cuda.is_available():
                raise ValueError(f"--device {args.device}: torch sees no CUDA device on this machine")
        check_writable(out)  # refuse before any training, not after the first cell
        check_writable(Path(args.leaderboard).parent)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.preflight:
        return preflight(cells, args)
    code = 0
    if not args.report:
        try:
            run_grid(cells, out, progress=not args.no_progress, force=args.force, executor=args.executor,
                     jobs=args.jobs, address=args.address)
        except CellsFailed as exc:
            print(f"error: {exc}", file=sys.stderr)
            code = 1
    shown = [a for a in (argv if argv is not None else sys.argv[1:]) if a != "--report"]
    command = "python -m benchmarks.run " + " ".join(shown)
    try:
        path = write_leaderboard(out, Path(args.leaderboard), command=command, suite=suite["name"], suite_config=suite,
                                 plot_dir=Path(args.plot_dir) if args.plot_dir else None,
                                 progress=not args.no_progress)
    except ValueError as exc:  # no finished cell of this suite yet
        print(f"error: {exc}", file=sys.stderr)
        return code or 1
    print(f"wrote {path}")
    return code


def preflight(cells: list[Cell], args: argparse.Namespace) -> int:
    """Run the tiny version of every distinct cell (:mod:`benchmarks.preflight`); 0 if all ran."""
    import tempfile

    from benchmarks.executors import CellsFailed
    from benchmarks.preflight import preflight_cells

    tiny = preflight_cells(cells)
    with tempfile.TemporaryDirectory(prefix="lfd-preflight-") as tmp:
        try:
            run_grid(tiny, Path(tmp), progress=not args.no_progress, force=True, executor=args.executor,
                     jobs=args.jobs, address=args.address)
        except CellsFailed as exc:
            print(f"preflight: {exc}", file=sys.stderr)
            return 1
    print(f"preflight: all {len(tiny)} (env, agent) pairs ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())
