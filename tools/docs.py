"""Regenerate the measured tables of the docs: ``python -m tools.docs [--tables NAMES]``.

Every table of measured numbers in ``README.md``, ``docs/particle_tasks.md`` and ``docs/mail.md``
sits between two markers, and this command replaces what is between them with a fresh run
(the prose around them is kept)::

    <!-- tools.docs:expert-table -->
    ... generated table and a line naming the command, commit, date and CPU ...
    <!-- /tools.docs -->

Tables (``--tables`` takes names or groups, comma-separated; default ``all``):

==========================  ======================  ==================================================
name                        file                    measured by
==========================  ======================  ==================================================
``expert-table``            docs/particle_tasks.md  :mod:`benchmarks.experts` (every row)
``speed-table``             docs/particle_tasks.md  :func:`benchmarks.speed.particle_env_rows`
``pick-place-speed-table``  docs/particle_tasks.md  :func:`benchmarks.speed.pick_place_speed_rows`
``version-speed-table``     docs/particle_tasks.md  :func:`benchmarks.speed.version_rows` (``-v1``
                                                    against ``-v0``)
``readme-expert-table``     README.md               :mod:`benchmarks.experts` (default set-ups), the
                                                    MuJoCo experts (success rates)
``readme-speed-table``      README.md               :mod:`benchmarks.speed` (engine, envs, renderer,
                                                    Sawyer, MoPA planner)
``mail-dynamics-table``     docs/mail.md            :mod:`benchmarks.mail_bench` (table 1)
``mail-transfer-table``     docs/mail.md            :mod:`benchmarks.mail_bench` (table 2)
==========================  ======================  ==================================================

Groups: ``particles`` (the four particle-task tables), ``readme``, ``mail``, ``experts``, ``speed``.
``--variants N`` (expert tables, default 100) and ``--episodes N`` (MuJoCo experts, default 50)
trade precision for time; ``--quick`` runs everything at tiny settings (to check the command, not
for numbers); ``--envs`` keeps only some particle tasks; ``--root DIR`` edits the files of another
checkout (or a copy). Examples::

    python -m tools.docs --tables mail                     # docs/mail.md, ~5 min on 2 cores
    python -m tools.docs --tables experts --variants 20 --jobs 2
    python -m tools.docs                                   # everything (hours on 2 cores)
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
END = "<!-- /tools.docs -->"
_BLOCK = re.compile(r"<!-- tools\.docs:(?P<name>[a-z0-9-]+) -->\n(?P<body>.*?)" + re.escape(END), re.S)


# ---------------------------------------------------------------------- markers
def find_blocks(text: str) -> dict[str, str]:
    """``{name: current body}`` of the marked blocks of a markdown text."""
    return {m.group("name"): m.group("body") for m in _BLOCK.finditer(text)}


def replace_blocks(text: str, bodies: dict[str, str]) -> str:
    """``text`` with the body of every marked block named in ``bodies`` replaced (others kept).

    Raises ``ValueError`` if a name has no block or a start marker has no end marker.
    """
    starts = re.findall(r"<!-- tools\.docs:([a-z0-9-]+) -->", text)
    if len(starts) != text.count(END):
        raise ValueError(f"unbalanced markers: {len(starts)} start markers, {text.count(END)} '{END}'")
    missing = sorted(set(bodies) - set(find_blocks(text)))
    if missing:
        raise ValueError(f"no marked block for {missing}")

    def sub(m: re.Match) -> str:
        name = m.group("name")
        if name not in bodies:
            return m.group(0)
        body = bodies[name].rstrip("\n") + "\n"
        return f"<!-- tools.docs:{name} -->\n{body}{END}"

    return _BLOCK.sub(sub, text)


# ---------------------------------------------------------------------- settings and shared runs
@dataclass
class Settings:
    """What the tables are measured with (from the command line)."""

    variants: int = 100
    episodes: int = 50
    quick: bool = False
    envs: tuple[str, ...] = ()
    jobs: int = 1
    command: str = "python -m tools.docs"


class Runs:
    """Measurements shared by several tables, each run at most once per command."""

    def __init__(self, settings: Settings):
        self.s = settings
        self._cache: dict[str, Any] = {}

    def once(self, key: str, fn: Callable[[], Any]) -> Any:
        if key not in self._cache:
            t0 = time.perf_counter()
            print(f"tools.docs: running {key} ...", file=sys.stderr, flush=True)
            self._cache[key] = fn()
            print(f"tools.docs: {key} took {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        return self._cache[key]

    def _keep(self, env_id: str) -> bool:
        return not self.s.envs or env_id in self.s.envs

    def experts(self, rows: list[Any]) -> dict[Any, tuple[np.ndarray, float]]:
        """Expert scores of ``rows`` (computed once for all rows any table asks for)."""
        from benchmarks.experts import expert_results

        done = self._cache.setdefault("experts", {})
        todo = [r for r in rows if r not in done and self._keep(r.env_id)]
        if todo:
            print(f"tools.docs: scripted experts, {len(todo)} rows x {self.s.variants} variants ...",
                  file=sys.stderr, flush=True)
            for row, scores, sec in expert_results(todo, self.s.variants, jobs=self.s.jobs):
                done[row] = (scores, sec)
        return {r: done[r] for r in rows if r in done}

    def particle_env_speed(self) -> list[dict[str, Any]]:
        from benchmarks.speed import particle_env_rows

        envs = ("StraightenRope-v0", "ClothFold-v0", "ClothFoldDiagonalPinned-v0", "ClothFoldDiagonalUnpinned-v0")
        envs = tuple(e for e in envs if self._keep(e))
        return self.once("particle env speed", lambda: particle_env_rows(repeats=1 if self.s.quick else 3,
                                                                         env_ids=envs))

    def pick_place_speed(self) -> list[dict[str, Any]]:
        from benchmarks.speed import PICK_PLACE_SPEED_CONFIGS, pick_place_speed_rows

        configs = tuple(c for c in PICK_PLACE_SPEED_CONFIGS if self._keep(c[0]))
        return self.once("pick-and-place speed limit", lambda: pick_place_speed_rows(
            variants=1 if self.s.quick else 4, steps=1 if self.s.quick else 3, configs=configs))

    def versions(self) -> list[dict[str, Any]]:
        from benchmarks.speed import VERSION_CONFIGS, version_rows

        configs = tuple(c for c in VERSION_CONFIGS if self._keep(f"{c[0]}-v0") or self._keep(f"{c[0]}-v1"))
        return self.once("-v1 against -v0 speed", lambda: version_rows(rounds=1 if self.s.quick else 3,
                                                                        configs=configs))

    def mail(self) -> dict[str, Any]:
        from benchmarks import mail_bench

        tiny = ["--train-transitions", "16", "--test-transitions", "8", "--epochs", "1", "--worlds", "4",
                "--demos", "1", "--population", "4", "--random-episodes", "1", "--cloth-resolution", "20"]
        args = mail_bench.parse_args(tiny if self.s.quick else [])
        return self.once("MAIL benchmark", lambda: {"args": args, **mail_bench.run_benchmark(args)})


def _cpu() -> str:
    from benchmarks.speed import _cpu_model

    import os

    return f"{_cpu_model()}, {os.cpu_count()} cores"


def git_commit(root: Path = ROOT) -> str:
    """Short commit of ``root`` (``unknown`` outside a git checkout)."""
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def stamp(name: str, settings: Settings, detail: str = "") -> str:
    """The line under a generated table: the command that regenerates it, commit, date, CPU."""
    extra = f"; {detail}" if detail else ""
    quick = " **(--quick: tiny settings, not for citing)**" if settings.quick else ""
    return (f"\n\n*Generated by `{settings.command}` (table `{name}`) at commit `{git_commit()}`, "
            f"{time.strftime('%Y-%m-%d')}, {_cpu()}{extra}.*{quick}")


# ---------------------------------------------------------------------- tables
def expert_table(runs: Runs) -> str:
    """Every row of :mod:`benchmarks.experts`."""
    from benchmarks.experts import ROWS, TABLE_HEADER, table_row

    results = runs.experts(list(ROWS))
    lines = [TABLE_HEADER] + [table_row(r, *results[r]) for r in ROWS if r in results]
    return "\n".join(lines) + stamp("expert-table", runs.s, f"mean final p̂ over eval variants "
                                                          f"0..{runs.s.variants - 1}, default resolution")


def speed_table(runs: Runs) -> str:
    """Env steps/s of the rope and fold tasks per action mode and obs mode."""
    rows = runs.particle_env_speed()
    table: dict[tuple[str, str], dict[str, Any]] = {}
    for r in rows:
        entry = table.setdefault((r["env"], r["action_mode"]), {"frames": r["frames"], "count": r["particles"],
                                                                 "rates": {}})
        entry["rates"][r["obs"]] = r["cpu_env_steps_per_s"]
    lines = ["| env | particles | action mode | state | image 32×32 | particles obs | frames/step |",
             "|---|---|---|---|---|---|---|"]
    for (env, mode), v in table.items():
        rates = v["rates"]
        lines.append(f"| {env} | {v['count']} | {mode} | {_g(rates.get('state'))} | {_g(rates.get('image'))} | "
                     f"{_g(rates.get('particles'))} | {v['frames']} |")
    return "\n".join(lines) + stamp("speed-table", runs.s, "env steps per second of the calling thread's CPU time, "
                                                         "one env, default resolution and pickers, random actions")


def pick_place_speed_table(runs: Runs) -> str:
    """Pick-and-place at the task's default schedule against the 1 m/s held-picker limit."""
    lines = ["| env | pickers | held pickers move | frames/step | env steps/s | cost | fastest particle (m/s) "
             "| farthest particle (m) |", "|---|---|---|---|---|---|---|---|"]
    for r in runs.pick_place_speed():
        speed = "task schedule" if r["pick_place_speed"] == "default" else f"≤ {r['pick_place_speed']:g} m/s"
        lines.append(f"| {r['env']} | {r['pickers']} | {speed} | {r['frames']} | {_g(r['cpu_env_steps_per_s'])} | "
                     f"{r['cost_vs_default']}× | {r['fastest_particle_m_s']} | {r['farthest_particle_m']} |")
    return "\n".join(lines) + stamp("pick-place-speed-table", runs.s, "MAIL-style random pick-and-place (a random "
                                   "particle, a random place), 3 steps on each of 4 train variants; env steps per "
                                   "second of the calling thread's CPU time; particle speed at the end of a step, "
                                   "distance from the workspace centre along x or y")


def version_speed_table(runs: Runs) -> str:
    """Env steps/s of the ``-v1`` ids against their ``-v0`` twins, measured side by side."""
    lines = ["| task | action mode | pickers | frames/step `-v0` / `-v1` | env steps/s `-v0` | env steps/s `-v1` "
             "| `-v1` / `-v0` |", "|---|---|---|---|---|---|---|"]
    for r in runs.versions():
        lines.append(f"| {r['env']} | {r['action_mode']} | {r['pickers']} | {r['v0_frames']:g} / {r['v1_frames']:g} | "
                     f"{_g(r['v0_cpu_env_steps_per_s'])} | {_g(r['v1_cpu_env_steps_per_s'])} | {r['v1_vs_v0']:.2f}× |")
    return "\n".join(lines) + stamp("version-speed-table", runs.s, "state observations, the same seeded random "
                                   "actions on both versions, median of interleaved rounds; env steps per second "
                                   "of the calling thread's CPU time")


def _g(x: Any) -> str:
    if x is None:
        return "—"
    x = float(x)
    return f"{x:.0f}" if x >= 100 else f"{x:.1f}"


#: README expert rows: env id -> [(pickers, action mode), ...] (the default set-ups first)
README_EXPERT_ROWS: dict[str, list[tuple[int, str]]] = {
    "StraightenRope-v0": [(2, "delta")],
    "ClothFold-v0": [(2, "delta"), (1, "delta")],
    "ClothFoldDiagonalPinned-v0": [(1, "delta"), (1, "pick_place")],
    "ClothFoldDiagonalUnpinned-v0": [(1, "delta"), (1, "pick_place")],
    "DryCloth-v0": [(2, "pick_place"), (1, "pick_place")],
    "ThreeBoxes-v0": [(3, "pick_place"), (2, "pick_place"), (1, "pick_place")],
}
MUJOCO_EXPERT_ENVS = ("Push2DObstacle-v0", "SawyerPushObstacle-v0", "SawyerLiftObstacle-v0",
                      "SawyerAssemblyObstacle-v0")


def readme_expert_table(runs: Runs) -> str:
    """Expert mean p̂ of the particle tasks' main set-ups and the MuJoCo experts' success rates."""
    from benchmarks.experts import ROWS

    wanted = [r for r in ROWS if (r.num_pickers, r.action_mode) in README_EXPERT_ROWS.get(r.env_id, [])]
    results = runs.experts(wanted)
    lines = ["| env | scripted expert | episodes |", "|---|---|---|"]
    for env_id, setups in README_EXPERT_ROWS.items():
        cells = []
        for pickers, mode in setups:
            row = next(r for r in wanted if (r.env_id, r.num_pickers, r.action_mode) == (env_id, pickers, mode))
            if row in results:
                cells.append(f"{results[row][0].mean():.3f} ({pickers} picker{'s' * (pickers > 1)}, {mode})")
        if cells:
            lines.append(f"| `{env_id}` | mean p̂ " + ", ".join(cells) + f" | {runs.s.variants} eval variants |")
    if not runs.s.envs:
        from benchmarks.sawyer_experts import evaluate

        for env_id in MUJOCO_EXPERT_ENVS:
            r = runs.once(f"{env_id} expert", lambda env_id=env_id: evaluate(env_id, runs.s.episodes))
            lines.append(f"| `{env_id}` | success {r['success_rate']:.2f} | {runs.s.episodes} eval variants |")
        from lfd_envs.experts.nist import success_rates

        rates = runs.once("NIST expert", lambda: success_rates(episodes=runs.s.episodes))
        lo, hi = min(v["success_rate"] for v in rates.values()), max(v["success_rate"] for v in rates.values())
        span = f"{lo:.2f}" if lo == hi else f"{lo:.2f}–{hi:.2f}"
        lines.append(f"| `NistBoardInsert-v0` | success {span} over its {len(rates)} peg/hole instructions | "
                     f"{runs.s.episodes} seeds each |")
    return "\n".join(lines) + stamp("readme-expert-table", runs.s)


def readme_speed_table(runs: Runs) -> str:
    """The README's throughput summary (every number measured by :mod:`benchmarks.speed` in this run)."""
    from benchmarks import speed

    q = runs.s.quick
    engine = runs.once("engine speed", lambda: speed.particle_engine_rows(
        resolutions=(40, 80), worlds=(1, 16), repeats=2 if q else 20))
    envs = runs.particle_env_speed()
    dry = runs.once("DryCloth speed", lambda: speed.drycloth_threeboxes_rows(
        repeats=1 if q else 3, configs=(("DryCloth-v0", "pick_place", 1, "state"),
                                        ("DryCloth-v0", "pick_place", 2, "state"))))
    render = runs.once("render speed", lambda: speed.render_rows(sizes=(32,), worlds=(1,), repeats=3 if q else 30))

    def engine_rate(config: str, cloth: str, **match: Any) -> dict[str, Any] | None:
        return next((r for r in engine if r["config"] == config and r["cloth"] == cloth
                     and all(r.get(k) == v for k, v in match.items())), None)

    def env_rate(env: str, mode: str, obs: str) -> str:
        r = next((r for r in envs if (r["env"], r["action_mode"], r["obs"]) == (env, mode, obs)), None)
        return _g(r["cpu_env_steps_per_s"]) if r else "—"

    e40, e80 = engine_rate("resolution", "40x40", self_collision=True), engine_rate("resolution", "80x80",
                                                                                 self_collision=True)
    b16 = engine_rate("batched", "40x40", worlds=16)
    dry_rates = sorted(r["cpu_env_steps_per_s"] for r in dry)
    lines = ["| what | measured | reference |", "|---|---|---|",
             f"| 40×40 cloth, 10 iterations, self-collision, substeps/s | {_g(e40 and e40['cpu_substeps_per_s'])} | |",
             f"| 80×80 cloth, substeps/s | {_g(e80 and e80['cpu_substeps_per_s'])} | |",
             f"| 16 batched worlds vs 1 world, cost | {b16['cost_vs_1_world'] if b16 else '—'}× | "
             "(serial CPU kernels: no launch overhead left to amortise) |",
             f"| ClothFold delta env steps/s, state / 32×32 image | {env_rate('ClothFold-v0', 'delta', 'state')} / "
             f"{env_rate('ClothFold-v0', 'delta', 'image')} | SoftGym FleX ≈ 55 on an RTX 3080 |",
             f"| pick_place env steps/s (ClothFold / DiagonalPinned / DryCloth 1–2 pickers) | "
             f"{env_rate('ClothFold-v0', 'pick_place', 'state')} / "
             f"{env_rate('ClothFoldDiagonalPinned-v0', 'pick_place', 'state')} / "
             f"{'–'.join(_g(x) for x in dry_rates) or '—'} | original DryCloth 3.4 on FleX with a GPU |",
             f"| 32×32 render of a 40×40 cloth scene | {render[0]['cpu_ms_per_call']:.2f} ms | |"]
    lines += [_readme_version_row(r) for r in runs.versions() if r["env"] == "ClothFold" and r["pickers"] == 2]
    if not runs.s.envs:
        sawyer = runs.once("Sawyer speed", lambda: speed.sawyer_env_rows(
            steps=20 if q else 150, image_steps=5 if q else 40, valid_checks=100 if q else 2000,
            repeats=1 if q else 3))
        state = [r for r in sawyer if r["obs"] == "state"]
        steps = sorted(r["cpu_env_steps_per_s"] for r in state)
        valid = sorted(r["cpu_is_valid_per_s"] for r in state)
        mopa = runs.once("MoPA planner speed", lambda: speed.mopa_rows(rrt_calls=2 if q else 15,
                                                                     budget_s=10.0 if q else 60.0))
        rrt = [r for r in mopa if r["env"].startswith("Sawyer")]
        lines += [f"| Sawyer tasks, state env steps/s | {_g(steps[0])}–{_g(steps[-1])} | robosuite 20–140 |",
                  f"| `is_valid` collision checks/s (Sawyer) | {valid[0] / 1e3:.0f}k–{valid[-1] / 1e3:.0f}k | |",
                  "| MoPA RRT-Connect call, median (Sawyer push/lift/assembly) | "
                  + " / ".join(f"{r['rrt_median_ms']:.0f}" if r["rrt_median_ms"] is not None else "—" for r in rrt)
                  + " ms | original ≈ 300 ms |"]
    return "\n".join(lines) + stamp("readme-speed-table", runs.s, "CPU time of the calling thread "
                                                                "(Warp's CPU kernels and MuJoCo run on it)")


def _readme_version_row(r: dict[str, Any]) -> str:
    """README line of one ``-v1`` against ``-v0`` row of :func:`benchmarks.speed.version_rows`."""
    return (f"| ClothFold {r['action_mode']} env steps/s, `-v1` / `-v0` (2 pickers, state) | "
            f"{_g(r['v1_cpu_env_steps_per_s'])} / {_g(r['v0_cpu_env_steps_per_s'])} ({r['v1_vs_v0']:.2f}×) | |")


def mail_dynamics_table(runs: Runs) -> str:
    """Learned dynamics vs simulator (table 1 of :mod:`benchmarks.mail_bench`)."""
    out = runs.mail()
    lines = ["| task | particles (model) | learned err (m) | mean motion (m) | learned / zero-motion chamfer (m) "
             "| learned / simulator transitions/s |", "| --- | --- | --- | --- | --- | --- |"]
    for r in out["dynamics"]:
        lines.append(f"| {r[0]} | {r[1]} ({r[2]}) | {r[7]} | {r[8]} | {r[9]} / {r[10]} | {r[11]} / {r[12]} ({r[13]}) |")
    return "\n".join(lines) + stamp("mail-dynamics-table", runs.s, _mail_detail(out))


def mail_transfer_table(runs: Runs) -> str:
    """The transfers (table 2 of :mod:`benchmarks.mail_bench`)."""
    out = runs.mail()
    lines = ["| transfer | backend | CEM s/demo | mean p̂ converted | mean p̂ kept (kept) | random-action p̂ |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in out["transfers"]:
        lines.append(f"| {r[0]} | {r[1]} | {r[3]} | {r[5]} | {r[6]} ({r[7]}) | {r[8]} |")
    return "\n".join(lines) + stamp("mail-transfer-table", runs.s, _mail_detail(out))


def _mail_detail(out: dict[str, Any]) -> str:
    a = out["args"]
    return (f"`python -m benchmarks.mail_bench` settings: cloth resolution {a.cloth_resolution}, "
            f"{a.train_transitions} training / {a.test_transitions} held-out transitions, {a.epochs} epochs, "
            f"{a.demos} demos per transfer, CEM population {a.population} × 1 iteration, scoring {a.scoring}; "
            f"{out['seconds'] / 60:.1f} min for both tables")


@dataclass(frozen=True)
class Table:
    """A generated table: the file (relative to the root) that holds its marked block and its generator."""

    file: str
    make: Callable[[Runs], str]


TABLES: dict[str, Table] = {
    "expert-table": Table("docs/particle_tasks.md", expert_table),
    "speed-table": Table("docs/particle_tasks.md", speed_table),
    "pick-place-speed-table": Table("docs/particle_tasks.md", pick_place_speed_table),
    "version-speed-table": Table("docs/particle_tasks.md", version_speed_table),
    "readme-expert-table": Table("README.md", readme_expert_table),
    "readme-speed-table": Table("README.md", readme_speed_table),
    "mail-dynamics-table": Table("docs/mail.md", mail_dynamics_table),
    "mail-transfer-table": Table("docs/mail.md", mail_transfer_table),
}
GROUPS: dict[str, tuple[str, ...]] = {
    "all": tuple(TABLES),
    "particles": ("expert-table", "speed-table", "pick-place-speed-table", "version-speed-table"),
    "readme": ("readme-expert-table", "readme-speed-table"),
    "mail": ("mail-dynamics-table", "mail-transfer-table"),
    "experts": ("expert-table", "readme-expert-table"),
    "speed": ("speed-table", "version-speed-table", "readme-speed-table"),
}


def resolve_tables(spec: str) -> list[str]:
    """Table names of a comma-separated list of names and groups (``ValueError`` listing both)."""
    names: list[str] = []
    for part in filter(None, (p.strip() for p in spec.split(","))):
        found = GROUPS.get(part, (part,) if part in TABLES else None)
        if found is None:
            raise ValueError(f"unknown table {part!r}; tables: {sorted(TABLES)}, groups: {sorted(GROUPS)}")
        names += [n for n in found if n not in names]
    if not names:
        raise ValueError("no table given")
    return names


def regenerate(names: list[str], settings: Settings, root: Path = ROOT) -> list[Path]:
    """Measure the tables ``names`` and write them into their files under ``root``.

    Every file and marker is checked before anything runs; files are written atomically once all
    their tables are measured. Returns the files written.
    """
    from lfd_bench.storage import atomic_write_text

    by_file: dict[Path, list[str]] = {}
    for name in names:
        by_file.setdefault(Path(root) / TABLES[name].file, []).append(name)
    texts = {}
    for path, file_names in by_file.items():
        if not path.is_file():
            raise ValueError(f"{path} does not exist (--root should be a checkout)")
        texts[path] = path.read_text()
        replace_blocks(texts[path], {n: "" for n in file_names})  # all markers present and balanced
    runs = Runs(settings)
    written = []
    for path, file_names in by_file.items():
        bodies = {n: TABLES[n].make(runs) for n in file_names}
        atomic_write_text(path, replace_blocks(texts[path], bodies))
        written.append(path)
        print(f"tools.docs: wrote {', '.join(file_names)} into {path}", file=sys.stderr, flush=True)
    return written


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.docs", description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tables", default="all", help=f"comma-separated tables {sorted(TABLES)} or groups "
                                                   f"{sorted(GROUPS)} (default all)")
    p.add_argument("--variants", type=int, default=100, help="eval variants per expert row (default 100)")
    p.add_argument("--episodes", type=int, default=50, help="episodes per MuJoCo expert (default 50)")
    p.add_argument("--envs", default="", help="only these particle env ids (expert and particle speed rows); "
                                              "leaves out the MuJoCo rows")
    p.add_argument("--jobs", type=int, default=1, help="worker processes for the expert rows")
    p.add_argument("--quick", action="store_true", help="tiny settings everywhere (checks the command)")
    p.add_argument("--root", default=str(ROOT), help="checkout whose README.md and docs/ are rewritten")
    p.add_argument("--list", action="store_true", help="list the tables and the files holding them")
    args = p.parse_args(argv)
    if args.list:
        for name, t in TABLES.items():
            print(f"{name:22s} {t.file}")
        return 0
    try:
        names = resolve_tables(args.tables)
        if args.variants < 1 or args.episodes < 1 or args.jobs < 1:
            raise ValueError("--variants, --episodes and --jobs must be >= 1")
        envs = tuple(filter(None, args.envs.split(",")))
        from benchmarks.experts import ROWS

        unknown = sorted(set(envs) - {r.env_id for r in ROWS})
        if unknown:
            raise ValueError(f"unknown particle env(s) {unknown}; valid: {sorted({r.env_id for r in ROWS})}")
        variants, episodes = (min(args.variants, 2), min(args.episodes, 2)) if args.quick else (args.variants,
                                                                                                   args.episodes)
        given = list(argv if argv is not None else sys.argv[1:])
        if "--root" in given:  # where the files were written is not part of how to regenerate them
            i = given.index("--root")
            del given[i:i + 2]
        given = [a for a in given if not a.startswith("--root=")]
        command = "python -m tools.docs " + " ".join(given)
        settings = Settings(variants=variants, episodes=episodes, quick=args.quick, envs=envs, jobs=args.jobs,
                            command=command.strip())
        import warp as wp

        wp.config.quiet = True
        regenerate(names, settings, Path(args.root))
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
