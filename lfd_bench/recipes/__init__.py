"""Named, versioned training recipes: an agent's settings and its demonstrator's, in one file.

A recipe is what a benchmark cell needs besides the env — the learner's keyword arguments and
where its demonstrations come from — stored as ``lfd_bench/recipes/<agent>/<name>.json`` and
named ``"<agent>/<name>"``. Suites refer to it by name (``"agents": {"dmfd": {"recipe":
"dmfd/state-v1"}}``; other keys in that object override the recipe's, e.g. ``demo_episodes`` for
a task that needs more demonstrations), and a user loads it in one line::

    import gymnasium as gym
    from lfd_bench import recipes

    env = gym.make("lfd_envs:ClothFoldDiagonalUnpinned-v1", obs_mode="state", action_mode="delta")
    model = recipes.load("dmfd/state-v1").make(env, seed=0)  # demonstrations collected (and cached)
    model.learn(20_000)

A recipe file::

    {"name": "dmfd/state-v1", "version": 1, "agent": "dmfd",
     "description": "...",
     "agent_kwargs": {"learning_rate": 0.001, ...},
     "demonstrations": {"episodes": 50, "policy": "expert", "policy_kwargs": {"hold_speed": 0.5}}}

A change to what a recipe does gets a new name (``state-v2``), so results that name a recipe keep
meaning what they meant.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

__all__ = ["Recipe", "Demonstrations", "load", "available", "resolve", "RECIPES_DIR", "default_demo_cache"]

RECIPES_DIR = Path(__file__).resolve().parent


class Demonstrations(BaseModel):
    """Where a recipe's demonstrations come from (the harness collects and caches them)."""

    model_config = ConfigDict(extra="forbid")

    episodes: int = Field(ge=1, description="demonstration episodes per training run")
    policy: str = Field("expert", description="'expert' or 'noisy_expert'")
    policy_kwargs: dict[str, Any] = Field(default_factory=dict, description="the demonstrator's settings")


class Recipe(BaseModel):
    """One named recipe (module docstring)."""

    model_config = ConfigDict(extra="forbid")

    name: str
    version: int = Field(ge=1)
    agent: str = Field(description="a built-in harness agent (lfd_bench.agents.BUILTIN_AGENTS)")
    description: str
    agent_kwargs: dict[str, Any] = Field(default_factory=dict)
    demonstrations: Demonstrations | None = None

    def kwargs(self, **overrides: Any) -> dict[str, Any]:
        """The harness agent's keyword arguments: the recipe's, demonstrations included
        (``demo_episodes``, ``demo_policy``, ``demo_policy_kwargs``), then ``overrides``."""
        out = dict(self.agent_kwargs)
        if self.demonstrations is not None:
            out.update(demo_episodes=self.demonstrations.episodes, demo_policy=self.demonstrations.policy,
                       demo_policy_kwargs=dict(self.demonstrations.policy_kwargs))
        out.update(overrides)
        return out

    def make(self, env: Any, seed: int = 0, **overrides: Any) -> Any:
        """The agent of this recipe on ``env`` (made with ``gym.make``), ready to ``learn``.

        Demonstrations are collected with the recipe's demonstrator on ``env``'s id and settings
        and cached in ``demo_cache`` (default :func:`default_demo_cache`); ``overrides`` replace
        recipe settings.
        """
        from lfd_bench.agents import resolve_agent

        factory = resolve_agent(self.agent)
        kwargs = self.kwargs(**overrides)
        if getattr(factory, "uses_demo_cache", False):
            kwargs.setdefault("demo_cache", str(default_demo_cache()))
        return factory(env, seed, **kwargs)


def default_demo_cache() -> Path:
    """Where :meth:`Recipe.make` caches demonstrations: ``$LFD_CACHE/demos``, else
    ``$XDG_CACHE_HOME/lfd-suite/demos`` (``~/.cache/lfd-suite/demos``) — never the install folder."""
    if os.environ.get("LFD_CACHE"):
        return Path(os.environ["LFD_CACHE"]) / "demos"
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "lfd-suite" / "demos"


def available() -> list[str]:
    """Names of the recipes shipped with the suite."""
    return sorted(f"{p.parent.name}/{p.stem}" for p in RECIPES_DIR.glob("*/*.json"))


def load(name: str) -> Recipe:
    """The recipe named ``"<agent>/<name>"`` (or at a path to a ``.json`` file); ``ValueError``
    naming the valid recipes otherwise."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"recipe must be a name such as 'dmfd/state-v1', got {name!r}")
    path = Path(name) if name.endswith(".json") else RECIPES_DIR / f"{name}.json"
    if not path.is_file() or (not name.endswith(".json") and name not in available()):
        raise ValueError(f"unknown recipe {name!r}; valid recipes are {available()} or a path to a .json file")
    try:
        recipe = Recipe.model_validate(json.loads(path.read_text()))
    except (json.JSONDecodeError, ValidationError) as exc:
        raise ValueError(f"recipe {path} is not valid: {exc}") from exc
    if not name.endswith(".json") and recipe.name != name:
        raise ValueError(f"recipe file {path} names itself {recipe.name!r}, not {name!r}")
    return recipe


def resolve(agent: str, kwargs: dict[str, Any]) -> tuple[dict[str, Any], str | None]:
    """A suite's kwargs of ``agent`` with its ``"recipe"`` expanded (the recipe's settings, then
    the other keys over them) and the recipe's name (None without one). ``ValueError`` for an
    unknown recipe or one of another agent."""
    if "recipe" not in kwargs:
        return dict(kwargs), None
    rest = {k: v for k, v in kwargs.items() if k != "recipe"}
    recipe = load(kwargs["recipe"])
    if recipe.agent != agent:
        raise ValueError(f"recipe {recipe.name!r} is for agent {recipe.agent!r}, not {agent!r}")
    return recipe.kwargs(**rest), recipe.name
