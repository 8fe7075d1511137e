"""Batched particle vector envs: one engine for all worlds, SAME_STEP autoreset, SB3 adapter."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs.core.sb3_vec import SB3VecEnv


def make_vec(env_id="ClothFold-v0", n=3, **kw):
    kw.setdefault("resolution", 10)
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kw)


def test_make_vec_spaces_and_metadata():
    venv = make_vec("ClothFoldDiagonalPinned-v0", n=3, num_pickers=2, action_mode="pick_place", obs_mode="state+image")
    assert venv.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    assert venv.num_envs == 3 and venv.unwrapped.task.pinned
    assert venv.single_action_space.shape == (12,) and venv.action_space.shape == (3, 12)
    obs, info = venv.reset(seed=0)
    assert obs["state"].shape == (3, 18) and obs["image"].shape == (3, 32, 32, 3)
    assert info["normalized_performance"].shape == (3,) and info["_variant"].all()
    with pytest.raises(ValueError, match=r"\(3, 12\)"):
        venv.step(np.zeros((2, 12)))
    with pytest.raises(ValueError, match="finite"):
        venv.step(np.full((3, 12), np.inf))
    venv.step(np.zeros((3, 12)))  # still usable


@pytest.mark.parametrize("env_id,obs_mode", [("ClothFold-v0", "particles"), ("StraightenRope-v0", "image")])
def test_vector_env_equals_single_envs(env_id, obs_mode):
    n, horizon, seed = 2, 3, 5
    venv = make_vec(env_id, n=n, horizon=horizon, obs_mode=obs_mode)
    singles = [gym.make(env_id, resolution=10, horizon=horizon, obs_mode=obs_mode) for _ in range(n)]
    vobs, vinfo = venv.reset(seed=seed)
    sobs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    assert all(np.array_equal(vobs[i], sobs[i]) for i in range(n))
    rng = np.random.default_rng(0)
    for t in range(horizon + 2):  # crosses an autoreset
        actions = rng.uniform(-1, 1, size=(n,) + venv.single_action_space.shape).astype(np.float32)
        vobs, vrew, vterm, vtrunc, vinfo = venv.step(actions)
        for i, env in enumerate(singles):
            obs, rew, term, trunc, info = env.step(actions[i])
            assert rew == pytest.approx(vrew[i], abs=0) and trunc == vtrunc[i] and term == vterm[i]
            if trunc or term:
                assert np.array_equal(vinfo["final_obs"][i], obs)
                assert vinfo["final_info"]["normalized_performance"][i] == info["normalized_performance"]
                obs, info = env.reset()
            assert np.array_equal(vobs[i], obs)
            assert vinfo["variant"][i] == info["variant"]
            assert vinfo["normalized_performance"][i] == info["normalized_performance"]


def test_world_state_round_trip_and_variant_options():
    venv = make_vec("StraightenRope-v0", n=2, obs_mode="particles")
    obs, info = venv.reset(seed=0, options={"variant": [3, 4], "split": "eval"})
    assert info["variant"].tolist() == [803, 804]
    state = venv.unwrapped.get_state(1)
    acts = np.zeros((2, 8), np.float32)
    acts[:, 3] = 1
    first = venv.step(acts)[0]
    venv.unwrapped.set_state(1, state)
    venv.unwrapped.set_state(0, state)
    again = venv.step(acts)[0]
    assert np.array_equal(again[1], first[1]) and np.array_equal(again[0], first[1])


@pytest.mark.parametrize("algo", ["PPO", "SAC"])
def test_sb3_learns_a_few_steps(algo):
    import stable_baselines3 as sb3

    venv = SB3VecEnv(make_vec("StraightenRope-v0", n=2, obs_mode="state", horizon=4), seed=0)
    if algo == "PPO":
        model = sb3.PPO("MlpPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, seed=0, device="cpu")
    else:
        model = sb3.SAC("MlpPolicy", venv, learning_starts=4, batch_size=8, buffer_size=100, seed=0, device="cpu")
    model.learn(total_timesteps=16)
    obs = venv.reset()
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (2, 8)
    venv.close()


def test_dataset_round_trip(tmp_path):
    from lfd_envs import datasets

    kwargs = dict(resolution=20, num_pickers=1, action_mode="pick_place", obs_mode="state")
    path = datasets.collect("ClothFoldDiagonalPinned-v0", 2, tmp_path, env_kwargs=kwargs, seed=3, progress=False)
    ds = datasets.load(path)
    env = datasets.make_env(ds)
    for ep in ds.iterate_episodes():
        finals = datasets.replay(env, ep)
        assert finals[-1] == pytest.approx(float(ep.infos["normalized_performance"][-1]), abs=1e-9)
        assert finals[-1] > 0.5
