"""Recipes: named settings files that suites refer to and users load in one line."""

import json

import gymnasium as gym
import pytest

from lfd_bench import recipes
from lfd_bench import run as bench
from test_readme import _block


def test_every_shipped_recipe_loads_and_names_a_known_agent():
    from lfd_bench.agents import BUILTIN_AGENTS

    names = recipes.available()
    assert "dmfd/state-v0" in names and "sac/state" in names
    for name in names:
        recipe = recipes.load(name)
        assert recipe.name == name and recipe.agent == name.split("/")[0] and recipe.agent in BUILTIN_AGENTS
        assert recipe.description.strip()


def test_unknown_or_malformed_recipes_are_clear_errors(tmp_path):
    with pytest.raises(ValueError, match=r"unknown recipe 'dmfd/nope'.*dmfd/state-v0"):
        recipes.load("dmfd/nope")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"name": "x/y", "version": 1, "agent": "dmfd", "description": "d", "agent_kwarg": {}}))
    with pytest.raises(ValueError, match="agent_kwarg"):
        recipes.load(str(bad))
    with pytest.raises(ValueError, match="is for agent 'dmfd', not 'bc'"):
        recipes.resolve("bc", {"recipe": "dmfd/state-v0"})


def test_a_suite_cell_takes_the_recipe_and_its_overrides(tmp_path):
    suite = {"name": "r", "seeds": [0], "budget": 10, "cells": [
        {"env": "ThreeBoxes-v0", "env_kwargs": {"num_pickers": 1, "action_mode": "pick_place", "obs_mode": "state"},
         "agents": {"dmfd": {"recipe": "dmfd/state-v0", "demo_episodes": 7}}}]}
    path = tmp_path / "r.json"
    path.write_text(json.dumps(suite))
    (cell,) = bench.expand_cells(bench.load_suite(str(path)))
    recipe = recipes.load("dmfd/state-v0")
    assert cell.tags["recipe"] == "dmfd/state-v0"
    assert cell.agent_kwargs == {**recipe.kwargs(), "demo_episodes": 7}
    suite["cells"][0]["agents"] = {"bc": {"recipe": "dmfd/state-v0"}}
    path.write_text(json.dumps(suite))
    with pytest.raises(ValueError, match=r"r\.json.*cells\[0\]\.agents.*is for agent 'dmfd'"):
        bench.load_suite(str(path))


def test_readme_recipe_example_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("LFD_CACHE", str(tmp_path))  # demonstrations cached here, not in the home folder
    exec(compile(_block("import gymnasium as gym\nfrom lfd_bench import recipes"), "README-recipes", "exec"), {})
    out = capsys.readouterr().out
    assert "dmfd/state-v0" in out and "0.5 10000" in out
    assert list((tmp_path / "demos").rglob("*.hdf5"))  # the recipe's demonstrations were collected there
