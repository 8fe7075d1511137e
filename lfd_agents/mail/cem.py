"""Cross-entropy method over action sequences, with warm-started model-predictive control.

Follows MAIL's optimiser (thesis Table D.8): a diagonal Gaussian over the whole sequence
(horizon × action_dim) starts at the centre of the bounds with variance (ub − lb)/4; each
iteration samples a population, clips it to the bounds, keeps the lowest-cost 10% (elites)
and refits mean and variance to them. Under MPC, the first action is executed, the mean is
shifted by one step (last slot reset to the centre) and the variance is reset.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

CostFn = Callable[[np.ndarray], np.ndarray]


@dataclass
class CEMConfig:
    """CEM hyper-parameters. ClothFold in MAIL: horizon 2, iterations 2, population 3750."""

    horizon: int = 2
    iterations: int = 2
    population: int = 200
    elite_fraction: float = 0.1
    low: float = -1.0
    high: float = 1.0
    seed: int = 0
    #: standard deviation around a warm-start mean (e.g. the teacher's actions); None = (ub − lb)/4 variance
    warm_std: float | None = 0.2

    def __post_init__(self) -> None:
        if self.horizon < 1 or self.iterations < 1 or self.population < 2:
            raise ValueError("horizon and iterations must be >= 1 and population >= 2")
        if not 0 < self.elite_fraction <= 1:
            raise ValueError(f"elite_fraction must be in (0, 1], got {self.elite_fraction}")
        if not self.low < self.high:
            raise ValueError("low must be < high")

    @property
    def num_elites(self) -> int:
        return max(1, int(round(self.population * self.elite_fraction)))


class CEM:
    """CEM optimiser over sequences of shape ``(horizon, action_dim)``.

    Args:
        action_dim: size of one action.
        config: hyper-parameters.
        constrain: optional function applied to every sampled population ``(P, H, d)`` (e.g. to
            fix a coordinate, as MAIL does for pick heights); must return the same shape.
    """

    def __init__(self, action_dim: int, config: CEMConfig | None = None,
                 constrain: Callable[[np.ndarray], np.ndarray] | None = None):
        self.config = config or CEMConfig()
        self.action_dim = int(action_dim)
        self.constrain = constrain
        self.rng = np.random.default_rng(self.config.seed)
        self.evaluations = 0

    def _initial(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        mean = np.full((c.horizon, self.action_dim), (c.high + c.low) / 2)
        var = np.full((c.horizon, self.action_dim), (c.high - c.low) / 4)
        return mean, var

    def optimize(self, cost_fn: CostFn, mean: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """Minimise ``cost_fn`` (batched: ``(P, H, d) -> (P,)``); returns the best sequence and its cost."""
        c = self.config
        init_mean, var = self._initial()
        if mean is None:
            mean = init_mean
        else:
            mean = np.array(mean, dtype=np.float64)
            if c.warm_std is not None:
                var = np.full_like(mean, c.warm_std ** 2)
        best, best_cost = mean.copy(), np.inf
        if mean.shape != var.shape:
            raise ValueError(f"mean must have shape {var.shape}, got {mean.shape}")
        for _ in range(c.iterations):
            samples = mean + self.rng.standard_normal((c.population,) + mean.shape) * np.sqrt(var)
            samples[0] = mean  # the current mean always competes (keeps a good warm start)
            samples = np.clip(samples, c.low, c.high)
            if self.constrain is not None:
                samples = self.constrain(samples)
            costs = np.asarray(cost_fn(samples), dtype=np.float64)
            self.evaluations += len(samples)
            order = np.argsort(costs, kind="stable")
            elites = samples[order[: c.num_elites]]
            if costs[order[0]] < best_cost:
                best, best_cost = samples[order[0]].copy(), float(costs[order[0]])
            mean, var = elites.mean(axis=0), elites.var(axis=0) + 1e-6
        return best, best_cost

    def plan_mpc(self, cost_fn_at: Callable[[int], CostFn], execute: Callable[[np.ndarray], None],
                 steps: int) -> list[np.ndarray]:
        """Receding-horizon control: re-plan at each of ``steps`` steps, execute the first action.

        ``cost_fn_at(t)`` returns the cost function from the current state at step ``t``
        (remaining horizon handled by the caller); the previous solution warm-starts the next.
        """
        executed = []
        warm = None
        for t in range(steps):
            seq, _ = self.optimize(cost_fn_at(t), mean=warm)
            execute(seq[0])
            executed.append(seq[0].copy())
            warm = np.concatenate([seq[1:], self._initial()[0][:1]], axis=0)
        return executed
