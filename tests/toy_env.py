"""A tiny LfdEnv used by the core tests (a point that must reach a goal in 2D)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lfd_envs.core import LfdEnv


class PointReachEnv(LfdEnv):
    """Point mass in [-1,1]^2; goal from the variant; performance = -distance to goal."""

    task_name = "PointReach"

    def __init__(self, obs_mode: str = "state", image_size: int = 8, render_mode: str | None = None,
                 horizon: int = 20, step_size: float = 0.1):
        self._init_contract(obs_mode=obs_mode, image_size=image_size, render_mode=render_mode, horizon=horizon)
        self.step_size = step_size
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.state_space = spaces.Box(-np.inf, np.inf, (4,), np.float32)
        self._pos = np.zeros(2)
        self._goal = np.zeros(2)
        self._finish_init()

    def _setup_variant(self, rng):
        self._goal = rng.uniform(-0.8, 0.8, 2)
        self._pos = rng.uniform(-0.8, 0.8, 2)

    def _apply_action(self, action):
        self._pos = np.clip(self._pos + self.step_size * action, -1, 1)

    def _state_obs(self):
        return np.concatenate([self._pos, self._goal]).astype(np.float32)

    def _render(self, h, w):
        img = np.zeros((h, w, 3), np.uint8)
        for p, c in ((self._pos, (255, 0, 0)), (self._goal, (0, 255, 0))):
            i, j = int((p[1] + 1) / 2 * (h - 1)), int((p[0] + 1) / 2 * (w - 1))
            img[i, j] = c
        return img

    def _performance(self):
        return -float(np.linalg.norm(self._pos - self._goal))

    def _is_success(self):
        return bool(np.linalg.norm(self._pos - self._goal) < 0.05)

    def _get_sim_state(self):
        return {"pos": self._pos.copy(), "goal": self._goal.copy()}

    def _set_sim_state(self, state):
        self._pos = np.array(state["pos"], dtype=np.float64)
        self._goal = np.array(state["goal"], dtype=np.float64)


class PointReachExpert:
    def __init__(self, env):
        self.env = env

    def reset(self):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        base = self.env.unwrapped
        d = (base._goal - base._pos) / base.step_size
        return np.clip(d, -1, 1).astype(np.float32), None


TOY_ID = "lfd_test/PointReach-v0"
if TOY_ID not in gym.registry:
    gym.register(TOY_ID, entry_point="toy_env:PointReachEnv", disable_env_checker=True)
