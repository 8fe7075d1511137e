"""``set_state`` checks the whole state before changing anything (particle, MuJoCo, NIST, vector env)."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401


def same_state(a, b):
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


def assert_rejected(base, bad, exc, match, get=None):
    """``base.set_state(bad)`` raises ``exc`` matching ``match`` and leaves the state unchanged."""
    get = get or base.get_state
    before = get()
    with pytest.raises(exc, match=match):
        base.set_state(bad) if not hasattr(base, "num_envs") else base.set_state(0, bad)
    assert same_state(before, get())


def edited(state, **changes):
    out = {k: np.array(v, copy=True) for k, v in state.items()}
    for key, value in changes.items():
        key = key.replace("__", "/")
        if value is None:
            del out[key]
        else:
            out[key] = value
    return out


def other_variant_state(env):
    """A valid state of eval variant 3 (the env is then put back on train variant 0)."""
    env.reset(seed=1, options={"split": "eval", "variant": 3})
    state = env.unwrapped.get_state()
    env.reset(seed=0, options={"variant": 0})
    return state


COMMON_BAD = [
    (dict(episode__step=None), ValueError, r"missing keys \['episode/step'\]"),
    (dict(sim__bogus=np.zeros(1)), ValueError, r"unknown keys \['sim/bogus'\]"),
    (dict(episode__split=np.array(7)), ValueError, "episode/split"),
    (dict(episode__step=np.array(-5)), ValueError, "episode/step"),
    (dict(episode__step=np.array(10 ** 6)), ValueError, "episode/step"),
    (dict(episode__variant=np.array(2.7)), ValueError, "episode/variant"),
    (dict(episode__variant=np.array(10 ** 9)), ValueError, "episode/variant"),
    (dict(episode__p0=np.array(np.nan)), ValueError, "episode/p0"),
    (dict(episode__prev_performance=np.array(np.inf)), ValueError, "episode/prev_performance"),
    (dict(episode__p0=np.array("0.5")), TypeError, "episode/p0"),
    (dict(episode__task_id=np.array(12345)), ValueError, "another task"),
]


def check_common(env, extra):
    base = env.unwrapped
    good = other_variant_state(env)
    with pytest.raises(TypeError, match="dict"):
        base.set_state(None)
    for changes, exc, match in COMMON_BAD + extra:
        assert_rejected(base, edited(good, **changes), exc, match)
    base.set_state(good)  # the valid state still goes through, variant included
    assert same_state(base.get_state(), good)


def test_particle_env_rejects_bad_states_unchanged():
    env = gym.make("ClothFold-v0", resolution=8, obs_mode="state")
    good = other_variant_state(env)
    n = good["sim/inv_mass"].shape[0]
    check_common(env, [
        (dict(sim__positions=np.full_like(good["sim/positions"], np.nan)), ValueError, "sim/positions"),
        (dict(sim__positions=np.zeros((n - 1, 3))), ValueError, r"sim/positions.*shape"),
        (dict(sim__inv_mass=-np.ones(n)), ValueError, "sim/inv_mass"),
        (dict(sim__radius=np.zeros(n)), ValueError, "sim/radius"),
        (dict(sim__picker_positions=np.full_like(good["sim/picker_positions"], 1e6)), ValueError, "picker_positions"),
        (dict(sim__grasped=np.full(good["sim/grasped"].shape, 2.5)), ValueError, "sim/grasped"),
        (dict(sim__attach=np.full(n, 7)), ValueError, "sim/attach"),
        (dict(sim__static_pos=None), ValueError, r"missing keys \['sim/static_pos'\]"),
    ])
    ctx_key = next(k for k in good if k.startswith("sim/ctx/") and np.asarray(good[k]).dtype.kind == "f"
                   and np.asarray(good[k]).size)
    assert_rejected(env.unwrapped, edited(good, **{ctx_key.replace("/", "__"): np.full_like(good[ctx_key], np.nan)}),
                    ValueError, ctx_key)
    other = gym.make("ClothFold-v0", resolution=8, obs_mode="state", num_pickers=1)
    other.reset(seed=0)
    assert_rejected(other.unwrapped, good, ValueError, "another task|missing keys|shape")


def test_mujoco_env_rejects_bad_states_unchanged(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo would write MUJOCO_LOG.TXT here on a bad state
    env = gym.make("SawyerLiftObstacle-v0")
    good = other_variant_state(env)
    check_common(env, [
        (dict(sim__qpos=np.full_like(good["sim/qpos"], np.nan)), ValueError, "sim/qpos"),
        (dict(sim__qvel=np.full_like(good["sim/qvel"], np.inf)), ValueError, "sim/qvel"),
        (dict(sim__qpos=np.zeros(3)), ValueError, r"sim/qpos.*shape"),
        (dict(sim__time=np.array(-1.0)), ValueError, "sim/time"),
        (dict(sim__qpos=np.array(["a"] * good["sim/qpos"].size)), TypeError, "sim/qpos"),
        (dict(sim__qpos=good["sim/qpos"] + 1j), TypeError, "sim/qpos"),
    ])
    assembly = gym.make("SawyerAssemblyObstacle-v0")
    assembly.reset(seed=0)
    assert_rejected(assembly.unwrapped, good, ValueError, "another task|keys|shape")
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_nist_env_rejects_bad_states_unchanged():
    env = gym.make("NistBoardInsert-v0", obs_mode="state")
    good = other_variant_state(env)
    check_common(env, [
        (dict(sim__target=np.zeros(2)), ValueError, r"sim/target.*shape"),
        (dict(sim__target=np.array([5.0, 0.0, 0.0])), ValueError, "sim/target"),
        (dict(sim__task=np.array(99)), ValueError, "sim/task"),
        (dict(sim__qpos=np.full_like(good["sim/qpos"], np.nan)), ValueError, "sim/qpos"),
    ])
    tight = gym.make("NistBoardInsert-v0", obs_mode="state", fit="tight")
    tight.reset(seed=0)
    assert_rejected(tight.unwrapped, good, ValueError, "another task")
    tight_state = tight.unwrapped.get_state()
    assert_rejected(env.unwrapped, tight_state, ValueError, "another task")


def test_vector_env_set_state_checks_before_changing():
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point", resolution=8,
                        obs_mode="state")
    venv.reset(seed=0)
    base = venv.unwrapped
    good = base.get_state(1)

    def get():
        return base.get_state(0)

    assert_rejected(base, edited(good, episode__step=None), ValueError, "episode/step", get)
    assert_rejected(base, edited(good, episode__variant=np.array(10 ** 9)), ValueError, "episode/variant", get)
    assert_rejected(base, edited(good, sim__inv_mass=-np.ones_like(good["sim/inv_mass"])), ValueError,
                    "sim/inv_mass", get)
    with pytest.raises(TypeError, match="dict"):
        base.set_state(0, None)
    single = gym.make("ClothFold-v0", resolution=8, obs_mode="state")
    single.reset(seed=3)
    state = single.unwrapped.get_state()
    base.set_state(0, state)  # a single env's state is accepted
    assert same_state(base.get_state(0), state)


MUJOCO_IDS = [("Push2DObstacle-v0", {}), ("SawyerPushObstacle-v0", {}), ("SawyerLiftObstacle-v0", {}),
              ("SawyerAssemblyObstacle-v0", {}), ("NistBoardInsert-v0", dict(obs_mode="state"))]


def shifted(key, delta, index=None):
    """A change for :func:`edited`: ``state[key] + delta`` (only entry ``index`` when given)."""
    def change(state):
        value = np.array(state[key], dtype=np.float64, copy=True)
        if index is None:
            value = value + delta
        else:
            value[index] = delta
        return value
    return change


@pytest.mark.parametrize("env_id,kwargs", MUJOCO_IDS)
def test_mujoco_set_state_refuses_impossible_values_unchanged(env_id, kwargs, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    base = env.unwrapped
    good = base.get_state()
    bad = [("sim/qpos", shifted("sim/qpos", 1e6, 0)), ("sim/qpos", shifted("sim/qpos", 1e10)),
           ("sim/qvel", shifted("sim/qvel", 1e12, 0)), ("sim/ctrl", shifted("sim/ctrl", 1e9))]
    if "sim/mocap_quat" in good and good["sim/mocap_quat"].size:
        bad.append(("sim/mocap_quat", lambda s: np.zeros_like(s["sim/mocap_quat"])))
    for key, change in bad:
        assert_rejected(base, edited(good, **{key.replace("/", "__"): change(good)}), ValueError, key)
    base.set_state(good)  # the valid state still goes through
    assert same_state(base.get_state(), good)


def test_free_joint_zero_quaternion_is_refused():
    env = gym.make("SawyerLiftObstacle-v0")
    env.reset(seed=0)
    base = env.unwrapped
    good = base.get_state()
    qpos = good["sim/qpos"].copy()
    qpos[3:7] = 0.0  # the free joint of the object: position 0:3, quaternion 3:7
    assert_rejected(base, edited(good, sim__qpos=qpos), ValueError, r"sim/qpos.*quaternion")


@pytest.mark.parametrize("env_id,kwargs", [("ClothFold-v0", dict(resolution=8)), ("StraightenRope-v1", {}),
                                           ("ThreeBoxes-v0", {})])
def test_particle_set_state_refuses_fast_or_buried_particles_unchanged(env_id, kwargs):
    env = gym.make(env_id, obs_mode="state", **kwargs)
    env.reset(seed=0)
    base = env.unwrapped
    good = base.get_state()
    assert_rejected(base, edited(good, sim__velocities=np.full_like(good["sim/velocities"], 1e12)), ValueError,
                    "sim/velocities.*speed")
    below = good["sim/positions"] - np.array([0.0, 0.0, 1.0], np.float32)
    assert_rejected(base, edited(good, sim__positions=below), ValueError, "sim/positions.*below the table")
    base.set_state(good)
    assert same_state(base.get_state(), good)


def test_three_boxes_refuses_zero_quaternions_and_boxes_inside_boxes():
    env = gym.make("ThreeBoxes-v0", obs_mode="state")
    env.reset(seed=0)
    base = env.unwrapped
    good = base.get_state()
    assert_rejected(base, edited(good, sim__box_quat=np.zeros_like(good["sim/box_quat"])), ValueError,
                    "sim/box_quat.*unit quaternion")
    move = good["sim/box_pos"][0] - good["sim/box_pos"][1]  # box 1 onto box 0's centre
    inside = good["sim/positions"].copy()
    inside[base.task.box_slices[1]] += move
    pose = good["sim/box_pos"].copy()
    pose[1] += move
    assert_rejected(base, edited(good, sim__positions=inside, sim__box_pos=pose), ValueError,
                    "boxes 0 and 1 interpenetrate")
    assert_rejected(base, edited(good, sim__positions=inside), ValueError, "sim/positions.*interpenetrate")
    base.set_state(good)
