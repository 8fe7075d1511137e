"""Scores that cannot be gamed and MAIL's variants of them; MAIL's random agent; the harness
columns that report them."""

import json

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs.core.rollout import play_episode
from lfd_envs.experts import make_expert

EVAL0 = {"split": "eval", "variant": 0}


def _diagonal(pinned: bool, **kw):
    return gym.make("lfd_envs:ClothFoldDiagonal-v0", pinned=pinned, obs_mode="state", action_mode="pick_place", **kw)


# ---------------------------------------------------------------------- diagonal fold quality
@pytest.mark.parametrize("pinned", [False, True])
def test_fold_quality_is_not_fooled_by_shrinking(pinned):
    env = _diagonal(pinned)
    _, info = env.reset(seed=0, options=EVAL0)
    assert abs(info["fold_quality"]) < 0.01  # the flat start is the 0 of the scale
    base = env.unwrapped
    task, batch = base.task, base.batch
    pos = batch.positions.astype(np.float64)
    center = task.grid(pos).reshape(1, -1, 3).mean(axis=1)
    for f in (0.1, 0.5, 0.8):
        shrunk = pos.copy()
        shrunk[..., :2] = center[:, None, :2] + f * (pos[..., :2] - center[:, None, :2])
        scores = task.evaluate(shrunk, batch.ctx)
        p_hat = task.normalized_performance(scores["performance"], batch.p0)[0]
        assert p_hat == pytest.approx(1.0 - f, abs=1e-3)  # the published edge metric is fooled
        assert scores["fold_quality"][0] < 0.1


@pytest.mark.parametrize("pinned", [False, True])
def test_fold_quality_expert_high_grab_lift_drop_low(pinned):
    env = _diagonal(pinned)
    expert_info = play_episode(env, make_expert(env), seed=0, options=EVAL0)
    assert expert_info["fold_quality"] > 0.8
    assert expert_info["fold_quality"] <= expert_info["normalized_performance"] + 0.05

    _, info = env.reset(seed=0, options=EVAL0)
    base = env.unwrapped
    n = base.task.resolution
    centre = base.batch.positions[0, base.task.grid_index(n // 2, n // 2)].astype(np.float64)
    lifted = centre + [0.0, 0.0, 0.35]
    grab_lift_drop = base.picker_actions.join(centre[None, None], lifted[None, None])[0]
    idle = base.picker_actions.join(lifted[None, None] + [0, 0, 0.2], lifted[None, None] + [0, 0, 0.2])[0]
    for action in (grab_lift_drop, idle, idle):
        _, _, _, _, info = env.step(action)
    assert info["performance"] != pytest.approx(base.batch.p0[0])  # the cloth really was lifted and dropped
    assert info["fold_quality"] < 0.1
    assert expert_info["fold_quality"] > info["fold_quality"] + 0.7


def test_fold_quality_below_expert_for_random_pick_place():
    from lfd_bench.agents import PickPlaceRandomAgent

    env = _diagonal(False)
    rand = np.mean([play_episode(env, PickPlaceRandomAgent(env, seed=s), seed=0, options=EVAL0)["fold_quality"]
                    for s in range(2)])
    expert = play_episode(env, make_expert(env), seed=0, options=EVAL0)["fold_quality"]
    assert rand < 0.5 < expert


def test_flat_layout_matches_the_start_state():
    env = _diagonal(True)
    env.reset(seed=0, options={"split": "eval", "variant": 7})
    base = env.unwrapped
    flat = base.task.flat_grid(base.batch.ctx["offset"], base.batch.ctx["yaw"])
    d = np.linalg.norm(base.task.grid(base.batch.positions) - flat, axis=-1)
    assert d.max() < 0.01 and d.mean() < 0.001  # settling moves the cloth by millimetres at most


# ---------------------------------------------------------------------- MAIL metrics
def test_clothfold_mail_metric_adds_the_corner_term():
    kw = dict(num_pickers=2, action_mode="pick_place", obs_mode="state", resolution=20)
    default, mail = gym.make("lfd_envs:ClothFold-v0", **kw), gym.make("lfd_envs:ClothFold-v0", metric="mail", **kw)
    _, a = default.reset(seed=0, options=EVAL0)
    _, b = mail.reset(seed=0, options=EVAL0)
    side = float(mail.unwrapped.batch.ctx["size"][0])
    assert b["corner_term"] == pytest.approx(2 * side, rel=0.01)  # flat: TL-TR and BL-BR are the side
    assert b["performance"] == pytest.approx(a["performance"] - b["corner_term"], abs=1e-6)
    # a cloth folded exactly (left half on the right half, right half in place): 0 with both metrics
    task, batch = mail.unwrapped.task, mail.unwrapped.batch
    grid = task.grid(batch.positions).astype(np.float64).copy()
    n = grid.shape[2]
    grid[:, :, : n // 2] = grid[:, :, ::-1][:, :, : n // 2]
    folded = grid.reshape(1, -1, 3)
    scores = task.evaluate(folded, batch.ctx)
    assert scores["corner_term"][0] == pytest.approx(0.0, abs=1e-9)
    assert scores["performance"][0] == pytest.approx(0.0, abs=1e-6)
    # the expert's fold scores high under MAIL's metric too
    info = play_episode(mail, make_expert(mail), seed=0, options=EVAL0)
    assert info["normalized_performance"] > 0.7
    with pytest.raises(ValueError, match="metric"):
        gym.make("lfd_envs:ClothFold-v0", metric="mial")


def test_drycloth_mail_spread_reference_and_reach():
    from lfd_envs.tasks.dry_cloth import PLANK_X

    kw = dict(obs_mode="state", resolution=20)
    env = gym.make("lfd_envs:DryCloth-v0", metric="mail", reach=0.1, **kw)
    refs = []
    for k in range(4):
        _, info = env.reset(seed=0, options={"split": "eval", "variant": k})
        yaw = float(env.unwrapped.batch.ctx["yaw"][0])
        assert info["spread_reference"] == pytest.approx(0.5 * abs(np.cos(yaw) + np.sin(yaw)), rel=1e-6)
        refs.append(info["spread_reference"])
    assert np.ptp(refs) > 0.05  # MAIL's reference changes with the rotation
    _, info = gym.make("lfd_envs:DryCloth-v0", **kw).reset(seed=0, options=EVAL0)
    assert info["spread_reference"] == 0.5
    # reach: no picker centre goes further than 0.1 m past the plank's centre line
    base = env.unwrapped
    env.reset(seed=0, options=EVAL0)
    pick = base.batch.positions[0, base.task.grid_index(0, 0)].astype(np.float64)
    far = np.array([PLANK_X - 0.5, 0.0, 0.4])
    a = base.picker_actions.join(pick[None, None], far[None, None])[0]
    targets, _ = base.picker_actions.plan(a[None], base.batch.pickers)
    assert targets[..., 0].min() == pytest.approx(PLANK_X - 0.1)
    default_ws = gym.make("lfd_envs:DryCloth-v0", **kw).unwrapped.workspace
    assert default_ws.lo[0] == pytest.approx(-0.65)  # default workspace unchanged
    with pytest.raises(ValueError, match="reach"):
        gym.make("lfd_envs:DryCloth-v0", reach=-1.0)
    with pytest.raises(ValueError, match="metric"):
        gym.make("lfd_envs:DryCloth-v0", metric="x")


def test_paper_mail_suite_uses_mail_metrics():
    from lfd_bench.run import load_suite

    for cell in load_suite("paper-mail")["cells"]:
        if cell["env"] in ("ClothFold-v0", "DryCloth-v0"):
            assert cell["env_kwargs"].get("metric") == "mail"
        if cell["env"] == "DryCloth-v0":
            assert cell["env_kwargs"].get("reach") == 0.1
        small = {"resolution": 20} if "Cloth" in cell["env"] else {}
        gym.make(cell["env"], **{**cell["env_kwargs"], **small}).close()  # the kwargs are accepted


# ---------------------------------------------------------------------- random agents
def test_random_agent_in_pick_place_picks_particles():
    from lfd_bench.agents import PickPlaceRandomAgent, RandomAgent, resolve_agent

    env = gym.make("lfd_envs:ClothFold-v0", num_pickers=1, action_mode="pick_place", obs_mode="state", resolution=20)
    mail_random, uniform = resolve_agent("random")(env, 0), resolve_agent("random_uniform")(env, 0)
    assert isinstance(mail_random, PickPlaceRandomAgent) and isinstance(uniform, RandomAgent)
    base = env.unwrapped
    radius = base.task.grasp_radius

    def pick_hits(agent, steps=4):
        hits = []
        for k in range(steps):
            obs, _ = env.reset(seed=k, options=EVAL0)
            agent.reset() if hasattr(agent, "reset") else None
            pick, _ = base.picker_actions.split(agent.predict(obs)[0][None])
            d = np.linalg.norm(base.batch.positions[0].astype(np.float64) - pick[0, 0], axis=1).min()
            hits.append(d < radius)
        return np.mean(hits)

    assert pick_hits(mail_random) == 1.0  # MAIL's random always picks a particle
    assert pick_hits(uniform, 40) < 0.25   # uniform points mostly grasp air
    # reproducible: same seeds, same actions
    obs, _ = env.reset(seed=3, options=EVAL0)
    a = PickPlaceRandomAgent(env, seed=1)
    a.reset()
    first = a.predict(obs)[0]
    env.reset(seed=3, options=EVAL0)
    a.reset()
    np.testing.assert_array_equal(a.predict(obs)[0], first)
    delta = gym.make("lfd_envs:ClothFold-v0", obs_mode="state", resolution=20)
    assert isinstance(resolve_agent("random")(delta, 0), RandomAgent)


# ---------------------------------------------------------------------- harness and leaderboard
def _result(agent, finals, metrics=None, seed=0):
    from lfd_bench.cell import environment_info

    r = {"cell": {"suite": "m", "env_id": "ClothFoldDiagonalPinned-v0", "agent": agent, "seed": seed, "tags": {}},
         "final_normalized_performance": finals, "learning_curve": [], "trained_steps": 0,
         "environment": environment_info()}
    if metrics is not None:
        r["final_metrics"] = metrics
    return r


def test_harness_records_fold_quality_and_leaderboard_reports_it(tmp_path, monkeypatch):
    from lfd_bench import run as bench
    from lfd_bench import stats

    monkeypatch.setattr(stats, "REPS", 200)  # fewer bootstrap replications: the table, not the CIs, is tested
    monkeypatch.setattr(stats, "POI_REPS", 100)
    from lfd_bench.leaderboard import write_leaderboard
    from lfd_bench.storage import read_result, write_result

    cell = bench.Cell(suite="m", env_id="ClothFoldDiagonalPinned-v0",
                      env_kwargs={"action_mode": "pick_place", "obs_mode": "state", "resolution": 20},
                      agent="random", agent_kwargs={}, seed=0, budget=0, eval_episodes=2)
    result = bench.run_cell(cell, progress=False)
    assert len(result["final_metrics"]["fold_quality"]) == 2
    path = write_result(tmp_path / "m" / "ClothFoldDiagonalPinned-v0" / "random" / "seed0.json", result)
    assert read_result(path)["final_metrics"] == result["final_metrics"]
    # an old result (no final_metrics) stays readable and shows a dash
    write_result(tmp_path / "m" / "ClothFoldDiagonalPinned-v0" / "bc" / "seed0.json", _result("bc", [0.5, 0.6]))
    write_result(tmp_path / "m" / "ClothFoldDiagonalPinned-v0" / "expert" / "seed0.json",
                 _result("expert", [0.95, 0.96], {"fold_quality": [0.9, 0.8]}))
    write_leaderboard(tmp_path, tmp_path / "lb.md", command="test", suite="m")
    md = (tmp_path / "docs" / "results" / "m.md").read_text()  # the appendix page holds every column
    head = next(line for line in md.splitlines() if line.startswith("| agent"))
    assert "fold quality mean ± std" in head
    col = head.split("|").index(" fold quality mean ± std ")
    rows = {line.split("|")[1].strip(): line.split("|") for line in md.splitlines() if line.startswith("| ")}
    assert rows["expert"][col].strip() == "0.850 ± 0.050"
    assert rows["bc"][col].strip() == "—"
    q = np.asarray(result["final_metrics"]["fold_quality"])
    assert rows["random"][col].strip() == f"{q.mean():.3f} ± {q.std():.3f}"
    assert all(len(r) == len(head.split("|")) for r in rows.values())
    # envs without the metric keep the old header
    bare = json.loads(json.dumps(_result("bc", [0.1])))
    bare["cell"]["env_id"] = "ThreeBoxes-v0"
    write_result(tmp_path / "m" / "ThreeBoxes-v0" / "bc" / "seed0.json", bare)
    write_leaderboard(tmp_path, tmp_path / "lb.md", command="test", suite="m")
    md = (tmp_path / "docs" / "results" / "m.md").read_text()
    section = md.split("## ThreeBoxes-v0")[1]
    assert "fold quality" not in section.split("\n\n")[1]


def test_malformed_final_metrics_is_corrupt(tmp_path):
    from lfd_bench.storage import CorruptResult, read_result, write_result

    path = write_result(tmp_path / "r.json", _result("bc", [0.5, 0.6], {"fold_quality": [0.1]}))
    with pytest.raises(CorruptResult, match="final_metrics"):
        read_result(path)
