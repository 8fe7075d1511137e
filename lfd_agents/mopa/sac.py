"""MoPA-SAC (and MoPA-TD3 for the ablation): SB3 off-policy agents for k-step MoPA actions.

A MoPA action (see :class:`~lfd_agents.mopa.wrapper.MoPAWrapper`) may run k low-level steps
and returns the discounted reward ``R = Σ_{i<k} γ^i r_i``. :class:`MoPAReplayBuffer` stores k
per transition and returns ``discounts = γ^k`` with every sample, which SB3's SAC/TD3 use in
the target ``y = s·R + (1 − done)·γ^k·(min Q'(o', a') − α log π(a'|o'))`` (s: reward scale).
For every planned path of more than 3 waypoints it also stores up to M sub-segments
(start < goal waypoints) as extra transitions, with the action that maps to the
sub-segment's displacement, its discounted reward and its own k (MoPA-RL's data reuse).

Per-task defaults (MoPA-RL's) live in :data:`MOPA_DEFAULTS`; :func:`make_mopa_env` wraps a task
with them and :func:`mopa_agent_kwargs` gives the matching agent arguments::

    env = make_mopa_env("Push2DObstacle-v0")
    model = MoPASAC("MlpPolicy", env, **mopa_agent_kwargs("Push2DObstacle-v0"))
    model.learn(10_000)

Limitations: Box observations only (no Dict/HER), data reuse needs ``n_envs == 1``, no
``VecNormalize`` (reuse transitions carry raw observations).
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import SAC, TD3
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.type_aliases import ReplayBufferSamples

from lfd_agents.mopa.wrapper import MoPAWrapper

__all__ = ["MoPASAC", "MoPATD3", "MoPAReplayBuffer", "MOPA_DEFAULTS", "MOPA_RL_SCHEDULE", "make_mopa_env",
           "mopa_agent_kwargs", "smdp_targets"]

#: Validity checks one OMPL search may run on Push2DObstacle (``max_checks``): above the 36k
#: that the hardest successful query of two fixed, seeded sets (330 queries) needed, so the
#: success rate is that of MoPA-RL's 1 s limit (``python tools/mopa_planner_queries.py``). 1 s
#: holds about 54k checks on a lightly loaded core and far fewer on a busy one; the budget
#: ends a search that cannot succeed (its goal in a pocket of free space cut off from the
#: start) after the same work on any machine.
PUSH2D_MAX_CHECKS = 40_000

#: Per-task MoPA settings (MoPA-RL scripts): ω, Δq_MP, M (reuse), reward scale, OMPL extension
#: range and time limit (the original Sawyer-Push script used 2 s), the invalid-target pull-back
#: step (MoPA-RL: 0.04 rad for the 2D pusher, 0.02 for Sawyer) and, where measured, a budget of
#: validity checks per OMPL search (``max_checks``) with the time limit as a safety cap.
MOPA_DEFAULTS: dict[str, dict[str, float]] = {
    "Push2DObstacle-v0": dict(omega=0.5, dq_mp=1.0, reuse=30, reward_scale=0.2, range=0.2, time_limit=10.0,
                              max_checks=PUSH2D_MAX_CHECKS, invalid_target_step=0.04),
    "SawyerPushObstacle-v0": dict(omega=0.7, dq_mp=0.5, reuse=15, reward_scale=0.8, range=0.1, time_limit=1.0),
    "SawyerLiftObstacle-v0": dict(omega=0.5, dq_mp=0.5, reuse=15, reward_scale=0.5, range=0.1, time_limit=1.0),
    "SawyerAssemblyObstacle-v0": dict(omega=0.7, dq_mp=0.5, reuse=15, reward_scale=1.0, range=0.1, time_limit=1.0),
}

_WRAPPER_KEYS = ("omega", "dq_mp", "range", "time_limit", "max_checks", "invalid_target_step")

#: MoPA-RL's learning schedule, the same on every task: ``warmup_stored`` uniformly random
#: actions until 10k transitions (reuse included) are stored, then one gradient step per stored
#: transition; timeouts stored as ``done``.
MOPA_RL_SCHEDULE: dict[str, Any] = dict(warmup_stored=10_000, update_per_stored=True, timeouts_as_done=True)


def _defaults(env_id: str) -> dict[str, float]:
    key = env_id.split(":")[-1]
    if key not in MOPA_DEFAULTS:
        raise KeyError(f"no MoPA defaults for {env_id!r}; known tasks: {sorted(MOPA_DEFAULTS)}")
    return dict(MOPA_DEFAULTS[key])


def make_mopa_env(env: str | gym.Env, **overrides: Any) -> MoPAWrapper:
    """``MoPAWrapper`` around ``env`` (an id or an instance) with the task's defaults.

    ``overrides`` go to :class:`MoPAWrapper` (e.g. ``rescale=False``, ``algorithm="rrt_star"``);
    ``env_kwargs`` (a dict) goes to ``gymnasium.make`` when ``env`` is an id.
    """
    env_kwargs = overrides.pop("env_kwargs", {})
    if isinstance(env, str):
        env_id, env = env, gym.make(env, **env_kwargs)
    else:
        env_id = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
    cfg = {k: v for k, v in _defaults(env_id).items() if k in _WRAPPER_KEYS}
    cfg.update(overrides)
    return MoPAWrapper(env, **cfg)


def mopa_agent_kwargs(env_id: str, **overrides: Any) -> dict[str, Any]:
    """``reward_scale`` and ``reuse`` (M) of a task for :class:`MoPASAC`/:class:`MoPATD3`, with
    :data:`MOPA_RL_SCHEDULE` (warm-up, updates, timeouts)."""
    cfg = _defaults(env_id)
    out = {"reward_scale": cfg["reward_scale"], "reuse": int(cfg["reuse"]), **MOPA_RL_SCHEDULE}
    out.update(overrides)
    return out


def smdp_targets(rewards: np.ndarray, dones: np.ndarray, steps: np.ndarray, next_values: np.ndarray,
                 gamma: float, reward_scale: float = 1.0) -> np.ndarray:
    """Reference k-step target ``s·R + (1 − done)·γ^k·V'`` (for checks and documentation)."""
    return reward_scale * np.asarray(rewards) + (1 - np.asarray(dones)) * gamma ** np.asarray(steps) * next_values


class MoPAReplayBuffer(ReplayBuffer):
    """Replay buffer with per-transition step counts k (discount γ^k) and MoPA data reuse.

    Extra args: ``gamma`` (must equal the agent's), ``reward_scale`` (multiplies stored
    rewards), ``reuse`` (M, sub-segments stored per planned path; 0 disables), ``seed``.
    Transitions whose ``info`` lacks ``mopa_k`` count as one step. With
    ``handle_timeout_termination=False`` a timeout is stored as ``done`` (MoPA-RL), also on the
    reused sub-segments that end where the episode timed out.
    """

    def __init__(self, buffer_size: int, observation_space: spaces.Space, action_space: spaces.Space,
                 device: th.device | str = "auto", n_envs: int = 1, optimize_memory_usage: bool = False,
                 handle_timeout_termination: bool = True, *, gamma: float = 0.99, reward_scale: float = 1.0,
                 reuse: int = 0, seed: int | None = None) -> None:
        if optimize_memory_usage:
            raise ValueError("MoPAReplayBuffer does not support optimize_memory_usage=True")
        if not isinstance(observation_space, spaces.Box):
            raise TypeError(f"MoPAReplayBuffer needs a Box observation space, got {observation_space}")
        if reuse and n_envs != 1:
            raise ValueError(f"data reuse (reuse={reuse}) needs n_envs == 1, got n_envs={n_envs}; pass reuse=0")
        super().__init__(buffer_size, observation_space, action_space, device, n_envs,
                         optimize_memory_usage, handle_timeout_termination)
        self.gamma = float(gamma)
        self.reward_scale = float(reward_scale)
        self.reuse = int(reuse)
        self.steps = np.ones((self.buffer_size, self.n_envs), dtype=np.float32)
        self.reused_added = 0
        self.stored = 0  # transitions ever written (reuse included), one per env and step
        self._rng = np.random.default_rng(seed)

    def add(self, obs: np.ndarray, next_obs: np.ndarray, action: np.ndarray, reward: np.ndarray,
            done: np.ndarray, infos: list[dict[str, Any]]) -> None:
        self.steps[self.pos] = [max(1, int(info.get("mopa_k", 1))) for info in infos]
        super().add(obs, next_obs, action, np.asarray(reward) * self.reward_scale, done, infos)
        self.stored += self.n_envs
        if self.reuse > 0:
            for info in infos:
                traj = info.get("mopa_trajectory")
                if traj is not None:
                    for t in self.reuse_transitions(traj):
                        self._add_one(*t)

    def _add_one(self, obs, next_obs, action, reward: float, done: bool, k: int) -> None:
        self.steps[self.pos] = k
        super().add(np.asarray(obs)[None], np.asarray(next_obs)[None], np.asarray(action)[None],
                    np.array([reward * self.reward_scale]), np.array([float(done)]), [{}])
        self.reused_added += 1
        self.stored += 1

    def reuse_transitions(self, traj: dict[str, Any]) -> list[tuple]:
        """Up to M transitions (obs, next_obs, action, reward, done, k) from sub-segments of a path.

        Waypoint pairs ``s < g`` (index 0 = start) are drawn without replacement; a pair is kept
        only if its displacement needs the planner (some joint beyond Δq_step) and maps to an
        action inside [-1, 1]. Reward: ``Σ_{i=s}^{g-1} γ^{i-s} r_i``; done only at the path end
        of a terminated episode (or, when timeouts are stored as done, of a timed-out one).
        """
        qpos, rewards, amap = traj["qpos"], np.asarray(traj["rewards"], dtype=np.float64), traj["action_map"]
        k = len(rewards)
        if k <= 3:
            return []
        s_idx, g_idx = np.triu_indices(k + 1, 1)
        picks = self._rng.choice(len(s_idx), size=min(self.reuse, k, len(s_idx)), replace=False)
        disc_cum = np.concatenate([[0.0], np.cumsum(self.gamma ** np.arange(k) * rewards)])
        extra = np.asarray(traj.get("extra_action", np.zeros(0)), dtype=np.float64)
        out = []
        for p in picks:
            s, g = int(s_idx[p]), int(g_idx[p])
            dq = qpos[g] - qpos[s]
            if amap.is_direct(dq):
                continue
            arm = amap.action(dq)
            if np.any(np.abs(arm) > 1.0):
                continue
            action = np.concatenate([arm, extra if g == k else np.zeros_like(extra)])
            reward = (disc_cum[g] - disc_cum[s]) / self.gamma ** s
            ended = bool(traj["terminated"]) or (not self.handle_timeout_termination and bool(traj.get("truncated")))
            done = ended and g == k
            out.append((traj["observations"][s], traj["observations"][g], action, reward, done, g - s))
        return out

    def _get_samples(self, batch_inds: np.ndarray, env=None) -> ReplayBufferSamples:
        env_indices = np.random.randint(0, high=self.n_envs, size=(len(batch_inds),))
        dones = self.dones[batch_inds, env_indices] * (1 - self.timeouts[batch_inds, env_indices])
        data = (
            self._normalize_obs(self.observations[batch_inds, env_indices, :], env),
            self.actions[batch_inds, env_indices, :],
            self._normalize_obs(self.next_observations[batch_inds, env_indices, :], env),
            dones.reshape(-1, 1),
            self._normalize_reward(self.rewards[batch_inds, env_indices].reshape(-1, 1), env),
            (self.gamma ** self.steps[batch_inds, env_indices]).reshape(-1, 1).astype(np.float32),
        )
        return ReplayBufferSamples(*tuple(map(self.to_torch, data)))


def _mopa_kwargs(kwargs: dict[str, Any], reward_scale: float, reuse: int, seed: int | None,
                 timeouts_as_done: bool) -> dict[str, Any]:
    """Route MoPA options into the replay-buffer arguments of an SB3 off-policy agent."""
    rb_class = kwargs.pop("replay_buffer_class", None) or MoPAReplayBuffer
    if not issubclass(rb_class, MoPAReplayBuffer):
        raise TypeError(f"replay_buffer_class must subclass MoPAReplayBuffer, got {rb_class.__name__}")
    rb_kwargs = dict(kwargs.pop("replay_buffer_kwargs", None) or {})
    rb_kwargs.setdefault("gamma", kwargs.get("gamma", 0.99))
    rb_kwargs.setdefault("reward_scale", reward_scale)
    rb_kwargs.setdefault("reuse", reuse)
    rb_kwargs.setdefault("seed", seed)
    rb_kwargs.setdefault("handle_timeout_termination", not timeouts_as_done)
    kwargs.update(replay_buffer_class=rb_class, replay_buffer_kwargs=rb_kwargs, seed=seed)
    return kwargs


def _sync_gamma(model) -> None:
    """Make the wrappers' multi-step reward discount equal the agent's γ."""
    if model.env is None:
        return
    try:
        model.env.env_method("set_gamma", model.gamma)
    except AttributeError:
        import warnings

        warnings.warn("no MoPAWrapper found in the env; transitions count as one step each", stacklevel=3)


class _MoPAAlgorithm:
    """What :class:`MoPASAC` and :class:`MoPATD3` add to their SB3 algorithm (listed second):
    the MoPA replay buffer and k-step discount (:func:`_mopa_kwargs`, :func:`_sync_gamma`) and
    the benchmark-harness adapter."""

    #: ``algo`` of :class:`~lfd_agents.mopa.agent.MoPAAgent` built by :meth:`for_benchmark`
    algo: ClassVar[str]

    def __init__(self, policy, env, *, reward_scale: float = 1.0, reuse: int = 15, seed: int | None = None,
                 update_per_stored: bool = False, warmup_stored: int = 0, timeouts_as_done: bool = False,
                 **kwargs: Any) -> None:
        if isinstance(warmup_stored, bool) or not isinstance(warmup_stored, (int, np.integer)) or warmup_stored < 0:
            raise ValueError(f"warmup_stored must be a non-negative integer, got {warmup_stored!r}")
        self.update_per_stored = bool(update_per_stored)
        self.warmup_stored = int(warmup_stored)
        self._stored_trained: int | None = None
        super().__init__(policy, env, **_mopa_kwargs(kwargs, reward_scale, reuse, seed, bool(timeouts_as_done)))
        _sync_gamma(self)

    def in_warmup(self) -> bool:
        """True while fewer than ``warmup_stored`` transitions (reuse included) are stored."""
        return self.replay_buffer is not None and self.replay_buffer.stored < self.warmup_stored

    def _sample_action(self, learning_starts: int, action_noise=None, n_envs: int = 1):
        """SB3's action choice; uniformly random while :meth:`in_warmup` (MoPA-RL's warm-up)."""
        if self.in_warmup():
            learning_starts = self.num_timesteps + 1
        return super()._sample_action(learning_starts, action_noise, n_envs)

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        """SB3's update (none while :meth:`in_warmup`); with ``update_per_stored`` one gradient
        step per transition stored since the previous call, reuse transitions included
        (MoPA-RL's schedule: a planned action with M reused sub-segments brings up to M + 1
        updates; warm-up transitions bring none)."""
        if self.in_warmup():
            return
        if self.update_per_stored:
            stored = self.replay_buffer.stored
            first = self._stored_trained is None or stored < self._stored_trained  # or a new buffer
            gradient_steps = 1 if first else stored - self._stored_trained
            self._stored_trained = stored
            if gradient_steps <= 0:
                return
        super().train(gradient_steps, batch_size)

    def set_env(self, env, force_reset: bool = True) -> None:
        super().set_env(env, force_reset)
        _sync_gamma(self)

    @classmethod
    def for_benchmark(cls, env: gym.Env, seed: int = 0, **kwargs: Any):
        """Harness adapter: :class:`~lfd_agents.mopa.agent.MoPAAgent` (budget in low-level steps)."""
        from lfd_agents.mopa.agent import MoPAAgent

        return MoPAAgent(env, seed=seed, algo=cls.algo, **kwargs)


class MoPASAC(_MoPAAlgorithm, SAC):
    """SAC on a :class:`MoPAWrapper` env with k-step targets and data reuse.

    Args (besides SB3 ``SAC``'s):
        reward_scale: multiplies rewards in the target (2D 0.2, Push 0.8, Lift 0.5, Assembly 1.0).
        reuse: M, sub-segments of each planned path stored as extra transitions (0: ablation).
        update_per_stored: one gradient step per stored transition, reuse included (MoPA-RL);
            default False: SB3's ``gradient_steps`` per decision of the policy.
        warmup_stored: uniformly random actions, and no updates, until this many transitions
            (reuse included) are stored (MoPA-RL: 10k); SB3's ``learning_starts`` (in
            decisions) applies as well. Default 0.
        timeouts_as_done: store a timeout as ``done`` (MoPA-RL: no bootstrapping at the
            horizon); default False: SB3's ``handle_timeout_termination``.

    :func:`mopa_agent_kwargs` gives MoPA-RL's values of all of these (``MOPA_RL_SCHEDULE``).
    """

    algo = "sac"


class MoPATD3(_MoPAAlgorithm, TD3):
    """TD3 counterpart of :class:`MoPASAC` (ablation "TD3 instead of SAC")."""

    algo = "td3"
