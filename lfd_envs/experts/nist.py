"""Scripted demonstrator for ``NistBoardInsert-v0`` with recovery from failed insertions.

The thesis (ch. 6) found that free-space demonstrations alone were not enough and added
demonstrations that recover from a failed insertion. This expert does both:

1. *approach*: move the commanded tip position above the hole (6 mm over the board),
2. *descend*: go down (slowing to ≤ 1.5 mm per control step over the last 5 mm above the
   board) and press to the bottom of the hole,
3. if the peg is *blocked* (it rests on the board while the compliance target is pressed
   3 mm below it) or *jammed* (no progress inside the hole), *back off* 6 mm above the board,
   re-align on the hole axis and descend again.

On a fraction ``recovery_prob`` of episodes the first attempt is deliberately misaligned by
``clearance + U(1, 3) mm`` in a random direction, so the peg hits the board and the expert
recovers. Which episodes are misaligned is a deterministic function of ``seed`` and the env's
variant id, so the same variant always gives the same demonstration.

The expert reads the privileged simulator state of ``env.unwrapped`` (hole position, tip
position, commanded target) and works with both action modes and any ``action_repeat``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from lfd_envs.core.rollout import play_episode
from lfd_envs.mujoco.nist import ACTION_BIN
from lfd_envs.experts.episodes import EpisodeTracker

APPROACH_HEIGHT = 0.006
SLOW_ZONE = 0.005
SLOW_SPEED = 0.0015
PRESS_DEPTH = 0.003
BLOCK_PRESS = 0.003
STALL_STEPS = 6


class NistInsertExpert:
    """Scripted insertion with deliberate misaligned first attempts and recovery.

    Args:
        env: a ``NistBoardInsert-v0`` env (wrappers allowed).
        recovery_prob: probability that an episode starts with a misaligned attempt.
        misalign_range: extra lateral offset beyond the clearance for that attempt (m).
        seed: seed of the per-variant misalignment draws.
    """

    def __init__(self, env: gym.Env, recovery_prob: float = 0.3,
                 misalign_range: tuple[float, float] = (0.001, 0.003), seed: int = 0) -> None:
        if not 0.0 <= float(recovery_prob) <= 1.0:
            raise ValueError(f"recovery_prob must be in [0, 1], got {recovery_prob}")
        lo, hi = (float(v) for v in misalign_range)
        if not 0.0 < lo <= hi:
            raise ValueError(f"misalign_range must be (low, high) with 0 < low <= high, got {misalign_range}")
        self.env = env
        self.recovery_prob = float(recovery_prob)
        self.misalign_range = (lo, hi)
        self.seed = int(seed)
        self._fresh = True
        self._episodes = EpisodeTracker(env)
        self.phase = "approach"
        self.offset = np.zeros(2)
        self.attempts = 0
        self.recovered = False

    # ------------------------------------------------------------------ episode state
    def reset(self) -> None:
        """Start a new episode (done by itself when the env starts a new episode)."""
        self._fresh = True

    def _start_episode(self) -> None:
        e = self.env.unwrapped
        split, k = e.variant
        rng = np.random.default_rng([self.seed, int(e.variants.global_id(split, k))])
        misalign = rng.random() < self.recovery_prob
        angle = rng.uniform(0.0, 2.0 * np.pi)
        extra = rng.uniform(*self.misalign_range)
        self.offset = np.zeros(2)
        if misalign:
            self.offset = (e.clearance + extra) * np.array([np.cos(angle), np.sin(angle)])
            if e.action_mode == "tokens":  # keep the goal on the reachable lattice
                lattice = ACTION_BIN * e.action_repeat
                self.offset = np.round(self.offset / lattice) * lattice
        self.phase = "approach"
        self.attempts = 0
        self.recovered = False
        self._stall = 0
        self._best_depth = np.inf
        self._fresh = False

    # ------------------------------------------------------------------ policy
    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """Action for the current env state (the observation itself is not used)."""
        e = self.env.unwrapped
        if self._episodes.new_episode() or self._fresh or bool(np.any(episode_start)):
            self._start_episode()
        goal = self._goal(e)
        repeat = e.action_repeat
        target = e.commanded_target
        step = np.full(3, e.max_delta)
        if self.phase == "descend" and e.tip_position[2] < e.hole_top[2] + SLOW_ZONE:
            step[2] = min(step[2], SLOW_SPEED)
        delta = np.clip((goal - target) / repeat, -step, step)
        return e.action_from_delta(delta), None

    def _goal(self, e: Any) -> np.ndarray:
        """Advance the phase machine and return the commanded-position goal."""
        hole, tip, target = e.hole_top, e.tip_position, e.commanded_target
        lattice = ACTION_BIN * e.action_repeat  # smallest token motion per env step
        tol = 0.5 * lattice + 1e-9 if e.action_mode == "tokens" else 1e-6
        above = np.array([*(hole[:2] + self.offset), hole[2] + APPROACH_HEIGHT])
        if self.phase == "approach":
            settled = np.linalg.norm(tip[:2] - target[:2]) < min(0.25 * e.clearance, 1e-4)
            if np.all(np.abs(above[:2] - target[:2]) <= tol) and abs(above[2] - target[2]) <= lattice + 1e-9 and settled:
                self.phase, self._stall, self._best_depth = "descend", 0, np.inf
            else:
                return above
        if self.phase == "descend":
            if self._failed(e, hole, tip, target):
                self.phase = "backoff"
                self.attempts += 1
            else:
                return np.array([*(hole[:2] + self.offset), hole[2] - e.hole_depth - PRESS_DEPTH])
        # backoff: straight up, then re-aligned approach
        up = np.array([target[0], target[1], hole[2] + APPROACH_HEIGHT])
        if tip[2] >= hole[2] + APPROACH_HEIGHT - 2 * ACTION_BIN:
            self.offset = np.zeros(2)
            self.recovered = True
            self.phase = "approach"
            return np.array([hole[0], hole[1], hole[2] + APPROACH_HEIGHT])
        return up

    def _failed(self, e: Any, hole: np.ndarray, tip: np.ndarray, target: np.ndarray) -> bool:
        """Blocked on the board, or stalled inside the hole (jammed)."""
        pressing = target[2] < tip[2] - BLOCK_PRESS
        if tip[2] > hole[2] - 0.0005 and pressing:
            return True
        depth = tip[2]
        if depth < self._best_depth - 5e-5:
            self._best_depth, self._stall = depth, 0
        elif pressing:
            self._stall += 1
        return self._stall >= STALL_STEPS and not e._is_success()


def success_rates(fit: str = "loose", action_mode: str = "continuous", episodes: int = 50,
                  recovery_prob: float = 0.3, action_repeat: int = 1) -> dict[str, dict[str, float]]:
    """Expert success rate, recovery count and mean length per task (state observations)."""
    from lfd_envs.mujoco.nist import NistBoardInsertEnv, all_tasks

    out = {}
    for task in all_tasks(fit):
        env = NistBoardInsertEnv(instruction=task, fit=fit, obs_mode="state", action_mode=action_mode,
                                 action_repeat=action_repeat)
        expert = NistInsertExpert(env, recovery_prob=recovery_prob)
        wins, recovered, lengths = 0, 0, []
        for seed in range(int(episodes)):
            info = play_episode(env, expert, seed=seed)
            wins += bool(info["is_success"])
            recovered += expert.recovered
            lengths.append(env.elapsed_steps)
        out[task] = {"success_rate": wins / episodes, "recovered_episodes": recovered,
                     "mean_length": float(np.mean(lengths))}
    return out


def main(argv: list[str] | None = None) -> None:
    """``python -m lfd_envs.experts.nist [--fit tight] [--action-mode tokens] [--episodes 100]``."""
    import argparse

    parser = argparse.ArgumentParser(description="Success rate of the NIST insertion expert per task")
    parser.add_argument("--fit", default="loose", choices=("loose", "tight"))
    parser.add_argument("--action-mode", default="continuous", choices=("continuous", "tokens"))
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--recovery-prob", type=float, default=0.3)
    parser.add_argument("--action-repeat", type=int, default=1)
    args = parser.parse_args(argv)
    rates = success_rates(args.fit, args.action_mode, args.episodes, args.recovery_prob, args.action_repeat)
    for task, r in rates.items():
        print(f"{task:36s} success {r['success_rate']:.3f}  recovered {r['recovered_episodes']:3d}  "
              f"mean length {r['mean_length']:.1f}")


if __name__ == "__main__":
    main()


__all__ = ["NistInsertExpert", "success_rates"]
