"""Command line for MAIL stages.

    python -m lfd_agents.mail teacher --env ThreeBoxes-v0 --pickers 3 --episodes 20 --out work/teacher
    python -m lfd_agents.mail run --env ThreeBoxes-v0 --student-pickers 1 --teacher work/teacher/... \
        --workdir work/mail --stage convert --backend simulator
"""

from __future__ import annotations

import argparse
import json
import sys

from lfd_agents.mail.cem import CEMConfig
from lfd_agents.mail.pipeline import MAIL, STAGES, MAILConfig


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m lfd_agents.mail", description="MAIL stages (resumable)")
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("teacher", help="collect teacher demonstrations with the scripted expert")
    t.add_argument("--env", required=True)
    t.add_argument("--pickers", type=int, required=True)
    t.add_argument("--episodes", type=int, default=20)
    t.add_argument("--out", required=True)
    r = sub.add_parser("run", help="run MAIL stages up to --stage (earlier stages resume from disk)")
    r.add_argument("--env", required=True, help="student env id")
    r.add_argument("--student-pickers", type=int, required=True)
    r.add_argument("--teacher", required=True, help="teacher dataset folder")
    r.add_argument("--workdir", required=True)
    r.add_argument("--stage", choices=STAGES, default="student")
    r.add_argument("--backend", choices=["learned", "simulator"], default="learned")
    r.add_argument("--random-transitions", type=int, default=300)
    r.add_argument("--epochs", type=int, default=60)
    r.add_argument("--population", type=int, default=200)
    r.add_argument("--iterations", type=int, default=2)
    r.add_argument("--max-demos", type=int)
    r.add_argument("--timesteps", type=int, default=10_000)
    args = p.parse_args(argv)
    if args.cmd == "teacher":
        from lfd_envs import datasets

        path = datasets.collect(args.env, args.episodes, args.out,
                                env_kwargs={"num_pickers": args.pickers, "action_mode": "pick_place",
                                            "obs_mode": "particles"})
        print(path)
        return 0
    cfg = MAILConfig(backend=args.backend, random_transitions=args.random_transitions, dynamics_epochs=args.epochs,
                     cem=CEMConfig(population=args.population, iterations=args.iterations))
    mail = MAIL(args.env, args.teacher, args.workdir, {"num_pickers": args.student_pickers}, cfg)
    stage = STAGES.index(args.stage)
    if stage >= 0 and args.backend == "learned":
        mail.random_data()
    if stage >= 1 and args.backend == "learned":
        mail.dynamics()
    if stage >= 2:
        stats = mail.convert(max_demos=args.max_demos)
        print(json.dumps({k: v for k, v in stats.items() if k != "finals"}, indent=1))
    if stage >= 3:
        mail.student(args.timesteps)
        print(f"student policy: {mail.policy_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
