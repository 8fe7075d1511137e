"""Stable-Baselines3 ``VecEnv`` view of a natively batched Gymnasium ``VectorEnv``.

SB3 does not accept ``gymnasium.vector.VectorEnv``: it wants its own ``VecEnv`` that resets
finished sub-envs in the same step and reports the last observation in
``info["terminal_observation"]``. Our batched envs use Gymnasium's ``SAME_STEP`` autoreset
mode (final observation in ``info["final_obs"]``), which maps onto SB3 one to one.

Example::

    import gymnasium as gym
    from lfd_envs.core.sb3_vec import SB3VecEnv
    venv = SB3VecEnv(gym.make_vec("lfd_envs:ClothFold-v0", num_envs=4,
                                  vectorization_mode="vector_entry_point", obs_mode="state"))
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv


def _index_obs(obs: Any, i: int) -> Any:
    if isinstance(obs, dict):
        return {k: v[i] for k, v in obs.items()}
    return obs[i]


class SB3VecEnv(VecEnv):
    """Wraps a batched ``gymnasium.vector.VectorEnv`` (SAME_STEP autoreset) for SB3.

    Args:
        venv: the batched env, e.g. from ``gym.make_vec(..., vectorization_mode="vector_entry_point")``.
        seed: optional seed for the first reset.
    """

    def __init__(self, venv: gym.vector.VectorEnv, seed: int | None = None):
        mode = venv.metadata.get("autoreset_mode")
        if mode is not None and getattr(mode, "name", str(mode)) not in ("SAME_STEP", "AutoresetMode.SAME_STEP"):
            raise ValueError(f"SB3VecEnv needs a VectorEnv with SAME_STEP autoreset, got {mode}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._seed = seed
        self.render_mode = getattr(venv, "render_mode", None)

    def reset(self):
        obs, infos = self.venv.reset(seed=self._seed)
        self._seed = None
        self.reset_infos = [self._info_at(infos, i) for i in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = np.logical_or(terminated, truncated)
        out_infos = []
        for i in range(self.num_envs):
            info = self._info_at(infos, i)
            if dones[i]:
                final_obs = infos.get("final_obs")
                if final_obs is not None:
                    info["terminal_observation"] = final_obs[i]
                final_info = infos.get("final_info")
                if isinstance(final_info, dict):
                    info.update(self._info_at(final_info, i))
                info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            out_infos.append(info)
        return obs, np.asarray(rewards, dtype=np.float32), dones, out_infos

    @staticmethod
    def _info_at(infos: dict[str, Any], i: int) -> dict[str, Any]:
        out = {}
        for key, value in infos.items():
            if key.startswith("_") or key in ("final_obs", "final_info"):
                continue
            mask = infos.get(f"_{key}")
            if mask is not None and not mask[i]:
                continue
            out[key] = _index_obs(value, i) if isinstance(value, dict) else value[i]
        return out

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        frames = self.venv.render()
        return list(frames) if frames is not None else [None] * self.num_envs

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def seed(self, seed: int | None = None):
        self._seed = seed
        return [seed for _ in range(self.num_envs)]
