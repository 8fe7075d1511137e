"""MAIL benchmark: learned particle dynamics vs the simulator, CEM cost, and the transfers.

    python -m benchmarks.mail_bench                 # small settings, ~5-10 min on 2 shared cores
    python -m benchmarks.mail_bench --cloth-resolution 40 --demos 5 --population 32

Prints markdown tables:

1. **Dynamics** (ThreeBoxes, ClothFold; 1 picker): the learned model is trained on
   ``--train-transitions`` random pick-and-place transitions (batched collection with
   exploration, :mod:`lfd_agents.mail.data`) and evaluated on ``--test-transitions`` held-out
   transitions from the *eval* variants (plain random pick-and-place, like MAIL's random
   dataset). Error = mean per-particle distance and symmetric chamfer distance of the predicted
   next state (model particles) vs the true one; "zero motion" is the error of predicting that
   nothing moves (= the mean particle motion). Speed = one-step predictions per second through
   the CEM backends (learned: batches of 256 sequences; simulator: batches of ``--worlds``
   worlds, including the state restore).
2. **Transfers** 2→1 (ClothFold, DryCloth) and 3→2, 3→1 (ThreeBoxes): ``--demos`` teacher
   demos (scripted expert) are converted with CEM (population ``--population``, 1 iteration,
   horizon 2, teacher warm start) on the simulator backend (all) and the learned backend
   (ClothFold 2→1, ThreeBoxes 3→1, with the model of table 1), replayed in the simulator and
   thresholded at p̂ > 0.3. Reported: CEM wall time per demo, mean final p̂ of all converted
   episodes and of the kept student dataset, vs the mean final p̂ of ``--random-episodes``
   random pick-and-place episodes (the random-action dataset).

Cloth tasks run at ``--cloth-resolution`` particles per side (default 20, i.e. 400 particles,
to fit the time budget; the task default is 40 for ClothFold, 36 for DryCloth). The transfers
score ClothFold and DryCloth with MAIL's metrics (``metric="mail"``; DryCloth also with MAIL's
reach past the plank) unless ``--scoring default``. ``python -m tools.docs --tables mail``
writes these tables into ``docs/mail.md``.
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np


def _row(cells: list[Any]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _table(header: list[str], rows: list[list[Any]]) -> str:
    return "\n".join([_row(header), _row(["---"] * len(header))] + [_row(r) for r in rows])


def dynamics_benchmark(env_id: str, kwargs: dict[str, Any], args: argparse.Namespace, workdir: Path):
    """Train the model, measure error on held-out transitions and speed of both backends."""
    import gymnasium as gym

    from lfd_agents.mail import DynamicsConfig, LearnedBackend, LearnedDynamics, SimulatorBackend
    from lfd_agents.mail.data import chamfer, collect_transitions

    t0 = time.perf_counter()
    train = collect_transitions(env_id, kwargs, args.train_transitions, num_worlds=args.worlds, seed=args.seed)
    test = collect_transitions(env_id, kwargs, args.test_transitions, num_worlds=args.worlds, seed=args.seed + 10_000,
                               split="eval", explore=0.0, uniform=0.0)
    collect_s = time.perf_counter() - t0
    env = gym.make(env_id, action_mode="pick_place", obs_mode="particles", **kwargs)
    model = LearnedDynamics.for_env(env, DynamicsConfig(), seed=args.seed)
    t0 = time.perf_counter()
    model.fit(train["x"], train["actions"], train["x_next"], epochs=args.epochs)
    fit_s = time.perf_counter() - t0
    idx = model.indices
    pred = model.rollout(test["x"], test["actions"][:, None])  # one start state per sequence
    true, start = test["x_next"][:, idx], test["x"][:, idx]
    err = float(np.linalg.norm(pred - true, axis=-1).mean())
    motion = float(np.linalg.norm(start - true, axis=-1).mean())
    ch, ch0 = float(chamfer(pred, true).mean()), float(chamfer(start, true).mean())
    # speed through the CEM backends (one-step sequences from one start state)
    env.reset(seed=args.seed)
    start_state = env.unwrapped.get_state()
    learned = LearnedBackend(model)
    seqs = np.random.default_rng(0).uniform(-1, 1, (256, 1, model.config.action_dim)).astype(np.float32)
    learned.final_particles(start_state, seqs[:8])  # warm-up
    t0 = time.perf_counter()
    reps = 4
    for _ in range(reps):
        learned.final_particles(start_state, seqs)
    learned_tps = reps * len(seqs) / (time.perf_counter() - t0)
    sim = SimulatorBackend(env_id, kwargs, num_worlds=args.worlds)
    t0 = time.perf_counter()
    sim.final_particles(start_state, seqs[: args.worlds])
    sim_tps = args.worlds / (time.perf_counter() - t0)
    sim.close()
    row = [env_id, model.num_particles, len(idx), len(train["x"]), args.epochs, f"{collect_s:.0f}", f"{fit_s:.0f}",
           f"{err:.3f}", f"{motion:.3f}", f"{ch:.3f}", f"{ch0:.3f}", f"{learned_tps:.0f}", f"{sim_tps:.1f}",
           f"{learned_tps / sim_tps:.0f}x"]
    return model, row


def random_dataset_mean(env_id: str, kwargs: dict[str, Any], episodes: int, seed: int, out: Path) -> float:
    """Mean final p̂ of random pick-and-place episodes (the random-action dataset)."""
    from lfd_envs import datasets

    path = datasets.collect(env_id, episodes, out, env_kwargs={**kwargs, "action_mode": "pick_place",
                                                               "obs_mode": "state"},
                            policy="random_pick_place", seed=seed, progress=False, overwrite=True)
    return float(np.mean([ep.infos["normalized_performance"][-1] for ep in datasets.load(path).iterate_episodes()]))


def transfer_benchmark(env_id: str, teacher_pickers: int, student_kwargs: dict[str, Any], backends: dict[str, Any],
                       args: argparse.Namespace, workdir: Path) -> list[list[Any]]:
    """Convert teacher demos with each backend; rows of the transfer table."""
    from lfd_agents.mail import MAIL, CEMConfig, MAILConfig
    from lfd_envs import datasets

    m = student_kwargs["num_pickers"]
    tag = f"{env_id.split('-')[0]}_{teacher_pickers}to{m}"
    teacher = datasets.collect(env_id, args.demos, workdir / tag / "teacher", progress=False, seed=args.seed,
                               overwrite=True,
                               env_kwargs={**student_kwargs, "num_pickers": teacher_pickers,
                                           "action_mode": "pick_place", "obs_mode": "state"})
    rand = random_dataset_mean(env_id, student_kwargs, args.random_episodes, args.seed, workdir / tag / "random")
    rows = []
    for name, model in backends.items():
        cfg = MAILConfig(backend=name, cem=CEMConfig(population=args.population, iterations=1, horizon=2),
                         simulator_worlds=args.worlds, seed=args.seed)
        wd = workdir / tag / name
        wd.mkdir(parents=True, exist_ok=True)
        if model is not None:
            model.save(wd / "dynamics.pt")  # the dynamics stage resumes from it
        mail = MAIL(env_id, teacher, wd, student_kwargs, cfg)
        st = mail.convert()
        finals = np.asarray(st["finals"])
        kept = finals[finals > cfg.threshold]
        rows.append([f"{env_id} {teacher_pickers}→{m}", name, st["teacher_episodes"], f"{st['seconds_per_demo']:.1f}",
                     st["model_transitions"], f"{finals.mean():.2f}",
                     f"{kept.mean():.2f}" if len(kept) else "–", f"{len(kept)}/{len(finals)}", f"{rand:.2f}"])
        print(_row(rows[-1]), flush=True)
    return rows


DYNAMICS_HEADER = ["task", "particles", "model particles", "train transitions", "epochs", "collect s", "fit s",
                   "learned err (m)", "zero-motion err = mean motion (m)", "learned chamfer (m)",
                   "zero-motion chamfer (m)", "learned transitions/s", "simulator transitions/s", "speed-up"]
TRANSFER_HEADER = ["transfer", "backend", "demos", "CEM s/demo", "model transitions", "mean p̂ converted",
                   "mean p̂ student dataset (kept)", "kept", "mean p̂ random-action dataset"]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The benchmark's settings (defaults: the small settings of the module docstring)."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.mail_bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--cloth-resolution", type=int, default=20)
    p.add_argument("--train-transitions", type=int, default=240)
    p.add_argument("--test-transitions", type=int, default=100)
    p.add_argument("--epochs", type=int, default=40)
    p.add_argument("--worlds", type=int, default=16, help="batched simulator worlds")
    p.add_argument("--demos", type=int, default=3, help="teacher demos per transfer")
    p.add_argument("--population", type=int, default=16, help="CEM population")
    p.add_argument("--random-episodes", type=int, default=6)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workdir", help="keep outputs here (default: a temporary folder)")
    p.add_argument("--scoring", choices=("mail", "default"), default="mail",
                   help="mail (default): ClothFold and DryCloth scored with MAIL's metrics and DryCloth's pickers "
                        "reaching 0.1 m past the plank, as in the paper-mail suite; default: the tasks' defaults")
    return p.parse_args(argv)


def run_benchmark(args: argparse.Namespace) -> dict[str, Any]:
    """Both tables: ``{"dynamics": rows, "transfers": rows, "seconds": wall time}`` (rows as lists
    in the order of :data:`DYNAMICS_HEADER` / :data:`TRANSFER_HEADER`)."""
    import lfd_envs  # noqa: F401  (registers the env ids)

    workdir = Path(args.workdir or tempfile.mkdtemp(prefix="mail-bench-"))
    t_start = time.perf_counter()
    cloth = {"resolution": args.cloth_resolution}
    mail = args.scoring == "mail"
    fold = {"num_pickers": 1, **cloth, **({"metric": "mail"} if mail else {})}
    dry = {"num_pickers": 1, **cloth, **({"metric": "mail", "reach": 0.1} if mail else {})}
    models, dynamics = {}, []
    for env_id, kw in [("ThreeBoxes-v0", {"num_pickers": 1}), ("ClothFold-v0", {"num_pickers": 1, **cloth})]:
        models[env_id], row = dynamics_benchmark(env_id, kw, args, workdir)
        dynamics.append(row)
        print(_row(row), flush=True)
    transfers = []
    transfers += transfer_benchmark("ClothFold-v0", 2, fold, {"simulator": None, "learned": models["ClothFold-v0"]},
                                    args, workdir)
    transfers += transfer_benchmark("DryCloth-v0", 2, dry, {"simulator": None}, args, workdir)
    transfers += transfer_benchmark("ThreeBoxes-v0", 3, {"num_pickers": 2}, {"simulator": None}, args, workdir)
    transfers += transfer_benchmark("ThreeBoxes-v0", 3, {"num_pickers": 1},
                                    {"simulator": None, "learned": models["ThreeBoxes-v0"]}, args, workdir)
    return {"dynamics": dynamics, "transfers": transfers, "seconds": time.perf_counter() - t_start,
            "workdir": str(workdir)}


def main(argv: list[str] | None = None) -> int:
    import torch

    args = parse_args(argv)
    print(f"# MAIL benchmark\n\n{platform.platform()}, {platform.processor() or platform.machine()}, "
          f"torch {torch.__version__} (CPU), settings: {vars(args)}\n")
    out = run_benchmark(args)
    print("\n## Learned dynamics vs simulator (held-out eval-variant transitions)\n")
    print(_table(DYNAMICS_HEADER, out["dynamics"]))
    print("\n## Transfers (CEM conversion, replay in the simulator, threshold p̂ > 0.3)\n")
    print(_table(TRANSFER_HEADER, out["transfers"]))
    print(f"\ntotal wall time {out['seconds']:.0f} s; outputs in {out['workdir']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
