"""The thesis-reproduction suites (repro-mopa, repro-mail, repro-nist) load, name their cuts and
reference numbers, and reference rows may hold success rates (a reported metric) besides p̂."""

from __future__ import annotations

import pytest

from lfd_bench import run as bench


@pytest.mark.parametrize("name", ["repro-mopa", "repro-mail", "repro-nist", "repro-cpu-v1", "repro-image"])
def test_repro_suites_load_with_notes_and_seeds(name):
    suite = bench.load_suite(name)
    assert "Cuts relative to the thesis" in suite["notes"] and suite["seeds"] == [0, 1, 2]
    cells = bench.expand_cells(suite)
    assert cells and all(c.budget > 0 and c.eval_episodes >= 20 for c in cells)
    labels = {c.env_id + (f" ({c.tags['label']})" if "label" in c.tags else "") for c in cells}
    for key, ref in suite.get("reference", {}).items():  # every reference row belongs to a cell it is shown beside
        assert key in labels | {c.env_id for c in cells}, key  # a cell label, or an env id (all its cells)
        assert set(ref["rows"]) <= {c.agent for c in cells if key.startswith(c.env_id)}


def test_repro_mopa_records_coverage_of_the_push2d_budget_up_to_the_thesis_span():
    cells = [c for c in bench.expand_cells(bench.load_suite("repro-mopa")) if c.env_id == "Push2DObstacle-v0"]
    assert {c.agent for c in cells} >= {"mopa_sac", "sac"}
    assert all(c.tags["coverage_steps"] == min(c.budget, 100_000) for c in cells)  # Fig. 3.6: first 100k


def test_reference_rows_accept_reported_metrics_only():
    suite = {"cells": [{"env": "Push2DObstacle-v0"}],
             "reference": {"Push2DObstacle-v0": {"source": "x", "rows": {"sac": {"is_success": 0.5, "mean": 0.1}}}}}
    bench.check_suite(suite)
    suite["reference"]["Push2DObstacle-v0"]["rows"]["sac"]["success_rate"] = 0.5
    with pytest.raises(ValueError, match="unknown keys"):
        bench.check_suite(suite)
