"""Random pick-and-place policy for dynamics-model data (MAIL's random-action datasets).

Every action picks something random and places it somewhere random: the task decides what
that means through ``task.sample_pick_place(positions, ctx, rng) -> (pick (P, 3), place (P, 3))``
in metres (DryCloth: a random cloth particle to a random point around the plank; ThreeBoxes:
a random box to a random point of the line). Tasks without that method get
:func:`default_sample_pick_place`: a random particle per picker, placed at a uniformly random
point of the workspace on the table (MAIL's ClothFold / rope random actions).

The policy is a :class:`~lfd_envs.experts.picker_expert.PickerExpert`, so it works in both
action modes (``pick_place``: one random move per step; ``delta``: each random move is executed
by the closed-loop state machine). Seeding: after every ``env.reset(seed=s, ...)`` and
``policy.reset()`` the moves depend only on ``(seed, s, variant)``, so datasets are reproducible.

Use it through :mod:`lfd_envs.datasets` (``policy="random_pick_place"``) or directly::

    policy = random_pick_place_policy(env, seed=0)
    obs, info = env.reset(seed=1); policy.reset()
    action, _ = policy.predict(obs)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfd_envs.experts.picker_expert import Move, PickerExpert

__all__ = ["RandomPickPlacePolicy", "random_pick_place_policy", "default_sample_pick_place"]


def default_sample_pick_place(task: Any, positions: np.ndarray, workspace: Any,
                              rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random particle per picker, placed at a random workspace point on the table."""
    p = task.num_pickers
    pick = np.asarray(positions, np.float64)[rng.integers(len(positions), size=p)].copy()
    lo, hi = workspace.lo + workspace.margin, workspace.hi - workspace.margin
    place = rng.uniform(lo, hi, size=(p, 3))
    place[:, 2] = lo[2]
    return pick, place


class RandomPickPlacePolicy(PickerExpert):
    """Random pick-and-place moves (see module docstring).

    Args:
        env: A particle env (wrappers allowed).
        seed: Policy seed, combined with the env's reset seed and variant.
    """

    def __init__(self, env: Any, seed: int = 0, **kwargs: Any) -> None:
        self.seed = int(seed)
        self._fallback = np.random.default_rng(self.seed)
        super().__init__(env, **kwargs)

    def reset(self) -> None:
        super().reset()
        base = getattr(self, "base", None)
        if base is None:
            self.rng = self._fallback
            return
        env_seed = getattr(base, "np_random_seed", None)
        if env_seed is None or int(env_seed) < 0:
            self.rng = self._fallback
        else:
            variant = base.variants.global_id(*base.variant) if base.variant[1] >= 0 else 0
            self.rng = np.random.default_rng([self.seed, int(env_seed), int(variant)])

    def sample(self) -> tuple[np.ndarray, np.ndarray]:
        """Pick and place points ``(P, 3)`` of the next random move."""
        sampler = getattr(self.task, "sample_pick_place", None)
        if sampler is None:
            return default_sample_pick_place(self.task, self.positions, self.workspace, self.rng)
        ctx = {k: v[0] for k, v in self.base.batch.ctx.items()}
        return sampler(self.positions, ctx, self.rng)

    def next_move(self) -> Move | None:
        pick, place = self.sample()
        pick = np.asarray(pick, np.float64).copy()
        pick[:, 2] = np.where(pick[:, 2] < 0.03, 0.0, pick[:, 2])  # on the table: go as low as possible
        return Move(pick, place)


def random_pick_place_policy(env: Any, seed: int = 0) -> RandomPickPlacePolicy:
    """Factory for :data:`lfd_envs.datasets.POLICIES` (``"random_pick_place"``)."""
    return RandomPickPlacePolicy(env, seed=seed)
