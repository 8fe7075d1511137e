"""MAIL: dynamics model, CEM, and the teacher -> student conversion on ThreeBoxes.

Sized for the test budget (< 60 s on an idle 2-core machine): ThreeBoxes (78 particles),
small CEM populations, few batched worlds, a few hundred model updates.
"""

import json

import numpy as np
import pytest

import gymnasium as gym
from lfd_agents.mail import (CEM, CEMConfig, DynamicsConfig, LearnedBackend, LearnedDynamics, MAIL, MAILConfig,
                             SimulatorBackend, collect_transitions)
from lfd_envs import datasets


def test_dynamics_model_overfits_tiny_dataset(tmp_path):
    rng = np.random.default_rng(0)
    n, m = 64, 24
    x = rng.uniform(-0.2, 0.2, (m, n, 3))
    a = rng.uniform(-1, 1, (m, 6))
    x_next = x + 0.05 * a[:, None, 3:] * (np.arange(n) < n // 2)[None, :, None]  # half the particles follow
    model = LearnedDynamics(n, DynamicsConfig(num_points=n, batch_size=8), seed=0)
    losses = model.fit(x, a, x_next, epochs=80)
    assert losses[-1] < losses[0] / 10
    model.save(tmp_path / "m.pt")
    again = LearnedDynamics.load(tmp_path / "m.pt")
    assert np.allclose(again.rollout(x[0], a[:2, None]), model.rollout(x[0], a[:2, None]))


def test_cem_finds_quadratic_optimum():
    target = np.array([[0.3, -0.5], [0.7, 0.1]])
    cem = CEM(2, CEMConfig(horizon=2, iterations=30, population=200, seed=1))
    best, cost = cem.optimize(lambda s: np.sum((s - target) ** 2, axis=(1, 2)))
    assert np.abs(best - target).max() < 0.03 and cost < 1e-3
    with pytest.raises(ValueError):
        CEMConfig(elite_fraction=0)


def _final_p(env, start, actions):
    env.unwrapped.set_state(start)
    info = None
    for a in actions:
        *_, info = env.step(np.asarray(a, np.float32))
    return info["normalized_performance"]


def test_cem_on_true_simulator_beats_random_actions():
    """No teacher: CEM on the batched simulator towards the goal beats random pick-and-place."""
    env = gym.make("ThreeBoxes-v0", num_pickers=1, action_mode="pick_place", obs_mode="particles")
    env.reset(seed=0, options={"split": "eval", "variant": 0})
    start = env.unwrapped.get_state()
    goal_particles = None
    backend = SimulatorBackend("ThreeBoxes-v0", {"num_pickers": 1}, num_worlds=24)
    # goal: every box particle translated to its box goal (the task's optimum)
    expert_env = gym.make("ThreeBoxes-v0", num_pickers=3, action_mode="pick_place", obs_mode="particles")
    from lfd_envs.experts import make_expert

    expert_env.reset(seed=0, options={"split": "eval", "variant": 0})
    ex = make_expert(expert_env)
    ex.reset()
    expert_env.step(ex.predict(None)[0])
    goal_particles = expert_env.unwrapped.particle_positions
    ws = env.unwrapped.workspace
    top = ws.to_action(np.array([0.0, 0.0, 0.1]))[2]  # box tops (MAIL fixes the pick height the same way)

    def constrain(samples):
        samples[..., 2] = top
        return samples

    cem = CEM(6, CEMConfig(horizon=1, iterations=2, population=48, seed=0), constrain=constrain)
    best, _ = cem.optimize(lambda s: np.linalg.norm(backend.final_particles(start, s) - goal_particles, axis=-1).mean(-1))
    p_cem = _final_p(env, start, best[:1])
    rng = np.random.default_rng(0)
    p_rand = np.mean([_final_p(env, start, rng.uniform(-1, 1, (1, 6))) for _ in range(8)])
    assert p_cem > p_rand + 0.15, (p_cem, p_rand)


def test_pipeline_three_to_one_student_beats_random_and_resumes(tmp_path):
    teacher = datasets.collect("ThreeBoxes-v0", 2, tmp_path / "teacher", progress=False,
                               env_kwargs={"num_pickers": 3, "action_mode": "pick_place", "obs_mode": "state"})
    cfg = MAILConfig(backend="simulator", cem=CEMConfig(population=12, iterations=1), simulator_worlds=12)
    mail = MAIL("ThreeBoxes-v0", teacher, tmp_path / "mail", {"num_pickers": 1}, cfg)
    stats = mail.convert()
    rand = datasets.collect("ThreeBoxes-v0", 4, tmp_path / "random", policy="random", progress=False,
                            env_kwargs={"num_pickers": 1, "action_mode": "pick_place", "obs_mode": "state"})
    rand_mean = np.mean([ep.infos["normalized_performance"][-1] for ep in datasets.load(rand).iterate_episodes()])
    student = datasets.load(mail._dataset_dir(mail.student_path))
    student_mean = np.mean([ep.infos["normalized_performance"][-1] for ep in student.iterate_episodes()])
    assert stats["kept"] >= 1 and student_mean > rand_mean + 0.4, (student_mean, rand_mean)
    # the student dataset replays to the same p̂ in a fresh env
    env = datasets.make_env(student)
    ep = next(iter(student.iterate_episodes()))
    assert datasets.replay(env, ep)[-1] == pytest.approx(float(ep.infos["normalized_performance"][-1]), abs=1e-9)
    # resume: a new pipeline object reads the saved stage instead of recomputing
    again = MAIL("ThreeBoxes-v0", teacher, tmp_path / "mail", {"num_pickers": 1}, cfg)
    assert again.convert() == json.loads((tmp_path / "mail" / "convert_stats.json").read_text())


def test_learned_backend_predicts_motion_and_dynamics_stage_resumes(tmp_path):
    """A model trained on 96 random transitions predicts held-out motion better than "nothing
    moves"; the random_data and dynamics stages are saved and a new pipeline reloads them."""
    teacher = datasets.collect("ThreeBoxes-v0", 1, tmp_path / "teacher", progress=False,
                               env_kwargs={"num_pickers": 3, "action_mode": "pick_place", "obs_mode": "state"})
    cfg = MAILConfig(backend="learned", random_transitions=96, random_worlds=32, dynamics_epochs=25)
    mail = MAIL("ThreeBoxes-v0", teacher, tmp_path / "mail", {"num_pickers": 1}, cfg)
    model = mail.dynamics()
    assert mail.random_path.exists() and mail.dynamics_path.exists() and "dynamics" in mail.timings
    held = collect_transitions("ThreeBoxes-v0", {"num_pickers": 1}, 32, num_worlds=32, seed=123, split="eval",
                               explore=0.0, uniform=0.0)
    backend = LearnedBackend(model)
    pred = np.stack([backend.final_particles({"sim/positions": x}, a[None, None])[0]
                     for x, a in zip(held["x"], held["actions"])])
    true = held["x_next"][:, model.indices]
    err = np.linalg.norm(pred - true, axis=-1).mean()
    zero = np.linalg.norm(held["x"][:, model.indices] - true, axis=-1).mean()
    assert err < 0.7 * zero, (err, zero)
    # resume: a new pipeline loads the saved model instead of collecting / training again
    again = MAIL("ThreeBoxes-v0", teacher, tmp_path / "mail", {"num_pickers": 1}, cfg)
    loaded = again.dynamics()
    assert again.timings == {} and loaded.history == model.history
    acts = held["actions"][:3, None]
    assert np.allclose(loaded.rollout(held["x"][0], acts), model.rollout(held["x"][0], acts))


def test_mail_agent_runs_from_the_benchmark_harness():
    from lfd_bench.agents import resolve_agent

    env = gym.make("ThreeBoxes-v0", num_pickers=1, action_mode="pick_place", obs_mode="state")
    agent = resolve_agent("mail")(env, 0, teacher_pickers=3, teacher_episodes=1, population=8, simulator_worlds=8,
                                  policy_kwargs={"net_arch": [16, 16]}, buffer_size=500, batch_size=8)
    agent.learn(10)
    agent.learn(10, reset_num_timesteps=False)
    assert agent.stats["kept"] == 1 and agent.mail.student_dataset() is not None
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(np.asarray(agent.predict(obs)[0], dtype=np.float32))


def test_mail_agent_checkpoint_selection_acts_with_the_best_student_and_counts_its_episodes():
    from lfd_bench.agents import resolve_agent
    from lfd_bench.budget import StepCounter, env_steps

    env = StepCounter(gym.make("ThreeBoxes-v0", num_pickers=1, action_mode="pick_place", obs_mode="state"))
    agent = resolve_agent("mail")(env, 0, teacher_pickers=3, teacher_episodes=1, population=8, simulator_worlds=8,
                                  policy_kwargs={"net_arch": [16, 16]}, buffer_size=500, batch_size=8,
                                  select_episodes=2)
    agent.learn(10)
    agent.learn(10, reset_num_timesteps=False)
    selector = agent.selector
    assert len(selector.scores) == 2 and selector.best_score == max(selector.scores)
    assert agent.validation_env_steps == 2 * 2 * 3  # 2 selections x 2 episodes x 3 pick-and-place steps
    assert env_steps(agent, env) == env.env_steps + agent.validation_env_steps
    obs, _ = env.reset(seed=0)
    assert np.array_equal(agent.predict(obs)[0], selector.best_policy.predict(obs, deterministic=True)[0])
    closed = []
    selector.env.close = lambda: closed.append(True)  # the harness closes agents after evaluation
    agent.close()
    assert closed == [True]


def _eval_final_p(env, act, episodes=6):
    """Final p̂ of ``episodes`` eval-split episodes (reset seeds 5000 + k) acting with ``act(obs)``."""
    finals = []
    for k in range(episodes):
        obs, _ = env.reset(seed=5000 + k, options={"split": "eval"})
        done = False
        while not done:
            obs, _, term, trunc, info = env.step(act(obs))
            done = term or trunc
        finals.append(info["normalized_performance"])
    return float(np.mean(finals))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mail_run_end_to_end_student_policy_beats_random(tmp_path, seed):
    """``MAIL.run`` on ThreeBoxes 3 -> 1 (simulator backend): 8 teacher demos, CEM conversion,
    then DMfD on the student dataset (1000 offline updates, 9 env steps, 64-64 MLPs). The saved
    student policy beats random actions on held-out eval episodes by > 0.3 in p̂ (measured:
    0.51 / 0.93 / 0.92 vs about 0 for seeds 0 / 1 / 2)."""
    from lfd_agents.dmfd import DMfD

    kw = {"num_pickers": 1, "action_mode": "pick_place", "obs_mode": "state"}
    teacher = datasets.collect("ThreeBoxes-v0", 8, tmp_path / "teacher", progress=False, seed=seed,
                               env_kwargs={**kw, "num_pickers": 3})
    cfg = MAILConfig(backend="simulator", cem=CEMConfig(population=12, iterations=1), simulator_worlds=12, seed=seed)
    mail = MAIL("ThreeBoxes-v0", teacher, tmp_path / "mail", {"num_pickers": 1}, cfg)
    stats = mail.run(9, policy_kwargs={"net_arch": [64, 64]}, batch_size=32, offline_steps=1000, buffer_size=2000)
    assert stats["kept"] >= 4 and mail.policy_path.exists()
    student = DMfD.load(mail.policy_path)
    env = gym.make("ThreeBoxes-v0", **kw)
    p_student = _eval_final_p(env, lambda obs: student.predict(obs, deterministic=True)[0])
    env.action_space.seed(seed)
    p_random = _eval_final_p(env, lambda obs: env.action_space.sample())
    assert p_student > p_random + 0.3, (p_student, p_random)
