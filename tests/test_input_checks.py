"""Constructor arguments, reset options and actions are checked with clear errors (MuJoCo, NIST, particle)."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401

PARTICLE = dict(resolution=8, obs_mode="state")


@pytest.mark.parametrize("env_id,kwargs,match", [
    ("Push2DObstacle-v0", dict(image_size="32"), "image_size"),
    ("Push2DObstacle-v0", dict(image_size=("32", "32")), "image_size"),
    ("Push2DObstacle-v0", dict(image_size=32.0), "image_size"),
    ("Push2DObstacle-v0", dict(horizon=2.5), "horizon"),
    ("Push2DObstacle-v0", dict(horizon=True), "horizon"),
    ("Push2DObstacle-v0", dict(goal_conditioned="no"), "goal_conditioned"),
    ("Push2DObstacle-v0", dict(render_size="32"), "render_size"),
    ("NistBoardInsert-v0", dict(horizon=2.5), "horizon"),
    ("NistBoardInsert-v0", dict(success_bonus=float("nan")), "success_bonus"),
    ("NistBoardInsert-v0", dict(success_bonus=float("inf")), "success_bonus"),
    ("NistBoardInsert-v0", dict(instruction=5), "instruction"),
    ("NistBoardInsert-v0", dict(instruction=[5]), "instruction"),
    ("NistBoardInsert-v0", dict(action_repeat=True), "action_repeat"),
    ("NistBoardInsert-v0", dict(action_repeat=1.5), "action_repeat"),
    ("NistBoardInsert-v0", dict(max_delta="0.003"), "max_delta"),
    ("NistBoardInsert-v0", dict(antialias="no"), "antialias"),
    ("NistBoardInsert-v0", dict(image_size="32"), "image_size"),
    ("ClothFold-v0", dict(PARTICLE, image_size="32"), "image_size"),
    ("ClothFold-v0", dict(PARTICLE, device=None), "device"),
])
def test_bad_constructor_arguments_raise_clear_errors(env_id, kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(env_id, **kwargs)


def test_human_render_mode_is_explained_at_construction():
    from lfd_envs.mujoco.nist import NistBoardInsertEnv
    from lfd_envs.mujoco.push2d import Push2DObstacleEnv
    from lfd_envs.tasks.cloth_fold import ClothFoldEnv

    for make in (lambda: Push2DObstacleEnv(render_mode="human"), lambda: NistBoardInsertEnv(render_mode="human"),
                 lambda: ClothFoldEnv(render_mode="human", **PARTICLE),
                 lambda: gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point",
                                      render_mode="human", **PARTICLE)):
        with pytest.raises(ValueError, match="headless.*rgb_array.*HumanRendering"):
            make()


def test_gymnasium_check_env_with_render_checks_passes():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("Push2DObstacle-v0", render_mode="rgb_array", render_size=32)
    check_env(env.unwrapped)  # makes the env again in every declared render mode


def rng_state(env):
    return env.unwrapped.np_random.bit_generator.state


@pytest.mark.parametrize("env_id,kwargs,bad_options", [
    ("Push2DObstacle-v0", {}, {"variant": 10 ** 6}),
    ("Push2DObstacle-v0", {}, {"variant": True}),
    ("Push2DObstacle-v0", {}, {"split": "test"}),
    ("NistBoardInsert-v0", dict(obs_mode="state"), {"variant": 10 ** 6}),
    ("NistBoardInsert-v0", dict(obs_mode="state"), {"variant": True, "instruction": "insert small peg in large hole"}),
    ("NistBoardInsert-v0", dict(obs_mode="state"), {"instruction": 5}),
    ("ClothFold-v0", PARTICLE, {"variant": True}),
])
def test_failed_reset_changes_nothing(env_id, kwargs, bad_options):
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    before_rng, before_state = rng_state(env), env.unwrapped.get_state()
    with pytest.raises(ValueError):
        env.reset(seed=123, options=bad_options)
    assert rng_state(env) == before_rng
    after = env.unwrapped.get_state()
    assert all(np.array_equal(before_state[k], after[k]) for k in before_state)


def test_failed_vector_reset_does_not_reseed():
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point", **PARTICLE)
    venv.reset(seed=0)
    before = [r.bit_generator.state for r in venv.unwrapped._rngs]
    with pytest.raises(ValueError):
        venv.reset(seed=5, options={"variant": True})
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=[1, "2"])
    assert [r.bit_generator.state for r in venv.unwrapped._rngs] == before


@pytest.mark.parametrize("env_id,kwargs", [
    ("Push2DObstacle-v0", {}),
    ("NistBoardInsert-v0", dict(obs_mode="state")),
    ("NistBoardInsert-v0", dict(obs_mode="state", action_mode="tokens")),
    ("ClothFold-v0", PARTICLE),
])
def test_non_real_actions_are_rejected(env_id, kwargs):
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    n = env.action_space.shape[0]
    for bad in (np.array(["0.5"] * n), ["1"] * n, np.full(n, 0.5 + 0.5j), np.array([object()] * n)):
        with pytest.raises(ValueError, match="real numeric"):
            env.step(bad)
    env.step(env.action_space.sample())  # still usable


def test_vector_env_rejects_complex_actions():
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point", **PARTICLE)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="real numeric"):
        venv.step(np.full(venv.action_space.shape, 0.1j))


@pytest.mark.parametrize("env_id,kwargs,size,shape", [
    ("Push2DObstacle-v0", {}, (48, 64), (48, 64, 3)),
    ("NistBoardInsert-v0", dict(obs_mode="state"), 40, (40, 40, 3)),
    ("ClothFold-v0", PARTICLE, (24, 40), (24, 40, 3)),
])
def test_render_size_sets_rgb_array_frames(env_id, kwargs, size, shape):
    env = gym.make(env_id, render_mode="rgb_array", render_size=size, **kwargs)
    env.reset(seed=0)
    assert env.render().shape == shape


@pytest.mark.parametrize("env_id,kwargs,match", [
    ("ClothFold-v0", dict(PARTICLE, sim_options={"substeps": 10 ** 7}), "substeps"),
    ("ClothFold-v1", dict(PARTICLE, sim_options={"iterations": 10 ** 7}), "iterations"),
    ("ClothFold-v0", dict(PARTICLE, sim_options={"max_neighbors": 10 ** 9}), "max_neighbors"),
    ("DryCloth-v1", dict(obs_mode="state", sim_options={"picker_radius": 1e6}), "picker_radius"),
    ("NistBoardInsert-v0", dict(obs_mode="state", action_repeat=10 ** 9), "action_repeat"),
    ("ClothFold-v1", dict(PARTICLE, sim_options="x"), "sim_options"),
    ("ClothFold-v0", dict(PARTICLE, sim_options="x"), "sim_options"),
])
def test_unbounded_settings_are_refused_quickly(env_id, kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(env_id, **kwargs)


@pytest.mark.parametrize("env_id,kwargs", [
    ("Push2DObstacle-v0", {}),
    ("NistBoardInsert-v0", dict(obs_mode="state")),
    ("ClothFold-v0", PARTICLE),
])
@pytest.mark.parametrize("seed,options,match", [
    (True, None, "seed"),
    (-1, None, "seed"),
    ("3", None, "seed"),
    (None, [("split", "train")], "options must be a dict"),
    (None, "train", "options must be a dict"),
    (None, 5, "options must be a dict"),
])
def test_bad_seed_or_options_type_is_refused_unchanged(env_id, kwargs, seed, options, match):
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    before_rng, before_state = rng_state(env), env.unwrapped.get_state()
    with pytest.raises(ValueError, match=match):
        env.reset(seed=seed, options=options)
    assert rng_state(env) == before_rng
    after = env.unwrapped.get_state()
    assert all(np.array_equal(before_state[k], after[k]) for k in before_state)


def test_vector_reset_refuses_bool_seed_and_non_dict_options():
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point", **PARTICLE)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=True)
    with pytest.raises(ValueError, match="options must be a dict"):
        venv.reset(options="train")


def test_nist_single_camera_name_means_that_camera():
    """A plain string names one camera (documented), it is not split into letters."""
    env = gym.make("NistBoardInsert-v0", cameras="wrist", image_size=16)
    assert env.unwrapped.cameras == ("wrist",)
    assert "wrist" in env.observation_space.spaces and "workspace" not in env.observation_space.spaces


@pytest.mark.parametrize("env_id,kwargs", [
    ("Push2DObstacle-v0", {}),
    ("NistBoardInsert-v0", dict(obs_mode="state")),
    ("ClothFold-v0", PARTICLE),
])
def test_closed_env_refuses_step_render_and_reset(env_id, kwargs):
    env = gym.make(env_id, render_mode="rgb_array", render_size=16, **kwargs)
    env.reset(seed=0)
    env.close()
    for call in (lambda: env.step(env.action_space.sample()), env.render, lambda: env.reset(seed=0)):
        with pytest.raises(RuntimeError, match="close"):
            call()


def test_closed_vector_env_refuses_step_and_render():
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        render_mode="rgb_array", render_size=16, **PARTICLE)
    venv.reset(seed=0)
    venv.close()
    with pytest.raises(RuntimeError, match="close"):
        venv.step(venv.action_space.sample())
    with pytest.raises(RuntimeError, match="close"):
        venv.render()
