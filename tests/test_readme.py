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


def test_every_python_block_that_uses_gym_imports_it():
    for code in re.findall(r"```python\n(.*?)```", README, re.S):
        if re.search(r"\bgym\.", code):
            assert "import gymnasium as gym" in code, code


def test_batched_worlds_example_runs():
    exec(compile(_block("import gymnasium as gym\nvenv = gym.make_vec"), "README-batched", "exec"), {})


def test_vectorisation_and_spec_notes_hold():
    """What the README says about MuJoCo ids and ``vector_entry_point``, and about ``gym.spec``."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401

    assert gym.spec("Push2DObstacle-v0").vector_entry_point is None
    with pytest.raises(gym.error.Error, match="MatchHorizon"):
        gym.make_vec("Push2DObstacle-v0", num_envs=2, vectorization_mode="vector_entry_point")
    venv = gym.make_vec("Push2DObstacle-v0", num_envs=2, vectorization_mode="sync")
    assert venv.reset(seed=0)[0].shape[0] == 2
    venv.close()
    with pytest.raises(gym.error.NameNotFound):
        gym.spec("lfd_envs:Push2DObstacle-v0")
    with pytest.warns(DeprecationWarning, match="is out of date"):
        gym.make("ClothFold-v0", resolution=8)
    flat = " ".join(README.split())
    assert "is out of date" in flat and "is not deprecated" in flat


def test_her_on_sawyer_needs_infos_as_the_readme_says():
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401

    assert '"copy_info_dict": True' in README
    env = gym.make("SawyerLiftObstacle-v0", goal_conditioned=True).unwrapped
    obs, info = env.reset(seed=0)
    with pytest.raises(ValueError, match="copy_info_dict"):
        env.compute_reward(obs["achieved_goal"][None], obs["desired_goal"][None], np.array([{}]))
    assert np.isfinite(env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info))
