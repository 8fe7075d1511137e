"""Train and evaluate agents on envs, one JSON per cell, then rewrite ``leaderboard.md``.

Usage::

    python -m lfd_bench.run --suite smoke
    python -m lfd_bench.run --suite paper-dmfd --seeds 0 1 2 --budget 200000
    python -m lfd_bench.run --suite smoke --agent mypkg.agents:make_agent   # third-party agent
    python -m lfd_bench.run --suite path/to/suite.json --out results/

A suite (``lfd_bench/configs/<name>.json``) lists cells: an env id with its kwargs, the
agents to run on it (name -> kwargs), a training budget (env steps), seeds and the number
of evaluation episodes (acting with ``predict(deterministic=True)``, or sampled actions where a
cell or the suite sets ``"deterministic": false``). Each (env, agent, seed) cell is trained, evaluated on the env's
*eval* variants and saved as JSON; cells whose JSON exists and reads back are skipped (resume);
a corrupt one is reported by path and re-run.

Cells run one after another (``--executor local``), in ``--jobs N`` local processes, or as
tasks on a Ray cluster (``--executor ray --address HOST:PORT``); see :mod:`lfd_bench.executors`.
Expert demonstrations are cached under ``<out>/_demos`` (:mod:`lfd_bench.demo_cache`).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path
from typing import Any

from lfd_bench.cell import REPORTED_METRICS, Cell, run_cell  # noqa: F401  (run_cell: importable from here too)
CONFIGS = Path(__file__).resolve().parent / "configs"
DEFAULT_OUT = Path("results")  #: relative to the working directory, never the install folder


# ---------------------------------------------------------------------- suites
def available_suites() -> list[str]:
    return sorted(p.stem for p in CONFIGS.glob("*.json"))


def load_suite(name: str) -> dict[str, Any]:
    """Load a suite by name (``lfd_bench/configs``) or path to a JSON file."""
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
    the schema of :mod:`lfd_bench.suite_schema`, the agents' kwargs and the reference rows."""
    from lfd_bench.suite_schema import check_agent_kwargs, validate_suite

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
    from lfd_bench import recipes
    from lfd_bench.agents import REFERENCE_AGENTS, resolve_agent
    from lfd_bench.suite_schema import check_env_kwargs

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


# ---------------------------------------------------------------------- grid
def run_grid(cells: list[Cell], out: Path, progress: bool = True, force: bool = False, *, executor: str = "local",
             jobs: int = 1, address: str | None = None) -> list[Path]:
    """Run every cell whose JSON is missing or corrupt (all with ``force``); return the result paths.

    Raises :class:`lfd_bench.executors.CellsFailed` after the other cells finished if any
    cell failed (their results are written all the same).
    """
    from lfd_bench.checkpoints import CHECKPOINT_DIRNAME, CheckpointStore
    from lfd_bench.demo_cache import CACHE_DIRNAME
    from lfd_bench.executors import run_cells
    from lfd_bench.storage import CorruptResult, check_writable, read_result, write_result

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
    p = argparse.ArgumentParser(prog="python -m lfd_bench.run", description=__doc__.split("\n")[0])
    p.add_argument("--suite", required=True, help=f"suite name {available_suites()} or path to a .json file")
    p.add_argument("--agents", nargs="+", help="only these agents (names or package.module:factory); a name that some cell lists runs only in the cells that list it")
    p.add_argument("--agent", action="append", default=[], help="add a third-party agent package.module:factory")
    p.add_argument("--envs", nargs="+", help="only these env ids")
    p.add_argument("--seeds", nargs="+", type=int, help="override the suite's seeds")
    p.add_argument("--budget", type=int, help="override training budget (env steps)")
    p.add_argument("--device", help="torch device for learning agents (cpu, cuda)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="results folder, one JSON per cell (default: ./results)")
    p.add_argument("--leaderboard", default="leaderboard.md", help="markdown file to rewrite (default: in the working directory)")
    p.add_argument("--plot-dir", help="folder of the leaderboard's plots (default: docs/leaderboard beside it)")
    p.add_argument("--pages-dir", help="folder of the suites' appendix pages (default: docs/results beside the leaderboard)")
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
    from lfd_bench.leaderboard import write_leaderboard

    args = parse_args(argv)
    try:
        suite = load_suite(args.suite)
        cells = expand_cells(suite, agents=args.agents, envs=args.envs, seeds=args.seeds, budget=args.budget,
                             device=args.device, extra_agents=args.agent)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from lfd_bench.executors import CellsFailed
    from lfd_bench.storage import check_writable

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
    command = regenerate_command(argv if argv is not None else sys.argv[1:])
    try:
        path = write_leaderboard(out, Path(args.leaderboard), command=command, suite=suite["name"], suite_config=suite,
                                 plot_dir=Path(args.plot_dir) if args.plot_dir else None,
                                 pages_dir=Path(args.pages_dir) if args.pages_dir else None,
                                 progress=not args.no_progress)
    except ValueError as exc:  # no finished cell of this suite yet
        print(f"error: {exc}", file=sys.stderr)
        return code or 1
    print(f"wrote {path}")
    return code


# Options that choose which of the suite's cells run now, or how, but not what any cell holds: the
# leaderboard shows every finished cell of the suite, so the command it prints leaves them out.
_RUN_SCOPE_FLAGS = {"--agents": True, "--envs": True, "--jobs": True, "--executor": True, "--address": True,
                    "--force": False, "--report": False, "--no-progress": False}


def regenerate_command(argv: list[str]) -> str:
    """The command that regenerates the whole suite section written from ``argv``: ``argv`` without
    the options that only scope or schedule this invocation (``--envs``, ``--agents``, ``--jobs``, ...)."""
    kept: list[str] = []
    skipping = False
    for token in argv:
        flag = token.split("=", 1)[0]
        if flag in _RUN_SCOPE_FLAGS:
            skipping = _RUN_SCOPE_FLAGS[flag] and "=" not in token
            continue
        if skipping and not token.startswith("-"):
            continue
        skipping = False
        kept.append(token)
    return " ".join(["python -m lfd_bench.run", *kept])


def preflight(cells: list[Cell], args: argparse.Namespace) -> int:
    """Run the tiny version of every distinct cell (:mod:`lfd_bench.preflight`); 0 if all ran."""
    import tempfile

    from lfd_bench.executors import CellsFailed
    from lfd_bench.preflight import preflight_cells

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
