"""The schema of a benchmark suite (``lfd_bench/configs/*.json``), checked before anything trains.

A suite is a JSON object; :data:`SUITE_SCHEMA` (JSON Schema, checked with ``jsonschema``) lists
every key it may have, at the top level and in each cell, with its type and range. An unknown
key (a typo such as ``"budgte"`` or a cell's ``"agent"`` for ``"agents"``) is refused, naming the
key and the file. Two checks go beyond the schema:

* :func:`check_agent_kwargs`: each agent's kwargs against what its factory accepts (its own
  parameters and those of the class it builds, where that can be read from the signatures;
  a third-party factory that takes ``**kwargs`` accepts anything);
* :func:`check_env_kwargs`: the env is made once with the cell's ``env_kwargs``, so a bad value
  is reported now rather than when the cell runs.
"""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jsonschema

__all__ = ["SUITE_SCHEMA", "validate_suite", "check_agent_kwargs", "check_env_kwargs", "accepted_kwargs"]


def _int(low: int, what: str) -> dict[str, Any]:
    return {"type": "integer", "minimum": low, "message": f"must be an integer >= {low} ({what})"}


#: settings a cell may override (the suite's value is the default)
_SETTINGS: dict[str, Any] = {
    "budget": _int(1, "training env steps"),
    "seeds": {"type": "array", "minItems": 1, "uniqueItems": True,
              "items": {"type": "integer", "minimum": 0, "message": "must be a non-negative integer"},
              "message": "must be a non-empty list of distinct non-negative integers, e.g. [0, 1, 2]"},
    "eval_episodes": _int(1, "evaluation episodes per cell"),
    "curve_points": _int(1, "learning-curve points"),
    "cpus": _int(1, "CPU cores a cluster scheduler gives the cell"),
    "deterministic": {"type": "boolean", "message": "must be true or false"},
    "checkpoint_steps": {"type": ["integer", "null"], "minimum": 1,
                         "message": "must be an integer >= 1 (env steps between checkpoints) or null"},
    "notes": {"type": "string", "message": "must be a string"},
}

_AGENTS = {"type": "object", "message": "must map agent names to their kwargs, e.g. {\"sac\": {}}",
           "additionalProperties": {"type": "object", "message": "must be an object of keyword arguments"}}

_CELL = {
    "type": "object",
    "message": "must be an object with an 'env'",
    "required": ["env"],
    "additionalProperties": False,
    "properties": {
        "env": {"type": "string", "minLength": 1, "message": "must be an env id such as \"ClothFold-v0\""},
        "env_kwargs": {"type": "object", "message": "must be an object of env constructor arguments"},
        "agents": _AGENTS,
        "label": {"type": "string", "message": "must be a string"},
        "coverage_steps": _int(1, "env steps whose states the coverage picture records"),
        "headline": {"type": "boolean", "message": "must be true or false (a cell of the suite's headline table)"},
        **_SETTINGS,
    },
}

#: JSON Schema of a suite file
SUITE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "message": "must be a JSON object with a list 'cells'",
    "required": ["cells"],
    "additionalProperties": False,
    "properties": {
        "name": {"type": "string", "minLength": 1, "message": "must be a non-empty string"},
        "description": {"type": "string", "message": "must be a string"},
        "budget_cut": {"type": "string", "message": "must be a string (one sentence: the budget against the thesis's)"},
        "headline_metric": {"enum": ["normalized_performance", "is_success"],
                            "message": "must be \"normalized_performance\" (p̂) or \"is_success\" (success rate)"},
        "cells": {"type": "array", "minItems": 1, "items": _CELL, "message": "must be a non-empty list of cells"},
        "reference": {"type": "object", "message": "must map env ids to {source, rows}",
                      "additionalProperties": {"type": "object", "message": "must be {source, rows}"}},
        **_SETTINGS,
    },
}

_VALIDATOR = jsonschema.Draft202012Validator(SUITE_SCHEMA)


def _where(parts: Any) -> str:
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "the top level"


def _describe(error: jsonschema.ValidationError) -> str:
    where = _where(error.absolute_path)
    if error.validator == "additionalProperties" and "properties" in error.schema:
        valid = sorted(error.schema["properties"])
        unknown = sorted(set(error.instance) - set(valid))
        hints = [f"{key!r} (did you mean {close[0]!r}?)" if close else repr(key)
                 for key in unknown for close in [difflib.get_close_matches(key, valid, n=1)]]
        return f"unknown key(s) {', '.join(hints)} in {where}; valid keys there: {valid}"
    if error.validator == "required":
        return f"{where} needs {error.message.split(' is a required')[0]}"
    message = error.schema.get("message")
    if message is None:
        return f"{where}: {error.message}"
    return f"{where} {message}, got {error.instance!r}"


def validate_suite(suite: Any, path: Path | str = "suite") -> None:
    """``ValueError`` naming ``path`` and every offending key unless ``suite`` fits :data:`SUITE_SCHEMA`."""
    errors = sorted(_VALIDATOR.iter_errors(suite), key=lambda e: (list(map(str, e.absolute_path)), e.validator))
    if errors:
        raise ValueError(f"{path}: " + "; ".join(dict.fromkeys(_describe(e) for e in errors)))


# ---------------------------------------------------------------------- agent kwargs
#: parameters a factory fills itself (never suite kwargs)
_SUPPLIED = {"self", "env", "seed", "policy", "demonstrations", "demo_cache"}


def _named_parameters(fn: Callable[..., Any]) -> tuple[set[str], bool]:
    """Keyword-passable parameter names of ``fn`` and whether it takes ``**kwargs``."""
    params = inspect.signature(fn).parameters.values()
    names = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    return names, any(p.kind == p.VAR_KEYWORD for p in params)


def _class_kwargs(cls: type) -> set[str] | None:
    """Constructor keywords of ``cls``, following ``**kwargs`` up its base classes; None where
    they end in ``object`` (a ``**kwargs`` that goes elsewhere)."""
    names: set[str] = set()
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        if klass is object:
            return None
        own, forwards = _named_parameters(vars(klass)["__init__"])
        names |= own
        if not forwards:
            return names
    return None


def accepted_kwargs(factory: Callable[..., Any]) -> set[str] | None:
    """Suite kwargs ``factory`` accepts, or None where that cannot be read from signatures.

    A factory's own parameters count; if it also takes ``**kwargs``, its ``kwargs_target``
    attribute (a function returning the class or function they go to; ``None``: it takes no
    others) says where they go; without that attribute anything is accepted.
    """
    names, forwards = _named_parameters(factory)
    if forwards:
        if not hasattr(factory, "kwargs_target"):
            return None
        target = factory.kwargs_target() if factory.kwargs_target is not None else None
        if target is not None:
            more = _class_kwargs(target) if isinstance(target, type) else _function_kwargs(target)
            if more is None:
                return None
            names |= more
    return {n for n in names if not n.startswith("_")} - _SUPPLIED


def _function_kwargs(fn: Callable[..., Any]) -> set[str] | None:
    names, forwards = _named_parameters(fn)
    return None if forwards else names


def check_agent_kwargs(suite: dict[str, Any], path: Path | str = "suite") -> None:
    """``ValueError`` naming the file, cell, agent and keys for an unknown agent or an agent
    kwarg its factory does not take (where the factory's signature tells)."""
    from lfd_bench import recipes
    from lfd_bench.agents import resolve_agent

    for i, spec in enumerate(suite["cells"]):
        for name, kwargs in spec.get("agents", {}).items():
            try:
                factory = resolve_agent(name)
                kwargs, _ = recipes.resolve(name, kwargs)
            except ValueError as exc:
                raise ValueError(f"{path}: cells[{i}].agents: {exc}") from None
            valid = accepted_kwargs(factory)
            unknown = sorted(set(kwargs) - valid) if valid is not None else []
            if unknown:
                raise ValueError(f"{path}: cells[{i}].agents.{name}: unknown keyword(s) {unknown} for agent "
                                 f"{name!r}; it takes {sorted(valid)}")


def check_env_kwargs(env_id: str, env_kwargs: dict[str, Any], where: str) -> None:
    """Make ``env_id`` once with ``env_kwargs``; ``ValueError`` naming ``where`` if that fails."""
    import gymnasium as gym

    try:
        env = gym.make(env_id, **env_kwargs)
    except (TypeError, ValueError, gym.error.Error) as exc:
        raise ValueError(f"{where}: env {env_id!r} cannot be made with env_kwargs {env_kwargs}: {exc}") from None
    env.close()
