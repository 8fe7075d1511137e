"""tools.offline_probe: each variant trains its own offline phase with its overrides."""

import json

from tools import offline_probe, online_probe

SUITE = {"name": "probe", "cells": [
    {"env": "ClothFoldDiagonalPinned-v0", "label": "pp",
     "env_kwargs": {"action_mode": "pick_place", "obs_mode": "state", "resolution": 12},
     "agents": {"dmfd": {"demo_episodes": 3, "offline_steps": 30, "demo_ratio": 0.5, "batch_size": 16,
                         "select_episodes": 2, "policy_kwargs": {"net_arch": [16, 16]}},
                "bc": {"demo_episodes": 3, "n_epochs": 2}}}]}


def test_each_variant_runs_its_own_offline_phase(tmp_path):
    cell = online_probe.find_cell(SUITE, "ClothFoldDiagonalPinned-v0", "dmfd")
    records = offline_probe.probe_offline(cell, {"base": {}, "short": {"offline_steps": 5}}, eval_episodes=2,
                                          demo_cache=tmp_path / "demos")
    assert [r["variant"] for r in records] == ["base", "short"]
    assert [r["updates"] for r in records] == [30, 5]  # the override took effect, nothing ran online
    assert all(0.0 <= r["held_rate"] <= 1.0 and r["train_s"] >= 0 for r in records)
    assert list((tmp_path / "demos").iterdir()), "the demonstrations were not cached where asked"


def test_an_offline_learner_is_scored_after_its_whole_training(tmp_path):
    cell = online_probe.find_cell(SUITE, "ClothFoldDiagonalPinned-v0", "bc")
    (record,) = offline_probe.probe_offline(cell, {"base": {}}, agent_name="bc", eval_episodes=1,
                                            demo_cache=tmp_path / "demos")
    assert record["updates"] > 0


def test_bad_variants_are_refused(tmp_path, capsys):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(SUITE))
    assert offline_probe.main(["--suite", str(path), "--env", "ClothFoldDiagonalPinned-v0",
                               "--variant", "x", "[1]"]) == 2
    assert "must be an object" in capsys.readouterr().err
