"""The ``-v1`` particle ids: the ``-v0`` tasks with the ``flex_like`` physics preset."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs
from lfd_envs import FLEX_LIKE_PICK_PLACE_SPEED, FLEX_LIKE_SIM_OPTIONS
from lfd_envs.experts import make_expert
from lfd_envs.physics import FLEX_LIKE

#: the ``-v1`` engine settings every committed ``-v1`` result was measured with
V1_SETTINGS = {"substeps": 20, "iterations": 1, "tethers": False, "collision_passes": 0, "self_collision_interval": 10,
               "picker_collision": True, "self_collision_distance": 0.01, "substeps_reference_resolution": 40,
               "bend_reference_resolution": 40}


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

    spec = gym.spec("ClothFold-v1").to_json()
    assert '"physics": "flex_like"' in spec and "lfd_envs.tasks.cloth_fold:ClothFoldEnv" in spec
    path = datasets.collect("ThreeBoxes-v1", 1, tmp_path / "demo", env_kwargs={"action_mode": "pick_place",
                            "obs_mode": "state"}, seed=0, progress=False)
    episode = next(iter(datasets.load(path).iterate_episodes()))
    assert episode.infos["normalized_performance"][-1] > 0.9


@pytest.mark.parametrize("task,kwargs", [("ClothFold", dict(resolution=10)), ("ThreeBoxes", {}),
                                         ("StraightenRope", dict(resolution=11))])
def test_the_flex_like_preset_is_the_v1_settings(task, kwargs):
    assert dict(FLEX_LIKE.sim_options) == V1_SETTINGS and FLEX_LIKE.pick_place_speed == 1.0
    v1 = gym.make(f"{task}-v1", obs_mode="state", **kwargs).unwrapped
    v0 = gym.make(f"{task}-v0", obs_mode="state", **kwargs).unwrapped
    assert (v1.physics, v0.physics) == ("flex_like", "fast")
    assert v1.batch.sim.params == dataclasses.replace(v1.task.sim_params(), **V1_SETTINGS)
    assert v0.batch.sim.params == v0.task.sim_params()
    defaults = type(v0.batch.sim.params)()  # the ``fast`` preset: the SimParams defaults, which every task keeps
    assert all(getattr(v0.batch.sim.params, name) == getattr(defaults, name) for name in V1_SETTINGS)
    by_argument = gym.make(f"{task}-v0", obs_mode="state", physics="flex_like", **kwargs).unwrapped
    assert by_argument.batch.sim.params == v1.batch.sim.params and by_argument.batch.identity() == v1.batch.identity()


def test_an_unknown_physics_is_a_clear_error():
    with pytest.raises(ValueError, match=r"physics must be one of \('fast', 'flex_like'\), got 'flex'"):
        gym.make("ClothFold-v0", resolution=10, physics="flex")


def _same(a, b):
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("task,kwargs", [("ClothFold", dict(resolution=10)), ("ThreeBoxes", {})])
def test_a_state_of_the_other_physics_is_refused_naming_both(task, kwargs):
    """The two presets give different futures from one state: ``set_state`` refuses a state
    saved under the other one (single and vector env) and changes nothing."""
    envs = {v: gym.make(f"{task}-{v}", obs_mode="state", **kwargs) for v in ("v0", "v1")}
    states = {}
    for v, env in envs.items():
        env.reset(seed=0, options={"variant": 1})
        states[v] = env.unwrapped.get_state()
    for v, other in (("v0", "v1"), ("v1", "v0")):
        base = envs[v].unwrapped
        with pytest.raises(ValueError, match=rf"from {task}\S*-{other} .*this env is {task}\S*-{v} "):
            base.set_state(states[other])
        assert _same(base.get_state(), states[v])
        base.set_state(states[v])  # its own state still loads
    venv = gym.make_vec(f"{task}-v1", num_envs=2, vectorization_mode="vector_entry_point", obs_mode="state", **kwargs)
    venv.reset(seed=0)
    before = venv.unwrapped.get_state(0)
    with pytest.raises(ValueError, match=rf"-v0 \(physics='fast'\); this env is {task}\S*-v1"):
        venv.unwrapped.set_state(0, states["v0"])
    assert _same(venv.unwrapped.get_state(0), before)
    venv.unwrapped.set_state(1, states["v1"])


def test_engine_options_on_a_v0_id_do_not_switch_the_expert_plan():
    """``sim_options={"picker_collision": True}`` on ``ClothFold-v0`` keeps the ``-v0`` plan of the
    one-picker expert (a left corner first); only the ``flex_like`` physics gets the ``-v1`` plan
    (the middle of the left edge)."""
    def first_pick(env_id, **kwargs):
        env = gym.make(env_id, obs_mode="state", action_mode="pick_place", num_pickers=1, resolution=10, **kwargs)
        env.reset(seed=0, options={"variant": 0, "split": "eval"})
        return make_expert(env).next_move().pick[0, :2]

    v0, v1 = first_pick("ClothFold-v0"), first_pick("ClothFold-v1")
    assert np.linalg.norm(v0 - v1) > 0.1  # the two plans start at points of the edge far apart
    colliding = first_pick("ClothFold-v0", sim_options={"picker_collision": True})
    assert np.allclose(colliding, v0, atol=1e-3)
