"""Agents the harness can run, by name or as a third-party ``package.module:factory``.

A factory is called as ``factory(env, seed, **kwargs)`` and returns any object with
``learn(total_timesteps)`` and ``predict(obs, deterministic=True) -> (action, state)``
(Stable-Baselines3's interface). Optional: ``reset()`` (called after every eval reset, for
scripted or recurrent agents) and ``needs_training = False`` (skip ``learn``).

A suite's agent kwargs are checked before training against the factory's named parameters; a
factory that takes ``**kwargs`` may set ``factory.kwargs_target`` to a function returning the class
or function they go to (``None``: it takes no others), so that those are checked too
(:func:`lfd_bench.suite_schema.accepted_kwargs`); without it any keyword is accepted.
"""

from __future__ import annotations

import importlib
import math
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
import numpy as np

AgentFactory = Callable[..., Any]
DEFAULT_RESULTS = Path("results")  #: default --out of lfd_bench.run, in the working directory


class RandomAgent:
    """Uniform random actions (agent ``random_uniform``; ``random`` outside pick-and-place)."""

    needs_training = False

    def __init__(self, env: gym.Env, seed: int = 0):
        self.action_space = env.action_space
        self.action_space.seed(seed)

    def learn(self, total_timesteps: int, **_: Any) -> "RandomAgent":
        return self

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.action_space.sample(), None


def uses_pick_place(env: gym.Env) -> bool:
    """Whether ``env`` is a particle task in pick-and-place mode (MAIL's action space)."""
    base = env.unwrapped
    return getattr(base, "action_mode", None) == "pick_place" and hasattr(base, "batch")


class PickPlaceRandomAgent:
    """MAIL's random agent for pick-and-place particle envs: every step picks a random particle
    (the task's own random pick, e.g. a cloth particle) and places it at a random point
    (:class:`lfd_envs.experts.random_pick_place.RandomPickPlacePolicy`). Uniform random
    pick-and-place actions mostly grasp air; this is the random row MAIL reports.

    The moves depend only on ``(seed, reset seed, variant)`` of each episode.
    """

    needs_training = False

    def __init__(self, env: gym.Env, seed: int = 0):
        if not uses_pick_place(env):
            raise ValueError(f"PickPlaceRandomAgent needs a particle env in pick_place mode, got {env}")
        self.seed = int(seed)
        self.bind(env)

    def bind(self, env: gym.Env) -> None:
        """Read the privileged particle state from ``env`` (the evaluation env)."""
        from lfd_envs.experts.random_pick_place import RandomPickPlacePolicy

        self._policy = RandomPickPlacePolicy(env, seed=self.seed)

    def reset(self) -> None:
        self._policy.reset()

    def learn(self, total_timesteps: int, **_: Any) -> "PickPlaceRandomAgent":
        return self

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self._policy.predict(obs)[0], None


def random_agent(env: gym.Env, seed: int = 0, **_: Any) -> RandomAgent | PickPlaceRandomAgent:
    """The ``random`` reference row: MAIL's random (:class:`PickPlaceRandomAgent`) in
    pick-and-place particle envs, uniform random actions (:class:`RandomAgent`) elsewhere."""
    return PickPlaceRandomAgent(env, seed) if uses_pick_place(env) else RandomAgent(env, seed)


class ZeroAgent:
    """The all-zero action ("do nothing": pickers stay, grasp flags off); the floor a learner must clear."""

    needs_training = False

    def __init__(self, env: gym.Env, seed: int = 0):
        space = env.action_space
        if not isinstance(space, gym.spaces.Box):
            raise TypeError(f"the zero agent needs a Box action space, got {space}")
        self._action = np.clip(np.zeros(space.shape, space.dtype), space.low, space.high)

    def learn(self, total_timesteps: int, **_: Any) -> "ZeroAgent":
        return self

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self._action.copy(), None


class ExpertAgent:
    """The task's scripted expert (:func:`lfd_envs.experts.make_expert`); the upper reference row."""

    needs_training = False

    def __init__(self, env: gym.Env, seed: int = 0, **kwargs: Any):
        from lfd_envs.experts import make_expert

        self._env = env
        self._kwargs = kwargs
        self._expert = make_expert(env, **kwargs)

    def bind(self, env: gym.Env) -> None:
        """Use ``env`` (the evaluation env) as the expert's privileged source of state."""
        from lfd_envs.experts import make_expert

        self._expert = make_expert(env, **self._kwargs)

    def reset(self) -> None:
        self._expert.reset()

    def learn(self, total_timesteps: int, **_: Any) -> "ExpertAgent":
        return self

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self._expert.predict(obs, deterministic=True)


def _policy_name(env: gym.Env) -> str:
    space = env.observation_space
    if isinstance(space, gym.spaces.Dict):
        return "MultiInputPolicy"
    if isinstance(space, gym.spaces.Box) and space.dtype == np.uint8 and len(space.shape) == 3:
        return "CnnPolicy"
    return "MlpPolicy"


def _image_extractor_kwargs(env: gym.Env) -> dict[str, Any]:
    """Policy kwargs giving SB3 the project's image encoders for image observations.

    SB3's ``NatureCNN`` needs images of at least 36×36 pixels; :class:`lfd_agents.ImageEncoder`
    (the encoder DMfD uses) works from 16×16, so SAC/TD3/PPO see images through the same
    network as the demonstration agents. Dict observations use ``KeySubsetExtractor`` (images
    through ``ImageEncoder``, vectors flattened). Empty for vector observations.
    """
    policy = _policy_name(env)
    if policy == "CnnPolicy":
        from lfd_agents.networks import ImageEncoder

        return {"features_extractor_class": ImageEncoder}
    if policy == "MultiInputPolicy":
        from lfd_agents.networks import KeySubsetExtractor

        return {"features_extractor_class": KeySubsetExtractor}
    return {}


def _sb3(algo_name: str) -> AgentFactory:
    def factory(env: gym.Env, seed: int = 0, reward_scale: float | None = None, **kwargs: Any):
        import stable_baselines3 as sb3

        algo = getattr(sb3, algo_name)
        if reward_scale is not None:  # SoftAgent/DMfD train every algorithm on scaled rewards
            scale = float(reward_scale)
            if not (math.isfinite(scale) and scale > 0):
                raise ValueError(f"reward_scale must be a finite number > 0, got {reward_scale!r}")
            env = gym.wrappers.TransformReward(env, lambda r: scale * r)
        kwargs.setdefault("verbose", 0)
        kwargs.setdefault("device", "cpu")
        if algo_name in ("SAC", "TD3"):
            kwargs.setdefault("learning_starts", 100)
            kwargs.setdefault("buffer_size", 100_000)
        kwargs["policy_kwargs"] = {**_image_extractor_kwargs(env), **dict(kwargs.get("policy_kwargs") or {})}
        return algo(_policy_name(env), env, seed=seed, **kwargs)

    factory.kwargs_target = lambda: getattr(importlib.import_module("stable_baselines3"), algo_name)
    factory.__doc__ = (f"Stable-Baselines3 {algo_name} with its default hyper-parameters "
                       "(image observations through lfd_agents.ImageEncoder; `reward_scale` multiplies "
                       "the training env's rewards).")
    return factory


def _lfd_agent(class_name: str, module: str = "lfd_agents") -> AgentFactory:
    def factory(env: gym.Env, seed: int = 0, **kwargs: Any):
        cls = getattr(importlib.import_module(module), class_name)
        if hasattr(cls, "for_benchmark"):
            return cls.for_benchmark(env, seed=seed, **kwargs)
        return cls(_policy_name(env), env, seed=seed, **kwargs)

    factory.kwargs_target = lambda: getattr(importlib.import_module(module), class_name)
    factory.__doc__ = f"{module}.{class_name}"
    return factory


def _named_factory(module: str, name: str) -> AgentFactory:
    def factory(env: gym.Env, seed: int = 0, **kwargs: Any):
        return getattr(importlib.import_module(module), name)(env, seed, **kwargs)

    factory.kwargs_target = lambda: getattr(importlib.import_module(module), name)
    factory.__doc__ = f"{module}.{name}"
    return factory


def _lfd_demo_agent(class_name: str) -> AgentFactory:
    def factory(env: gym.Env, seed: int = 0, demo_episodes: int = 20, demo_cache: str | Path | None = None,
                demo_policy: str = "expert", demo_policy_kwargs: dict[str, Any] | None = None,
                select_episodes: int = 0, select_first_variant: int = 400, **kwargs: Any):
        from lfd_bench.demo_cache import demonstrations_for
        from lfd_bench.recipes import default_demo_cache

        if int(select_episodes) < 0:
            raise ValueError(f"select_episodes must be >= 0 (0: no checkpoint selection), got {select_episodes!r}")
        cls = getattr(importlib.import_module("lfd_agents"), class_name)
        cache = Path(demo_cache) if demo_cache is not None else default_demo_cache()
        demos = demonstrations_for(env, int(demo_episodes), cache, policy=demo_policy,
                                   policy_kwargs=demo_policy_kwargs)
        kwargs.setdefault("device", "cpu")
        policy = _policy_name(env)
        from stable_baselines3.sac.policies import SACPolicy

        policy_cls = cls.policy_aliases.get(policy)
        if isinstance(policy_cls, type) and issubclass(policy_cls, SACPolicy):
            # an SB3 SAC policy (SAC-LfD's): give it the project's image encoder, as for plain SAC
            kwargs["policy_kwargs"] = {**_image_extractor_kwargs(env), **dict(kwargs.get("policy_kwargs") or {})}
        agent = cls(policy, env, demonstrations=str(demos.path), seed=seed, **kwargs)
        if int(select_episodes) > 0:  # act with the best checkpoint on validation variants
            from lfd_agents.selection import SelectBest

            agent = SelectBest(agent, env, int(select_episodes), int(select_first_variant), seed=seed)
        agent.demo_transitions = demos.transitions
        agent.demo_performance = demos.mean_final_performance
        return agent

    factory.__doc__ = (f"lfd_agents.{class_name} with `demo_episodes` demonstrations (cached) of `demo_policy` "
                       "(default the scripted expert; `noisy_expert` with `demo_policy_kwargs` {'epsilon': ...} "
                       "for lower-quality ones); `select_episodes` N > 0 scores the policy on N training variants "
                       "(from `select_first_variant`, default 400) after every training chunk and acts with the "
                       "best one (lfd_agents.selection.SelectBest; the validation steps count as env steps).")
    factory.uses_demo_cache = True  # the harness passes demo_cache=<out>/_demos
    factory.kwargs_target = lambda: getattr(importlib.import_module("lfd_agents"), class_name)
    return factory


#: built-in agents that are scripted references, not learners (no device, never "baselines")
REFERENCE_AGENTS = ("expert", "random", "random_uniform", "zero", "mail_dataset")

def _no_kwargs(factory: AgentFactory) -> AgentFactory:
    """Mark ``factory`` as taking no suite kwargs (it ignores any the harness passes)."""
    factory.kwargs_target = None
    return factory


BUILTIN_AGENTS: dict[str, AgentFactory] = {
    "random": _no_kwargs(random_agent),
    "random_uniform": _no_kwargs(lambda env, seed=0, **kw: RandomAgent(env, seed)),
    "zero": _no_kwargs(lambda env, seed=0, **kw: ZeroAgent(env, seed)),
    "expert": lambda env, seed=0, **kw: ExpertAgent(env, seed, **kw),
    "sac": _sb3("SAC"),
    "td3": _sb3("TD3"),
    "ppo": _sb3("PPO"),
    "dmfd": _lfd_demo_agent("DMfD"),
    "sac_lfd": _lfd_demo_agent("SACLfD"),
    "bc": _lfd_demo_agent("BC"),
    "awac": _lfd_demo_agent("AWAC"),
    "drq": _lfd_agent("DrQ"),
    "curl": _lfd_agent("CURL"),
    "mopa_sac": _lfd_agent("MoPASAC", "lfd_agents.mopa"),
    "mail": _lfd_agent("MAILAgent", "lfd_agents.mail"),
    "mail_dataset": _named_factory("lfd_bench.mail_dataset", "mail_dataset"),
    "nist_bc": _named_factory("lfd_agents.nist_bc", "nist_bc"),
    "nist_bc_h6": _named_factory("lfd_agents.nist_bc", "nist_bc_h6"),
    "nist_bc_1cam": _named_factory("lfd_agents.nist_bc", "nist_bc_1cam"),
}


def resolve_agent(spec: str) -> AgentFactory:
    """Factory for a built-in name or a ``package.module:factory`` spec (clear error otherwise)."""
    if spec in BUILTIN_AGENTS:
        return BUILTIN_AGENTS[spec]
    if ":" not in spec:
        raise ValueError(
            f"unknown agent {spec!r}; valid built-in agents are {sorted(BUILTIN_AGENTS)}, "
            "or give a third-party factory as 'package.module:factory'"
        )
    module_name, _, attr = spec.partition(":")
    if not module_name or not attr:
        raise ValueError(f"agent {spec!r} must be 'package.module:factory' with both parts, "
                         f"e.g. 'mypkg.agents:make_agent'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(f"cannot import module {module_name!r} of agent {spec!r}: {exc}") from exc
    factory = getattr(module, attr, None)
    if not callable(factory):
        public = sorted(n for n in dir(module) if not n.startswith("_") and callable(getattr(module, n)))
        raise ValueError(f"{module_name!r} has no callable {attr!r}; callables there: {public}")
    return factory
