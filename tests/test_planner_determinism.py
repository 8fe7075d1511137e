"""A seeded OMPLPlanner gives the same paths whatever OMPL planning ran before in the process.

OMPL seeds every RNG it creates from one process-global generator; the planner re-seeds that
generator per query (see :mod:`lfd_envs.mujoco.ompl_planner`). The reference paths come from a
fresh interpreter, the compared ones from this process after other (seeded and unseeded)
planning, with other planners' queries interleaved between the seeded planner's own.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from typing import Callable

import numpy as np
import pytest

from lfd_envs.mujoco.ompl_planner import ompl_available, query_seed

pytestmark = pytest.mark.skipif(not ompl_available(), reason="ompl not installed")

LIMITS = np.array([[-1.0, 1.0], [-1.0, 1.0]])
#: start/goal pairs on either side of the wall: the straight line is blocked, OMPL must search
QUERIES = [((-0.6, 0.0), (0.6, 0.0)), ((-0.5, 0.5), (0.7, -0.3)), ((0.6, -0.2), (-0.6, 0.4))]


def wall_valid(q: np.ndarray) -> bool:
    """Free space of the unit square minus a wall |x| < 0.15, |y| < 0.8 (gaps at top and bottom)."""
    return not (abs(q[0]) < 0.15 and abs(q[1]) < 0.8)


def seeded_paths(seed: int, between: Callable[[], None] | None = None) -> list[list[list[float]]]:
    """Paths of the :data:`QUERIES` by one planner seeded ``seed``; ``between`` runs before each."""
    from lfd_envs.mujoco.ompl_planner import OMPLPlanner

    planner = OMPLPlanner(wall_valid, LIMITS, dq_step=0.05, range=0.2, time_limit=5.0, seed=seed)
    out = []
    for start, goal in QUERIES:
        if between is not None:
            between()
        result = planner.plan(np.array(start), np.array(goal))
        assert result.status == "planner", result.status
        out.append(result.path.tolist())
    return out


def _fresh_process_paths(seed: int) -> list[np.ndarray]:
    here = os.path.dirname(os.path.abspath(__file__))
    code = (f"import sys, json; sys.path.insert(0, {here!r}); "
            f"from test_planner_determinism import seeded_paths; print(json.dumps(seeded_paths({seed})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         cwd=os.path.dirname(here), check=True)
    return [np.array(p) for p in json.loads(out.stdout.strip().splitlines()[-1])]


def _other_planning(seed: int | None) -> None:
    """Blocked queries by another planner (creates and consumes OMPL RNGs)."""
    from lfd_envs.mujoco.ompl_planner import OMPLPlanner

    planner = OMPLPlanner(wall_valid, LIMITS, dq_step=0.05, range=0.2, time_limit=5.0, seed=seed)
    for start, goal in QUERIES[:2]:
        assert planner.plan(np.array(goal), np.array(start)).used_planner


def test_seeded_paths_match_a_fresh_process_after_other_planning():
    reference = _fresh_process_paths(3)
    _other_planning(None)
    _other_planning(11)
    again = [np.array(p) for p in seeded_paths(3, between=lambda: _other_planning(None))]
    assert len(again) == len(reference)
    for ref, got in zip(reference, again):
        assert ref.shape == got.shape and np.array_equal(ref, got)
    # the seed matters: another seed finds other paths for the same queries
    other = [np.array(p) for p in seeded_paths(4)]
    assert any(a.shape != b.shape or not np.array_equal(a, b) for a, b in zip(reference, other))


def test_query_seeds_are_valid_ompl_seeds_and_distinct():
    seeds = {query_seed(s, k) for s in range(5) for k in range(50)}
    assert len(seeds) == 250
    assert all(1 <= v < 2**31 for v in seeds)


@pytest.mark.parametrize("bad", [-1, 1.5, "3", True])
def test_bad_seed_is_rejected(bad):
    from lfd_envs.mujoco.ompl_planner import OMPLPlanner

    with pytest.raises(ValueError, match="seed"):
        OMPLPlanner(wall_valid, LIMITS, dq_step=0.05, seed=bad)


def test_mopa_agent_seeds_its_planners():
    import gymnasium as gym

    import lfd_envs  # noqa: F401
    from lfd_agents.mopa import MoPAAgent

    env = gym.make("Push2DObstacle-v0")
    agent = MoPAAgent(env, seed=5, learning_starts=10)
    assert agent.train_env.planner.seed == 5
    agent.bind(gym.make("Push2DObstacle-v0"))
    assert agent._eval.planner.seed == 5
    custom = MoPAAgent(env, seed=5, wrapper_kwargs={"planner_kwargs": {"seed": 9}})
    assert custom.train_env.planner.seed == 9


def test_a_query_does_not_depend_on_the_planners_earlier_queries():
    """The second query of two planners with the same seed gives the same path and the same
    number of validity checks although their first queries differed: every random object of a
    query is made after that query's seed."""
    from lfd_envs.mujoco.ompl_planner import OMPLPlanner

    second = []
    for first_goal in ((0.6, 0.0), (0.6, -0.5)):
        planner = OMPLPlanner(wall_valid, LIMITS, dq_step=0.05, range=0.2, time_limit=5.0, max_checks=3000, seed=4)
        first = planner.plan(np.array([-0.6, 0.3]), np.array(first_goal))
        assert first.used_planner
        result = planner.plan(np.array([-0.5, -0.3]), np.array([0.7, 0.3]))
        assert result.status == "planner", result.status
        second.append((result.path, result.extra["checks"]))
        planner.close()
    np.testing.assert_array_equal(second[0][0], second[1][0])
    assert second[0][1] == second[1][1]
