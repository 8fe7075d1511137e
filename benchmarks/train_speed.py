"""Training throughput of the demonstration agents (DMfD) on a particle task.

For each observation type (reduced state, 32×32 image) it measures, with the SPEC §6 network
sizes (1024-1024, batch 256) unless told otherwise:

* ``env_steps_per_s`` — env steps with random actions (simulation + rendering only);
* ``grad_steps_per_s`` — DMfD gradient steps (critic + actor + target update) on a filled buffer;
* ``train_steps_per_s`` — ``DMfD.learn`` with one gradient step per env step (the real loop);
  each such step is one env step *and* one gradient step.

Usage::

    python -m benchmarks.train_speed [--device cpu|cuda] [--env ClothFoldDiagonalPinned-v0]
        [--steps 200] [--grad-steps 50] [--resolution 40] [--obs state image]

``agent_rows(...)`` returns the rows for ``benchmarks.speed`` tables.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from typing import Any, Sequence

import numpy as np


def _make_env(env_id: str, obs_mode: str, resolution: int | None, device: str | None):
    import gymnasium as gym

    import lfd_envs  # noqa: F401

    kwargs: dict[str, Any] = dict(obs_mode=obs_mode, action_mode="delta")
    if obs_mode != "state":
        kwargs["image_size"] = 32
    if resolution is not None:
        kwargs["resolution"] = resolution
    if device is not None:
        try:
            return gym.make(env_id, device=device, **kwargs)
        except TypeError:
            pass
    return gym.make(env_id, **kwargs)


def _rate(n: int, seconds: float) -> float:
    return float(n / seconds) if seconds > 0 else float("nan")


def agent_rows(env_id: str = "ClothFoldDiagonalPinned-v0", obs_modes: Sequence[str] = ("state", "image"),
               device: str = "cpu", steps: int = 200, grad_steps: int = 50, batch_size: int = 256,
               net_arch: Sequence[int] = (1024, 1024), resolution: int | None = None,
               sim_device: str | None = None, seed: int = 0) -> list[dict[str, Any]]:
    """Throughput rows (one per observation mode) for DMfD on ``env_id``; see module docstring."""
    import torch as th

    from lfd_agents import DMfD

    rows = []
    for obs_mode in obs_modes:
        env = _make_env(env_id, obs_mode, resolution, sim_device)
        rng = np.random.default_rng(seed)
        env.reset(seed=seed)
        env.step(env.action_space.sample())  # warm-up (kernel loads)
        t0 = time.perf_counter()
        for _ in range(steps):
            _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
            if term or trunc:
                env.reset()
        env_rate = _rate(steps, time.perf_counter() - t0)

        policy = "MlpPolicy" if obs_mode == "state" else ("CnnPolicy" if obs_mode == "image" else "MultiInputPolicy")
        model = DMfD(policy, env, buffer_size=max(10 * steps, 2 * batch_size), batch_size=batch_size,
                     learning_starts=max(steps, batch_size), rsi_prob=0.0, device=device, seed=seed,
                     policy_kwargs=dict(net_arch=list(net_arch)))
        model.learn(max(steps, batch_size))  # random-action warm-up fills the buffer, no training
        model.train(3, batch_size)  # warm-up
        if device.startswith("cuda"):
            th.cuda.synchronize()
        t0 = time.perf_counter()
        model.train(grad_steps, batch_size)
        if device.startswith("cuda"):
            th.cuda.synchronize()
        grad_rate = _rate(grad_steps, time.perf_counter() - t0)

        model.learning_starts = 0
        t0 = time.perf_counter()
        model.learn(steps, reset_num_timesteps=False)
        train_rate = _rate(steps, time.perf_counter() - t0)
        obs_name = obs_mode if obs_mode == "state" else f"{obs_mode} 32x32"
        rows.append({"agent": "DMfD", "env": env_id, "obs": obs_name,
                     "device": device, "net": "-".join(map(str, net_arch)), "batch": batch_size,
                     "env_steps_per_s": round(env_rate, 1), "grad_steps_per_s": round(grad_rate, 1),
                     "train_steps_per_s": round(train_rate, 1)})
        env.close()
    return rows


def _print(rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    keys = list(rows[0])
    print(" | ".join(keys))
    for r in rows:
        print(" | ".join(str(r[k]) for k in keys))


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--env", default="ClothFoldDiagonalPinned-v0")
    p.add_argument("--obs", nargs="+", default=["state", "image"])
    p.add_argument("--device", default="cpu", help="torch device of the networks")
    p.add_argument("--sim-device", default=None, help="Warp device of the simulator (env default when omitted)")
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--grad-steps", type=int, default=50)
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--net", type=int, nargs="+", default=[1024, 1024])
    p.add_argument("--resolution", type=int, default=None)
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    import torch as th

    if args.threads:
        th.set_num_threads(args.threads)
    print(f"python {platform.python_version()}, torch {th.__version__}, {platform.processor() or platform.machine()}, "
          f"torch threads {th.get_num_threads()}, cuda {th.cuda.get_device_name(0) if th.cuda.is_available() else 'none'}")
    rows = agent_rows(args.env, args.obs, args.device, args.steps, args.grad_steps, args.batch_size, args.net,
                      args.resolution, args.sim_device)
    print(json.dumps(rows, indent=1)) if args.json else _print(rows)


if __name__ == "__main__":
    main()
