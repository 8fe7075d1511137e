"""Engine parameters from ``gym.make`` (``sim_options``): they reach the engine, bad ones are clear errors."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401


def test_options_reach_the_engine_of_single_and_vector_envs():
    opts = {"picker_collision": True, "self_collision_distance": 0.01, "tethers": False}
    env = gym.make("lfd_envs:ClothFold-v0", resolution=10, sim_options=opts)
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point", resolution=10,
                        sim_options=opts)
    for sim in (env.unwrapped.batch.sim, venv.unwrapped.batch.sim):
        assert sim.params.picker_collision and sim.params.self_collision_distance == 0.01 and not sim.params.tethers
    default = gym.make("lfd_envs:ClothFold-v0", resolution=10).unwrapped.batch.sim.params
    assert not default.picker_collision and default.tethers and default.self_collision_distance is None


def test_a_thickness_in_metres_sets_the_collision_distance_at_every_resolution():
    for res in (10, 20):
        sim = gym.make("lfd_envs:ClothFold-v0", resolution=res, sim_options={"self_collision_distance": 0.01}
                       ).unwrapped.batch.sim
        assert np.allclose(sim.get_state(0)["sc_r"], 0.005)
    coarse = gym.make("lfd_envs:ClothFold-v0", resolution=10).unwrapped.batch.sim.get_state(0)["sc_r"]
    fine = gym.make("lfd_envs:ClothFold-v0", resolution=20).unwrapped.batch.sim.get_state(0)["sc_r"]
    assert coarse.max() > 1.8 * fine.max()  # the default scales with the particle spacing


@pytest.mark.parametrize("bad,error", [({"no_such_field": 1}, "unknown engine parameter"),
                                       ({"substeps": 0}, "substeps"), ([("tethers", False)], "dict")])
def test_bad_options_are_clear_errors(bad, error):
    with pytest.raises(ValueError, match=error):
        gym.make("lfd_envs:StraightenRope-v0", sim_options=bad)
