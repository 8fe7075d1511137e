"""The joint-space planner belongs to the env package; experts and MoPA share it; fallbacks warn."""

import ast
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs.experts import sawyer as sawyer_experts
from lfd_envs.mujoco.ompl_planner import OMPLPlanner

ROOT = Path(__file__).resolve().parent.parent


def test_env_package_never_imports_agents():
    offenders = []
    for path in (ROOT / "lfd_envs").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            offenders += [f"{path.relative_to(ROOT)}: {n}" for n in names if n.split(".")[0] == "lfd_agents"]
    assert offenders == []
    code = "import sys, lfd_envs.experts.sawyer; print([m for m in sys.modules if m.startswith('lfd_agents')])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_mopa_uses_the_env_package_planner():
    from lfd_agents.mopa import OMPLPlanner as MoPAPlanner

    assert MoPAPlanner is OMPLPlanner


def test_sawyer_expert_plans_with_ompl_and_warns_on_fallback(monkeypatch, recwarn):
    env = gym.make("SawyerPushObstacle-v0")
    env.reset(seed=0)
    base = env.unwrapped
    q0 = base.arm_qpos()
    rng = np.random.default_rng(0)
    q1 = next(q for q in (q0 + rng.uniform(-0.2, 0.2, q0.shape) for _ in range(100)) if base.is_valid(q))
    plan = sawyer_experts.make_planner(env, time_limit=0.5)
    assert isinstance(plan.planner, OMPLPlanner) and not recwarn.list
    path = plan(q0, q1)
    assert path is not None and np.allclose(path[0], q0) and np.allclose(path[-1], q1)
    monkeypatch.setattr(sawyer_experts, "ompl_available", lambda: False)
    with pytest.warns(RuntimeWarning, match="OMPL is not installed.*plan_path.*OMPLPlanner"):
        fallback = sawyer_experts.make_planner(env)
    path = fallback(q0, q1)
    assert path is not None and np.allclose(path[-1], q1)
