"""NistBoardInsert-v0: contact physics of the peg and board, env contract, scripted expert."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs.core.rollout import play_episode
from lfd_envs.experts import make_expert
from lfd_envs.mujoco import nist_board as board
from lfd_envs.mujoco.nist import HELDOUT_TASKS, TRAIN_TASKS, NistBoardInsertEnv, all_tasks


def _place(env: NistBoardInsertEnv, pos: np.ndarray) -> None:
    """Put the tip (and its compliance target) at ``pos`` at rest."""
    d = env.data
    d.qpos[:3] = pos
    d.qvel[:] = 0.0
    env.set_commanded_target(pos)
    mujoco.mj_forward(env.model, d)


def _inserts(env: NistBoardInsertEnv, offset: float, angle: float) -> bool:
    """Descend at full speed from 3 cm above the hole, laterally offset; True if the peg went in."""
    env.reset(seed=0)
    hole = env.hole_top
    _place(env, hole + [offset * np.cos(angle), offset * np.sin(angle), 0.03])
    for _ in range(25):
        _, _, terminated, _, _ = env.step(np.array([0.0, 0.0, -1.0], np.float32))
        if terminated:
            break
    return bool(env.tip_position[2] < hole[2] - 0.003)


ANGLES = (0.0, 1.0, 2.5, 4.0)


@pytest.mark.parametrize("task,fit", [("insert medium peg in large hole", "loose"),
                                      ("insert small peg in small hole", "tight")])
def test_peg_enters_only_when_aligned(task, fit):
    env = NistBoardInsertEnv(instruction=task, fit=fit, obs_mode="state")
    env.reset(seed=0)
    c = env.clearance
    assert all(_inserts(env, 0.8 * c, a) for a in ANGLES)
    # beyond the clearance (plus ~0.1 mm of soft-contact "chamfer" at full speed) it is blocked
    assert not any(_inserts(env, c + 3e-4, a) for a in ANGLES)
    assert not any(_inserts(env, c + 2e-3, a) for a in ANGLES)


def test_tight_fit_blocks_more_offsets_than_loose():
    offsets = (0.1e-3, 0.3e-3, 0.6e-3, 1.0e-3, 1.5e-3, 2.5e-3)
    loose = NistBoardInsertEnv(instruction="insert medium peg in large hole", fit="loose", obs_mode="state")
    tight = NistBoardInsertEnv(instruction="insert medium peg in medium hole", fit="tight", obs_mode="state")
    blocked_loose = sum(not _inserts(loose, o, 0.5) for o in offsets)
    blocked_tight = sum(not _inserts(tight, o, 0.5) for o in offsets)
    assert blocked_tight >= blocked_loose + 3, (blocked_loose, blocked_tight)
    with pytest.raises(ValueError, match="does not fit"):
        NistBoardInsertEnv(instruction="insert medium peg in medium hole", fit="loose")


@pytest.mark.parametrize("where", ["flat", "hole_edge", "in_hole"])
def test_contact_pressed_on_board_is_stable(where):
    env = NistBoardInsertEnv(instruction="insert small peg in medium hole", fit="tight", obs_mode="state")
    env.reset(seed=0)
    hole = env.hole_top
    start = {"flat": np.array([0.0, 0.0, hole[2] + 0.005]),
             "hole_edge": hole + [env.clearance + 0.5e-3, 0.0, 0.005],
             "in_hole": hole + [0.0, 0.0, -0.010]}[where]
    _place(env, start)
    rng = np.random.default_rng(0)
    max_speed = 0.0
    lateral = 0.0 if where == "hole_edge" else 0.3  # pressed right at the edge of the hole
    for t in range(120):
        action = np.array([*rng.uniform(-lateral, lateral, 2), -1.0], np.float32)
        env.step(action)
        assert np.all(np.isfinite(env.data.qpos)) and np.all(np.isfinite(env.data.qvel))
        max_speed = max(max_speed, float(np.abs(env.data.qvel[:3]).max()))
        if where != "in_hole":
            assert env.tip_position[2] > hole[2] - 2e-4  # never through the board
        else:
            assert env.tip_position[2] > env.hole_bottom[2] - 2e-4
    # commanded speed is 7.5 cm/s; kinetic energy stays of that order (no explosion)
    assert max_speed < 0.2
    assert 0.5 * board.EE_MASS * max_speed ** 2 < 0.01


def test_spaces_tokens_and_contract():
    env = gym.make("lfd_envs:NistBoardInsert-v0", action_mode="tokens", obs_mode="state+image",
                   image_size=(24, 32), action_repeat=2)
    obs, info = env.reset(seed=1)
    assert set(obs) == {"workspace", "wrist", "instruction_tokens", "state"}  # gym.make's SB3-friendly default
    assert obs["workspace"].shape == (24, 32, 3) and obs["wrist"].dtype == np.uint8
    assert env.unwrapped.instruction in TRAIN_TASKS and env.observation_space.contains(obs)
    assert env.action_space.nvec.tolist() == [21, 21, 21]
    assert {"performance", "normalized_performance", "variant", "is_success"} <= set(info)
    tip = env.unwrapped.tip_position
    env.step(np.array([20, 10, 10]))  # +3 mm in x twice (action_repeat=2)
    assert env.unwrapped.commanded_target[0] - tip[0] == pytest.approx(0.006, abs=1e-9)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.array([1, 2]))
    with pytest.raises(ValueError, match="integer"):
        env.step(np.array([1.5, 2, 3]))
    env.step(np.array([99, -5, 10]))  # clipped
    with pytest.raises(TypeError, match="valid arguments"):
        NistBoardInsertEnv(bogus=1)
    with pytest.raises(ValueError, match="cameras"):
        NistBoardInsertEnv(cameras=("top",))


def test_state_roundtrip_and_determinism():
    env = NistBoardInsertEnv(instruction="all", fit="tight", obs_mode="state")
    env.reset(seed=5, options={"instruction": "insert tiny peg in tiny hole"})
    assert env.instruction == "insert tiny peg in tiny hole"
    for _ in range(5):
        env.step(np.array([0.3, -0.2, -1.0], np.float32))
    state = env.get_state()
    actions = [np.array([0.1, 0.2, -1.0], np.float32)] * 10
    first = [env.step(a)[0] for a in actions]
    env.reset(seed=9)  # another task/variant
    env.set_state(state)
    assert env.instruction == "insert tiny peg in tiny hole"
    second = [env.step(a)[0] for a in actions]
    assert all(np.array_equal(a, b) for a, b in zip(first, second))


def test_images_differ_between_cameras_and_tasks():
    env = NistBoardInsertEnv(image_size=(32, 40), instruction=TRAIN_TASKS)
    obs, _ = env.reset(seed=0, options={"instruction": TRAIN_TASKS[0]})
    assert not np.array_equal(obs["workspace"], obs["wrist"])
    obs2, _ = env.reset(seed=0, options={"instruction": TRAIN_TASKS[1]})
    assert obs2["instruction"] == TRAIN_TASKS[1]
    assert not np.array_equal(obs["wrist"], obs2["wrist"])  # another peg in the gripper


@pytest.mark.parametrize("fit,mode", [("loose", "continuous"), ("tight", "tokens")])
def test_expert_succeeds_with_recovery(fit, mode):
    tasks = (*TRAIN_TASKS, *HELDOUT_TASKS) + (("insert small peg in small hole",) if fit == "tight" else ())
    successes, recovered = [], 0
    for task in tasks:
        env = NistBoardInsertEnv(instruction=task, fit=fit, obs_mode="state", action_mode=mode)
        expert = make_expert(env, recovery_prob=0.5)
        for seed in range(4):
            info = play_episode(env, expert, seed=seed)
            successes.append(info["is_success"])
            recovered += expert.recovered
    assert np.mean(successes) >= 0.95
    assert recovered >= 2  # some episodes hit the board, backed off and re-aligned


def test_task_lists():
    assert len(all_tasks("loose")) == 6 and len(all_tasks("tight")) == 10
    assert HELDOUT_TASKS[0] not in TRAIN_TASKS
