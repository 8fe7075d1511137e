"""Minari demonstration datasets: write, load, restore states, replay."""

import re

import numpy as np
import pytest

from lfd_envs import datasets
import gymnasium as gym
from toy_env import TOY_ID, PointReachExpert


def test_collect_load_replay_round_trip(tmp_path):
    path = datasets.collect(TOY_ID, 3, tmp_path, policy=PointReachExpert, seed=10, progress=False)
    ds = datasets.load(path)
    assert ds.total_episodes == 3
    env = datasets.make_env(ds)
    for ep in ds.iterate_episodes():
        finals = datasets.replay(env, ep)
        assert finals[-1] == pytest.approx(float(ep.infos["normalized_performance"][-1]))
        states = datasets.episode_states(ep, env)
        assert len(states) == len(ep.actions) + 1
        env.unwrapped.set_state(states[2])
        assert np.allclose(env.unwrapped.current_observation(), ep.observations[2])
    assert np.mean([ep.infos["normalized_performance"][-1] for ep in ds.iterate_episodes()]) > 0.9


def test_cli_and_bad_policy(tmp_path, capsys):
    assert datasets.main(["collect", "--env", TOY_ID, "--episodes", "2", "--out", str(tmp_path), "--policy", "random"]) == 0
    assert "2 episodes" in capsys.readouterr().out
    with pytest.raises(ValueError, match="unknown policy"):
        datasets.collect(TOY_ID, 1, tmp_path, policy="oracle")
    with pytest.raises(FileNotFoundError):
        datasets.load(tmp_path / "nothing")


def test_existing_dataset_is_kept_unless_overwrite(tmp_path):
    path = datasets.collect(TOY_ID, 1, tmp_path, policy="random", progress=False, name="dup")
    stamp = (path / "data" / "main_data.hdf5").stat().st_mtime_ns
    with pytest.raises(FileExistsError, match="overwrite"):
        datasets.collect(TOY_ID, 2, tmp_path, policy="random", progress=False, name="dup")
    assert (path / "data" / "main_data.hdf5").stat().st_mtime_ns == stamp
    again = datasets.collect(TOY_ID, 2, tmp_path, policy="random", progress=False, name="dup", overwrite=True)
    assert again == path and datasets.load(again).total_episodes == 2


@pytest.mark.parametrize("name", ["dup", "dup-v0", "lfd/lfd_test/PointReach/dup-v0"])
def test_dataset_name_is_normalised(name):
    assert datasets.dataset_id(TOY_ID, name) == "lfd/lfd_test/PointReach/dup-v0"
    assert datasets.dataset_id("ThreeBoxes-v0", name.replace("lfd_test/PointReach", "ThreeBoxes")) == \
        "lfd/ThreeBoxes/dup-v0"


@pytest.mark.parametrize("name", ["", "lfd/ThreeBoxes/dup-v0", "a/b", "dup-v1", "sp ace"])
def test_bad_dataset_names_are_refused(name):
    with pytest.raises(ValueError, match="name"):
        datasets.dataset_id(TOY_ID, name)


def test_cli_reports_errors_in_one_line(tmp_path, capsys):
    args = ["collect", "--env", TOY_ID, "--policy", "random", "--out", str(tmp_path)]
    assert datasets.main(args + ["--episodes", "1", "--name", "lfd/lfd_test/PointReach/dup-v0"]) == 0
    assert (tmp_path / "lfd" / "lfd_test" / "PointReach" / "dup-v0").is_dir()
    capsys.readouterr()
    (tmp_path / "file").write_text("x")
    for extra, match in [(["--episodes", "1", "--name", "dup"], "already exists.*--overwrite"),
                         (["--episodes", "0"], "episodes"),
                         (["--episodes", "1", "--out", str(tmp_path / "file")], "is a file"),
                         (["--episodes", "1", "--name", "a/b"], "name")]:
        assert datasets.main(args + extra) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err and err.count("\n") == 1
        assert re.search(match, err), err
    assert datasets.main(args + ["--episodes", "1", "--name", "dup", "--overwrite"]) == 0


def test_image_demonstrations_load_exactly_as_the_env_rendered_them(tmp_path):
    """Minari stores uint8 images as JPEG; loading a dataset of this module renders them again
    from the stored states, so an agent trains on the images the env shows it."""
    from lfd_agents.demos import load_episodes

    kwargs = dict(obs_mode="state+image", image_size=32, resolution=12, observe_grasp=True)
    path = datasets.collect("ClothFoldDiagonalUnpinned-v1", 1, tmp_path, env_kwargs=kwargs, seed=4, progress=False,
                            policy_kwargs={"hold_speed": 0.5, "free_speed": 0.5, "press": 0.005})
    stored = next(datasets.load(path).iterate_episodes())
    env = gym.make("ClothFoldDiagonalUnpinned-v1", **kwargs)
    env.reset(seed=0)
    env.unwrapped.set_state(datasets.episode_states(stored, env)[0])
    live = [env.unwrapped.current_observation()["image"]]
    for action in stored.actions:  # the env is deterministic: replaying shows the images of collection
        live.append(env.step(action)[0]["image"])
    live = np.stack(live)
    assert np.abs(stored.observations["image"].astype(int) - live).mean() > 1, "Minari's copy is lossy"
    (episode,) = load_episodes(path)
    np.testing.assert_array_equal(episode.observations["image"], live)
    np.testing.assert_array_equal(episode.observations["state"], stored.observations["state"])
