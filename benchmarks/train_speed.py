"""Learning speed on CPU: gradient updates and env steps per second of the learning agents.

For each network width (256 and 1024 by default; batch 256, state observations, delta
actions, ``ClothFold-v0``, one torch thread unless told otherwise) and each agent (DMfD,
AWAC, SAC-LfD, BC and plain SB3 SAC as the reference) it measures

* ``updates_per_s`` — gradient updates (``train``) on a filled replay buffer (BC: minibatch
  steps of ``learn`` on a demonstration set of the same size);
* ``learn_steps_per_s`` — ``learn`` with one update per env step (the real loop; BC does not
  step the env);
* ``env_steps_per_s`` — the env alone with random actions, measured in the same rounds;

and the ratios ``vs_sac`` (updates/s over SB3 SAC's at the same width; ``vs_sac_cpu`` the
same by CPU time) and ``vs_env`` (learn steps/s over env-only steps/s).

Image rows (``--image``): the same agents with 32×32 image observations of the same env
(``CnnPolicy``: the default lean :class:`~lfd_agents.ImageEncoder`, actor and critic sharing
it), plus ``dmfd_separate`` (DMfD with a lean encoder each for actor and critic, the network of the
harness's ``dmfd/image-v2`` recipe), ``dmfd_thesis`` (DMfD with the thesis's encoder, separate
for actor and critic), ``drq`` and ``curl``. Their ``vs_state`` is the update's CPU time over that
of the agent's state update in the same run (DMfD's for both DMfD variants, SAC-LfD's for DrQ and CURL, which
run its update machinery); ``vs_sac`` stays against SB3 SAC on state.

What bounds an update: ``matmul_ms`` is the time of the matrix products one update runs
(the ``addmm``/``mm``/``bmm``/``baddbmm`` calls and their shapes are recorded with the torch
profiler over a few updates, then replayed alone on random tensors of the same shapes, so the
profiler's own overhead is not counted), ``update_ms`` the whole update, ``matmul_share`` their
ratio, and ``max_vs_sac`` = SB3 SAC's ``update_ms`` / this agent's ``matmul_ms``: the ``vs_sac``
an update with no cost at all besides its fp32 matrix products would reach.  The machine is usually shared, so every quantity is
measured in interleaved rounds (each agent, then the env, then the next round) and the
median over rounds is reported; ``updates_per_cpu_s`` divides by the thread's CPU time,
which other processes disturb less.  The buffer holds random transitions: the cost of an
update does not depend on the data.

Usage::

    python -m benchmarks.train_speed [--env ClothFold-v0] [--widths 256 1024] [--agents dmfd awac sac_lfd bc sac]
        [--image] [--image-agents dmfd dmfd_separate dmfd_thesis bc drq curl sac]
        [--rounds 3] [--updates 100] [--learn-steps 40] [--batch-size 256] [--threads 1] [--json]

``agent_rows(...)`` returns the rows as dicts.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from typing import Any, Callable, Sequence

import numpy as np

AGENTS = ("dmfd", "awac", "sac_lfd", "bc", "sac")
IMAGE_AGENTS = ("dmfd", "dmfd_separate", "dmfd_thesis", "bc", "drq", "curl", "sac")
NAMES = {"dmfd": "DMfD", "awac": "AWAC", "sac_lfd": "SAC-LfD", "bc": "BC", "sac": "SB3 SAC",
         "dmfd_separate": "DMfD (an encoder each)", "dmfd_thesis": "DMfD (thesis encoder)", "drq": "DrQ", "curl": "CURL"}
#: the state agent an image agent's update is compared with (``vs_state``)
STATE_COUNTERPART = {"dmfd": "dmfd", "dmfd_separate": "dmfd", "dmfd_thesis": "dmfd", "bc": "bc", "drq": "sac_lfd", "curl": "sac_lfd",
                     "sac": "sac"}


def _make_env(env_id: str, obs_mode: str = "state"):
    import gymnasium as gym

    import lfd_envs  # noqa: F401

    return gym.make(env_id, obs_mode=obs_mode, action_mode="delta")


def _random_obs(rng: np.random.Generator, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
    if np.dtype(dtype) == np.uint8:  # images
        return rng.integers(0, 256, size=shape, dtype=np.uint8)
    return rng.normal(size=shape).astype(dtype)


def _fill(buffer: Any, n: int, rng: np.random.Generator) -> None:
    """Write ``n`` random transitions into an SB3 ``ReplayBuffer`` (Box observations)."""
    shape_o = buffer.observations.shape[1:]
    shape_a = buffer.actions.shape[1:]
    buffer.observations[:n] = _random_obs(rng, (n, *shape_o), buffer.observations.dtype)
    buffer.next_observations[:n] = _random_obs(rng, (n, *shape_o), buffer.observations.dtype)
    buffer.actions[:n] = rng.uniform(-1, 1, size=(n, *shape_a))
    buffer.rewards[:n] = rng.normal(size=buffer.rewards[:n].shape)
    buffer.dones[:n] = 0.0
    buffer.pos, buffer.full = n % buffer.buffer_size, n == buffer.buffer_size


def _episodes(env: Any, n: int, rng: np.random.Generator, length: int = 100) -> list[dict[str, Any]]:
    """Random episodes (dicts as :func:`lfd_agents.demos.load_episodes` takes) with ``n`` steps in all."""
    space = env.observation_space
    act_dim = env.action_space.shape[0]
    episodes = []
    for start in range(0, n, length):
        t = min(length, n - start)
        episodes.append({"observations": _random_obs(rng, (t + 1, *space.shape), space.dtype),
                         "actions": rng.uniform(-1, 1, (t, act_dim)).astype(np.float32),
                         "rewards": rng.normal(size=t), "terminations": np.zeros(t, bool),
                         "truncations": np.eye(1, t, t - 1, dtype=bool)[0]})
    return episodes


def _build(agent: str, env: Any, width: int, batch_size: int, buffer_rows: int, seed: int) -> Any:
    from stable_baselines3 import SAC
    from stable_baselines3.common.logger import configure

    from lfd_agents import AWAC, BC, CURL, DMfD, DrQ, ImageEncoder, SACLfD
    from lfd_agents.networks import THESIS_ENCODER

    rng = np.random.default_rng(seed)
    image = len(env.observation_space.shape) == 3
    policy = "CnnPolicy" if image else "MlpPolicy"
    arch = dict(net_arch=[width, width])
    common = dict(buffer_size=2 * buffer_rows, batch_size=batch_size, learning_starts=0, seed=seed, device="cpu")
    if agent == "bc":
        model = BC(policy, env, demonstrations=_episodes(env, buffer_rows, rng), batch_size=batch_size,
                   policy_kwargs=arch, seed=seed, device="cpu")
    elif agent == "dmfd":
        model = DMfD(policy, env, rsi_prob=0.0, policy_kwargs=arch, **common)
    elif agent == "dmfd_separate" and image:
        model = DMfD(policy, env, rsi_prob=0.0, policy_kwargs=dict(arch, share_encoder=False), **common)
    elif agent == "dmfd_thesis" and image:
        model = DMfD(policy, env, rsi_prob=0.0, policy_kwargs=dict(arch, share_encoder=False,
                                                                   features_extractor_kwargs=THESIS_ENCODER), **common)
    elif agent == "awac":
        model = AWAC(policy, env, offline_steps=0, policy_kwargs=arch, **common)
    elif agent == "sac_lfd":
        model = SACLfD(policy, env, policy_kwargs=dict(arch, features_extractor_class=ImageEncoder) if image else arch,
                       **common)
    elif agent in ("drq", "curl") and image:
        model = {"drq": DrQ, "curl": CURL}[agent](policy, env, policy_kwargs=arch, **common)
    elif agent == "sac":
        model = SAC(policy, env, policy_kwargs=dict(arch, features_extractor_class=ImageEncoder) if image else arch,
                    **common)
    else:
        raise ValueError(f"unknown agent {agent!r} for {'image' if image else 'state'} observations; choose from "
                         f"{IMAGE_AGENTS if image else AGENTS}")
    if agent != "bc":
        _fill(model.replay_buffer, buffer_rows, rng)
        model.set_logger(configure(None, []))
    return model


def _timed(fn: Callable[[], Any]) -> tuple[float, float]:
    t0, c0 = time.perf_counter(), time.thread_time()
    fn()
    return time.perf_counter() - t0, time.thread_time() - c0


def _updates(model: Any, agent: str, n: int, batch_size: int) -> Callable[[], int]:
    """A callable running about ``n`` updates; returns how many it ran."""
    if agent == "bc":
        per_epoch = -(-model.dataset.size() // model.batch_size)
        epochs = max(1, round(n / per_epoch))
        return lambda: (model.learn(epochs=epochs, log_interval=0), epochs * per_epoch)[1]
    return lambda: (model.train(n, batch_size), n)[1]


_MATMUL_OPS = ("aten::addmm", "aten::mm", "aten::bmm", "aten::baddbmm")


def _replay_ms(op: str, shapes: list[list[int]], repeats: int = 100) -> float:
    """Milliseconds of one ``op`` call on random tensors of the recorded input ``shapes``."""
    import torch as th

    fn = {"aten::mm": th.mm, "aten::bmm": th.bmm, "aten::addmm": th.addmm, "aten::baddbmm": th.baddbmm}[op]
    args = [th.randn(*shape) for shape in shapes[:2 if op in ("aten::mm", "aten::bmm") else 3]]
    for _ in range(3):
        fn(*args)
    t0 = time.perf_counter()
    for _ in range(repeats):
        fn(*args)
    return (time.perf_counter() - t0) / repeats * 1e3


def matmul_floor_ms(model: Any, agent: str, batch_size: int, updates: int = 10) -> float | None:
    """Milliseconds of matrix products per update of ``model`` (recorded, then replayed alone);
    None for BC (its update runs through ``learn``)."""
    if agent == "bc":
        return None
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU], record_shapes=True) as prof:
        model.train(updates, batch_size)
    total = 0.0
    for ev in prof.key_averages(group_by_input_shape=True):
        if ev.key in _MATMUL_OPS:
            total += _replay_ms(ev.key, ev.input_shapes) * ev.count / updates
    return total


def _env_steps(env: Any, n: int, rng: np.random.Generator) -> None:
    for _ in range(n):
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        if term or trunc:
            env.reset()


def _median_rates(samples: list[tuple[float, float]]) -> tuple[float, float]:
    return statistics.median(w for w, _ in samples), statistics.median(c for _, c in samples)


def agent_rows(env_id: str = "ClothFold-v0", widths: Sequence[int] = (256, 1024), agents: Sequence[str] = AGENTS,
               rounds: int = 3, updates: int = 100, learn_steps: int = 40, batch_size: int = 256,
               buffer_rows: int = 2_000, seed: int = 0, log: Callable[[str], None] | None = None,
               image_agents: Sequence[str] = (), matmul_floor: bool = True) -> list[dict[str, Any]]:
    """One row per (width, agent, observation kind); see the module docstring. Counts are per
    round at width 256; wider networks run ``(256/width)²``-scaled updates and
    ``(256/width)``-scaled steps (at least 10). ``image_agents`` adds image rows, and the
    state agents they are compared with; ``matmul_floor=False`` skips the (slow) profiling of
    the matrix products (their columns are then None)."""
    unknown = [a for a in agents if a not in AGENTS] + [a for a in image_agents if a not in IMAGE_AGENTS]
    if unknown or rounds < 1 or updates < 1 or learn_steps < 1:
        raise ValueError(f"agents must be among {AGENTS} and image agents among {IMAGE_AGENTS} (got {unknown}); "
                         "rounds, updates, learn_steps >= 1")
    state_agents = list(dict.fromkeys([*agents, *(STATE_COUNTERPART[a] for a in image_agents)]))
    cases = [(a, "state") for a in state_agents] + [(a, "image") for a in image_agents]
    rows = []
    for width in widths:
        scale = min(1.0, 256 / width)
        n_upd, n_learn = max(10, int(updates * scale ** 2)), max(10, int(learn_steps * scale))
        rng = np.random.default_rng(seed)
        envs = {obs: _make_env(env_id, obs) for obs in dict.fromkeys(o for _, o in cases)}
        for env in envs.values():
            env.reset(seed=seed)
            _env_steps(env, 5, rng)  # warm-up (kernel loads)
        models = {(a, o): _build(a, envs[o], width, batch_size, buffer_rows, seed) for a, o in cases}
        runs = {c: _updates(m, c[0], n_upd, batch_size) for c, m in models.items()}
        for (a, o), m in models.items():  # warm-up: first calls allocate, and learn() resets the env once
            _updates(m, a, 2, batch_size)()
            if a != "bc":
                m.learn(2, reset_num_timesteps=False)
        floors = {c: matmul_floor_ms(m, c[0], batch_size) if matmul_floor else None for c, m in models.items()}
        upd: dict[tuple[str, str], list[tuple[float, float]]] = {c: [] for c in cases}
        lrn: dict[tuple[str, str], list[float]] = {c: [] for c in cases if c[0] != "bc"}
        env_rates: dict[str, list[tuple[float, float]]] = {o: [] for o in envs}
        for r in range(rounds):
            for c, m in models.items():
                count = [0]
                wall, cpu = _timed(lambda: count.__setitem__(0, runs[c]()))
                upd[c].append((count[0] / wall, count[0] / cpu))
                if c in lrn:
                    wall, _ = _timed(lambda: m.learn(n_learn, reset_num_timesteps=False))
                    lrn[c].append(n_learn / wall)
            for o, env in envs.items():
                env.reset()
                wall, cpu = _timed(lambda: _env_steps(env, n_learn, rng))
                env_rates[o].append((n_learn / wall, n_learn / cpu))
            if log:
                log(f"width {width}: round {r + 1}/{rounds} done")
        ref, ref_cpu = _median_rates(upd[("sac", "state")]) if ("sac", "state") in upd else (float("nan"),) * 2
        for a, o in cases:
            u, u_cpu = _median_rates(upd[(a, o)])
            env_rate = _median_rates(env_rates[o])[0]
            row = {"agent": NAMES[a], "obs": o, "net": f"{width}-{width}", "updates_per_s": round(u, 1),
                   "vs_sac": round(u / ref, 2), "updates_per_cpu_s": round(u_cpu, 1),
                   "vs_sac_cpu": round(u_cpu / ref_cpu, 2)}
            counterpart = (STATE_COUNTERPART[a], "state") if o == "image" else None
            row["vs_state"] = round(_median_rates(upd[counterpart])[1] / u_cpu, 2) if counterpart else None
            floor = floors[(a, o)]
            row.update(update_ms=round(1e3 / u, 2), matmul_ms=None if floor is None else round(floor, 2),
                       matmul_share=None if floor is None else round(floor * u / 1e3, 2),
                       max_vs_sac=None if floor is None else round(1e3 / ref / floor, 2))
            if (a, o) in lrn:
                s = statistics.median(lrn[(a, o)])
                row.update(learn_steps_per_s=round(s, 1), env_steps_per_s=round(env_rate, 1),
                           vs_env=round(s / env_rate, 2))
            else:
                row.update(learn_steps_per_s=None, env_steps_per_s=round(env_rate, 1), vs_env=None)
            rows.append(row)
        for env in envs.values():
            env.close()
    return rows


def _print(rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join("-" if r[k] is None else str(r[k]) for k in keys) + " |")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--env", default="ClothFold-v0")
    p.add_argument("--widths", type=int, nargs="+", default=[256, 1024])
    p.add_argument("--agents", nargs="+", default=list(AGENTS), choices=AGENTS)
    p.add_argument("--image", action="store_true", help="add image rows (32x32 observations of the same env)")
    p.add_argument("--image-agents", nargs="+", default=list(IMAGE_AGENTS), choices=IMAGE_AGENTS,
                   help="agents of the image rows (with --image)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--updates", type=int, default=100, help="updates per agent and round at width 256")
    p.add_argument("--learn-steps", type=int, default=40, help="learn() env steps per agent and round at width 256")
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    import torch as th

    th.set_num_threads(args.threads)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"python {platform.python_version()}, torch {th.__version__}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs, torch threads {th.get_num_threads()}, load average {load:.2f}; "
          f"{args.env} {'state and 32x32 image' if args.image else 'state'}/delta, batch {args.batch_size}", flush=True)
    rows = agent_rows(args.env, args.widths, args.agents, args.rounds, args.updates, args.learn_steps,
                      args.batch_size, log=lambda s: print(s, flush=True),
                      image_agents=args.image_agents if args.image else ())
    print(json.dumps(rows, indent=1)) if args.json else _print(rows)
    if hasattr(os, "getloadavg"):
        print(f"load average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
