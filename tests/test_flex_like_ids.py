"""The ``-v1`` particle ids: the ``-v0`` tasks with FleX-like engine settings."""

import gymnasium as gym
import pytest

import lfd_envs
from lfd_envs import FLEX_LIKE_PICK_PLACE_SPEED, FLEX_LIKE_SIM_OPTIONS


def _speed_limit(env):
    """Pick-and-place speed limit of held pickers in m/s (None: the task's schedule)."""
    batch = env.unwrapped.batch
    limit = batch.action_mode.schedule.max_speed
    return None if limit is None else limit / batch.sim.params.frame_dt


def test_every_particle_task_has_a_v1_id_with_the_flex_like_settings():
    v0 = [i for i in lfd_envs.PARTICLE_ENV_IDS if i.endswith("-v0")]
    assert sorted(i.replace("-v0", "-v1") for i in v0) == sorted(i for i in lfd_envs.PARTICLE_ENV_IDS
                                                                 if i.endswith("-v1"))
    env = gym.make("ClothFold-v1", obs_mode="state", resolution=10, action_mode="pick_place")
    params = env.unwrapped.batch.sim.params
    for name, value in FLEX_LIKE_SIM_OPTIONS.items():
        assert getattr(params, name) == value, name
    assert _speed_limit(env) == pytest.approx(FLEX_LIKE_PICK_PLACE_SPEED)
    plain = gym.make("ClothFold-v0", obs_mode="state", resolution=10, action_mode="pick_place")
    assert not plain.unwrapped.batch.sim.params.picker_collision and _speed_limit(plain) is None


def test_options_given_to_a_v1_id_apply_on_top_of_its_settings():
    env = gym.make("DryCloth-v1", obs_mode="state", resolution=20, sim_options={"substeps": 10},
                   pick_place_speed=0.5, action_mode="pick_place")
    params = env.unwrapped.batch.sim.params
    assert params.substeps == 10 and params.picker_collision and not params.tethers
    assert _speed_limit(env) == pytest.approx(0.5)
    venv = gym.make_vec("ThreeBoxes-v1", num_envs=2, vectorization_mode="vector_entry_point", obs_mode="state")
    assert venv.unwrapped.batch.sim.params.picker_collision
    again = gym.make(env.spec)  # a spec rebuilds the same env
    assert again.unwrapped.batch.sim.params.substeps == 10


def test_bad_options_are_clear_errors():
    with pytest.raises(ValueError, match="substeps"):
        gym.make("ClothFold-v1", sim_options={"substeps": 0})
    with pytest.raises(TypeError):
        gym.make("ClothFold-v1", no_such_argument=1)


def test_v1_specs_serialise_and_demonstrations_can_be_recorded(tmp_path):
    """Minari stores the env spec with a dataset: a ``-v1`` spec must serialise (string entry points)."""
    from lfd_envs import datasets

    assert "lfd_envs.flex_like:" in gym.spec("ClothFold-v1").to_json()
    path = datasets.collect("ThreeBoxes-v1", 1, tmp_path / "demo", env_kwargs={"action_mode": "pick_place",
                            "obs_mode": "state"}, seed=0, progress=False)
    episode = next(iter(datasets.load(path).iterate_episodes()))
    assert episode.infos["normalized_performance"][-1] > 0.9
