"""README examples run as written."""

import re
from pathlib import Path

import pytest

README = (Path(__file__).resolve().parent.parent / "README.md").read_text()


def _block(start: str) -> str:
    for code in re.findall(r"```python\n(.*?)```", README, re.S):
        if code.startswith(start):
            return code
    raise AssertionError(f"no README python block starting with {start!r}")


def test_quick_start_runs(capsys):
    exec(compile(_block("import gymnasium as gym\nfrom lfd_envs.experts"), "README-quick-start", "exec"), {})
    perf = float(re.search(r"normalized performance (-?[0-9.]+)", capsys.readouterr().out).group(1))
    assert perf > 0.8


def test_agents_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(_block("import gymnasium as gym\nfrom lfd_envs import datasets"), "README-agents", "exec"), {})
    assert (tmp_path / "dmfd_threeboxes.zip").exists()


def test_quick_start_is_short():
    assert len(_block("import gymnasium as gym\nfrom lfd_envs.experts").strip().splitlines()) <= 11


def test_video_example_records_an_mp4(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(_block("import gymnasium as gym  # records videos"), "README-video", "exec"), {})
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert videos and videos[0].stat().st_size > 1000
