"""Packaging and tool integration: distribution name, the video extra, Minari's datasets folder."""

import importlib.metadata as md
import re
import tomllib
from pathlib import Path

import gymnasium as gym
import pytest

import lfd_envs  # noqa: F401
from lfd_envs import datasets

PYPROJECT = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())


def test_distribution_is_not_named_lfd():
    assert PYPROJECT["project"]["name"] == "lfd-suite"  # "lfd" on PyPI is an unrelated project
    assert md.version("lfd-suite") == PYPROJECT["project"]["version"]
    from lfd_bench.cell import environment_info

    assert environment_info()["versions"]["lfd-suite"] == PYPROJECT["project"]["version"]


def test_pytest_has_a_global_timeout_and_keeps_meaningful_warnings(request):
    assert 60 <= float(request.config.getini("timeout")) <= 900  # pytest-timeout: a hung test fails
    ignored = " ".join(request.config.getini("filterwarnings"))
    assert "out of date" in ignored  # the -v0 ids are deliberate (see the README)
    assert "always" not in ignored and "ignore::" not in ignored  # no blanket silencing


def test_video_extra_keeps_pillow_and_records_mp4(tmp_path):
    (spec,) = PYPROJECT["project"]["optional-dependencies"]["video"]
    assert re.fullmatch(r"moviepy>=1\.0\.3,<2", spec)  # moviepy 2 caps pillow below 12
    import moviepy  # noqa: F401  (installed by the test extra)
    env = gym.make("ThreeBoxes-v0", obs_mode="state", render_mode="rgb_array", render_size=48)
    env = gym.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda e: True)
    env.reset(seed=0)
    done = False
    while not done:
        *_, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_collect_cli_writes_where_minari_looks(tmp_path, monkeypatch, capsys):
    import minari

    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.delenv("MINARI_DATASETS_PATH", raising=False)
    assert datasets.main(["collect", "--env", "ThreeBoxes-v0", "--episodes", "1"]) == 0
    assert "minari list local" in capsys.readouterr().out
    assert "lfd/ThreeBoxes/expert-v0" in minari.list_local_datasets()
    assert minari.load_dataset("lfd/ThreeBoxes/expert-v0").total_episodes == 1
    assert (tmp_path / ".minari" / "datasets" / "lfd" / "ThreeBoxes" / "expert-v0").is_dir()


def test_collect_cli_with_out_tells_how_minari_finds_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    out = tmp_path / "demos"
    datasets.main(["collect", "--env", "ThreeBoxes-v0", "--episodes", "1", "--out", str(out)])
    assert f"export MINARI_DATASETS_PATH={out.resolve()}" in capsys.readouterr().out


def test_harness_is_the_installed_lfd_bench_package_with_a_console_script():
    """The harness installs as ``lfd_bench`` with an ``lfd-bench`` script; benchmarks/ and tools/
    (speed tables, diagnostics) stay in the checkout."""
    assert PYPROJECT["project"]["scripts"]["lfd-bench"] == "lfd_bench.run:main"
    assert PYPROJECT["tool"]["setuptools"]["packages"]["find"]["include"] == ["lfd_envs*", "lfd_agents*", "lfd_bench*"]
    (script,) = [e for e in md.entry_points(group="console_scripts") if e.name == "lfd-bench"]
    from lfd_bench import run

    assert script.load() is run.main
    import tools

    for line in tools.__doc__.splitlines():  # every diagnostic says which question it answers
        if line.startswith("- "):
            assert line.rstrip().endswith(("?", ".")), line


def test_harness_writes_results_and_leaderboard_to_the_working_directory(tmp_path, monkeypatch):
    """Defaults are relative to where the user runs the command, never the install folder."""
    from lfd_bench import run

    monkeypatch.chdir(tmp_path)
    args = run.parse_args(["--suite", "smoke"])
    assert Path(args.out).resolve() == tmp_path / "results"
    assert Path(args.leaderboard).resolve() == tmp_path / "leaderboard.md"
