"""``python -m benchmarks.speed``: the ``-v1`` against ``-v0`` rows, progress lines, argument checks."""

import pytest

from benchmarks import speed


def test_version_rows_time_both_versions_on_the_same_actions(capsys):
    row, = speed.version_rows(rounds=1, configs=(("StraightenRope", "delta", 2),))
    assert (row["env"], row["action_mode"], row["pickers"]) == ("StraightenRope", "delta", 2)
    assert row["v0_frames"] == row["v1_frames"] == 8.0
    v0, v1 = row["v0_cpu_env_steps_per_s"], row["v1_cpu_env_steps_per_s"]
    assert v0 > 0 and v1 > 0
    assert row["v1_vs_v0"] == pytest.approx(v1 / v0, rel=0.01)  # one round: the ratio of its two rates
    assert "versions: StraightenRope delta 2 picker(s), round 1/1" in capsys.readouterr().err


def test_unknown_section_is_refused_before_anything_runs(capsys):
    with pytest.raises(SystemExit):
        speed.main(["--sections", "versions,nope"])
    out = capsys.readouterr()
    assert "unknown section 'nope'" in out.err
    assert "## versions" not in out.out
