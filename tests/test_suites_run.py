"""Every committed suite runs: each agent and each env of every suite is built, trained a few
steps (gradient updates included), evaluated and recorded, with ``--device cpu`` passed to the
learners. Budgets are tiny (``lfd_bench.preflight``): 4 env steps, one demonstration episode,
one evaluation episode capped at 10 steps (``max_episode_steps``, for time only)."""

import json

import gymnasium as gym
import pytest

from lfd_bench import run as bench
from lfd_bench.agents import REFERENCE_AGENTS
from lfd_bench.preflight import preflight_cells
from lfd_bench.storage import read_result, result_files

SUITES = bench.available_suites()


def _obs_kind(cell) -> str:
    spec = gym.registry[cell.env_id.split(":")[-1]]
    return str(cell.env_kwargs.get("obs_mode", (spec.kwargs or {}).get("obs_mode", "default")))


def _code_path(cell) -> tuple:
    """Cells that exercise the same code: one agent, one observation kind, same string options
    (``backend``: simulator/learned...)."""
    options = tuple(sorted((k, v) for k, v in cell.agent_kwargs.items() if isinstance(v, str) and k != "device"))
    return cell.agent, _obs_kind(cell), options


def covering_cells():
    """Fewest cells such that every (agent, observation kind, options) and every env id of every
    suite runs at least once; cheap envs and cheap agents are preferred."""
    every, chosen, paths, envs = [], [], set(), set()
    for name in SUITES:
        suite = bench.load_suite(name)
        every += [(name, c) for c in preflight_cells(bench.expand_cells(suite, device="cpu"))]
    for name, cell in every:
        if _code_path(cell) not in paths:
            paths.add(_code_path(cell))
            envs.add((name, cell.env_id))
            chosen.append(cell)
    cheap = ("random", "zero", "expert")
    for name, cell in sorted(every, key=lambda nc: cheap.index(nc[1].agent) if nc[1].agent in cheap else len(cheap)):
        if (name, cell.env_id) not in envs:
            envs.add((name, cell.env_id))
            chosen.append(cell)
    return every, chosen


def test_covering_set_names_every_agent_and_env():
    every, chosen = covering_cells()
    assert {c.agent for _, c in every} == {c.agent for c in chosen}
    for name in SUITES:
        suite = bench.load_suite(name)
        assert {s["env"] for s in suite["cells"]} <= {c.env_id for c in chosen}
    assert all(c.agent_kwargs.get("device") == "cpu" for c in chosen if c.agent not in REFERENCE_AGENTS)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_every_agent_and_env_of_every_suite_runs(tmp_path, one_torch_thread):
    _, cells = covering_cells()
    out = tmp_path / "res"
    bench.run_grid(cells, out, progress=False)  # raises CellsFailed naming every cell that crashed
    files = result_files(out)
    assert len(files) == len({c.key for c in cells})
    for f in files:
        r = read_result(f)
        cell = r["cell"]
        assert len(r["final_normalized_performance"]) == 1
        assert {"env_steps", "gradient_updates", "demo_transitions"} <= set(r)
        if cell["agent"] in ("sac", "td3", "ppo", "dmfd", "sac_lfd", "awac", "mopa_sac", "drq", "curl"):
            assert r["env_steps"] > 0 and r["gradient_updates"] > 0, (f, r["env_steps"], r["gradient_updates"])
        if cell["agent"] in ("bc", "nist_bc", "nist_bc_h6", "nist_bc_1cam"):
            assert r["env_steps"] == 0 and r["gradient_updates"] > 0 and r["demo_transitions"] > 0, f
        json.dumps(r)
