"""What ``make demo`` runs: pictures of every particle scene, then the smoke benchmark suite.

1. Renders each particle task (256×256, the project's own Warp ray-caster) after a reset
   and after its scripted expert has acted, side by side, into ``docs/images/<EnvId>.png``
   (the pictures in the README).
2. Runs ``python -m lfd_bench.run --suite smoke --force`` (real training at small budgets on
   a 2-core CPU, re-running the committed cells) which rewrites ``docs/leaderboard-smoke.md``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
IMAGES = ROOT / "docs" / "images"


def render_scenes(out_dir: Path = IMAGES) -> list[Path]:
    """Save ``<EnvId>.png`` (start frame | frame after the expert) of every particle task."""
    import gymnasium as gym
    import numpy as np

    import lfd_envs
    from lfd_envs.core.rollout import finish_episode
    from lfd_envs.experts import make_expert
    from lfd_envs.render import save_png

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for env_id in (i for i in lfd_envs.PARTICLE_ENV_IDS if i.endswith("-v0")):  # -v1: the same scenes
        try:
            env = gym.make(env_id, render_mode="rgb_array", obs_mode="state", action_mode="pick_place")
        except Exception as exc:  # a task that is not available in this build
            print(f"[demo] skipping {env_id}: {type(exc).__name__}: {exc}", file=sys.stderr)
            continue
        obs, _ = env.reset(seed=0, options={"split": "eval", "variant": 0})
        start = env.render()
        expert = make_expert(env)
        expert.reset()
        info = finish_episode(env, expert, obs)
        path = out_dir / f"{env_id}.png"
        save_png(path, np.stack([start, env.render()]))  # start | after the expert, side by side
        written.append(path)
        print(f"[demo] {env_id}: expert p̂ = {info.get('normalized_performance', float('nan')):.3f}")
        env.close()
    return written


def main(argv: list[str] | None = None) -> int:
    from lfd_bench import run

    t0 = time.perf_counter()
    files = render_scenes()
    print(f"[demo] wrote {len(files)} images to {IMAGES.relative_to(ROOT)} in {time.perf_counter() - t0:.0f} s")
    # --force: the committed leaderboard's cells exist already; the demo re-trains them for real
    code = run.main(["--suite", "smoke", "--force", "--leaderboard", str(ROOT / "docs" / "leaderboard-smoke.md"),
                     "--plot-dir", str(ROOT / "docs" / "leaderboard"), "--pages-dir", str(ROOT / "docs" / "results"),
                     *(argv or [])])
    print(f"[demo] done in {(time.perf_counter() - t0) / 60:.1f} min")
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
