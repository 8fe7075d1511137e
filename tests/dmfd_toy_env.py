"""A cheap LfdEnv for the agent tests: a 2-D point gripper that must pick a block and place it on a goal.

The reward (performance change) only moves when the block moves, and the block only moves
after a grasp within 0.15 of it, so random exploration almost never sees reward while a
scripted expert solves it in ~15 steps: demonstrations matter, as on the cloth tasks.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from lfd_envs.core import LfdEnv


class ToyPickPlaceEnv(LfdEnv):
    """2-D pick-and-place. Action: [dx, dy, grasp] in [-1, 1] (move 0.1·a, grasp when > 0).

    Reduced state: gripper xy, block xy, goal xy, grasped flag. p = −‖block − goal‖.
    """

    task_name = "ToyPickPlace"
    step_size = 0.1
    grasp_radius = 0.15

    def __init__(self, obs_mode: str = "state", image_size: int | tuple[int, int] = 32,
                 render_mode: str | None = None, horizon: int = 30):
        self._init_contract(obs_mode=obs_mode, image_size=image_size, render_mode=render_mode, horizon=horizon)
        self.action_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.state_space = spaces.Box(-np.inf, np.inf, (7,), np.float32)
        self.gripper = np.zeros(2)
        self.block = np.zeros(2)
        self.goal = np.zeros(2)
        self.grasped = False
        self._finish_init()

    def _setup_variant(self, rng: np.random.Generator) -> None:
        self.gripper = rng.uniform(-0.8, 0.8, 2)
        self.block = rng.uniform(-0.6, 0.6, 2)
        self.goal = self.block
        while np.linalg.norm(self.goal - self.block) < 0.5:
            self.goal = rng.uniform(-0.6, 0.6, 2)
        self.grasped = False

    def _apply_action(self, action: np.ndarray) -> None:
        grasp = bool(action[2] > 0)
        if grasp and not self.grasped and np.linalg.norm(self.gripper - self.block) < self.grasp_radius:
            self.grasped = True
        if not grasp:
            self.grasped = False
        self.gripper = np.clip(self.gripper + self.step_size * action[:2], -1.0, 1.0)
        if self.grasped:
            self.block = self.gripper.copy()

    def _state_obs(self) -> np.ndarray:
        return np.concatenate([self.gripper, self.block, self.goal, [float(self.grasped)]]).astype(np.float32)

    def _performance(self) -> float:
        return -float(np.linalg.norm(self.block - self.goal))

    def _is_success(self) -> bool:
        return bool(np.linalg.norm(self.block - self.goal) < 0.05)

    def _render(self, height: int, width: int) -> np.ndarray:
        img = np.zeros((height, width, 3), np.uint8)
        for pos, colour in ((self.goal, (0, 200, 0)), (self.block, (220, 30, 30)), (self.gripper, (255, 255, 255))):
            r = int(np.clip((1 - pos[1]) / 2 * height, 0, height - 1))
            c = int(np.clip((pos[0] + 1) / 2 * width, 0, width - 1))
            img[max(r - 1, 0):r + 2, max(c - 1, 0):c + 2] = colour
        return img

    def _get_sim_state(self) -> dict[str, np.ndarray]:
        return {"gripper": self.gripper.copy(), "block": self.block.copy(), "goal": self.goal.copy(),
                "grasped": np.array(self.grasped)}

    def _set_sim_state(self, state: dict[str, np.ndarray]) -> None:
        self.gripper = np.array(state["gripper"], dtype=np.float64)
        self.block = np.array(state["block"], dtype=np.float64)
        self.goal = np.array(state["goal"], dtype=np.float64)
        self.grasped = bool(state["grasped"])


class ToyExpert:
    """Scripted oracle: keep the grasp closed, go to the block (it attaches), carry it to the goal.

    ``goal_offset`` makes a suboptimal demonstrator that carries the block to ``goal + offset``.
    """

    def __init__(self, env: Any, goal_offset: np.ndarray | None = None):
        self.env = env.unwrapped
        self.goal_offset = np.zeros(2) if goal_offset is None else np.asarray(goal_offset, float)

    def reset(self) -> None:
        pass

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        e = self.env
        target = np.clip(e.goal + self.goal_offset, -1.0, 1.0) if e.grasped else e.block
        delta = (target - e.gripper) / e.step_size
        move = delta / max(1.0, float(np.abs(delta).max()))
        return np.array([move[0], move[1], 1.0], np.float32), None


def collect_episodes(n: int, obs_mode: str = "state", seed: int = 0, horizon: int = 30,
                     image_size: int = 32, wrong_goal_fraction: float = 0.0) -> list[dict[str, Any]]:
    """Expert episodes as dicts (observations T+1, actions, rewards, ..., per-step states in infos).

    With ``wrong_goal_fraction`` that share of the episodes (drawn at random) carries the block
    to a wrong place 0.6 from the goal: mixed-quality demonstrations.
    """
    env = ToyPickPlaceEnv(obs_mode=obs_mode, horizon=horizon, image_size=image_size)
    rng = np.random.default_rng(seed)
    episodes = []
    for i in range(n):
        obs, _ = env.reset(seed=seed + i)
        direction = rng.normal(size=2)
        offset = 0.6 * direction / np.linalg.norm(direction) if rng.random() < wrong_goal_fraction else None
        expert = ToyExpert(env, offset)
        observations, actions, rewards, states = [obs], [], [], [env.get_state()]
        done = False
        while not done:
            action, _ = expert.predict(obs)
            obs, reward, term, trunc, _ = env.step(action)
            observations.append(obs)
            actions.append(action)
            rewards.append(reward)
            states.append(env.get_state())
            done = term or trunc
        t = len(actions)
        if isinstance(observations[0], dict):
            stacked = {k: np.stack([o[k] for o in observations]) for k in observations[0]}
        else:
            stacked = np.stack(observations)
        episodes.append({"observations": stacked, "actions": np.stack(actions), "rewards": np.array(rewards),
                         "terminations": np.zeros(t, bool), "truncations": np.eye(1, t, t - 1, dtype=bool)[0],
                         "infos": {"state": {k: np.stack([s[k] for s in states]) for k in states[0]}}})
    return episodes


def evaluate(policy: Any, n: int = 20, seed: int = 10_000, obs_mode: str = "state", horizon: int = 30) -> float:
    """Mean final normalised performance of ``policy`` (None = uniform random) on eval variants."""
    env = ToyPickPlaceEnv(obs_mode=obs_mode, horizon=horizon)
    rng = np.random.default_rng(seed)
    scores = []
    for i in range(n):
        obs, info = env.reset(seed=seed + i, options={"split": "eval"})
        done = False
        while not done:
            if policy is None:
                action = rng.uniform(-1, 1, 3)
            else:
                action, _ = policy.predict(obs, deterministic=True)
            obs, _, term, trunc, info = env.step(action)
            done = term or trunc
        scores.append(info["normalized_performance"])
    return float(np.mean(scores))
