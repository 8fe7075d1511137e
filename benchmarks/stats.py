"""Statistics for the leaderboard: thesis-style percentiles and rliable-style IQM with CIs."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


def iqm(values: np.ndarray) -> float:
    """Interquartile mean: mean of the middle 50% of the sorted values.

    Uses the trimmed-mean definition of rliable (25% cut from each end, fractional
    observations weighted), which equals the plain mean for n < 4 only when no cut applies.
    """
    x = np.sort(np.asarray(values, dtype=np.float64).ravel())
    n = x.size
    if n == 0:
        raise ValueError("iqm of an empty array")
    lo, hi = 0.25 * n, 0.75 * n
    # weight of each sorted sample inside [lo, hi)
    idx = np.arange(n)
    w = np.clip(np.minimum(idx + 1, hi) - np.maximum(idx, lo), 0.0, 1.0)
    return float(np.sum(w * x) / np.sum(w))


def bootstrap_ci(values: np.ndarray, statistic=iqm, confidence: float = 0.95, n_boot: int = 2000,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of ``statistic`` (fixed seed: reproducible)."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        raise ValueError("bootstrap of an empty array")
    rng = np.random.default_rng(seed)
    samples = x[rng.integers(0, x.size, size=(n_boot, x.size))]
    stats = np.array([statistic(s) for s in samples])
    alpha = (1.0 - confidence) / 2
    return float(np.quantile(stats, alpha)), float(np.quantile(stats, 1 - alpha))


@dataclass
class Summary:
    """Summary of final normalised performances p̂(H) over eval episodes × seeds."""

    n: int
    p25: float
    mean: float
    std: float
    median: float
    p75: float
    iqm: float
    iqm_ci_low: float
    iqm_ci_high: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def summarize(values: np.ndarray) -> Summary:
    """All leaderboard statistics of ``values``."""
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        raise ValueError("cannot summarise an empty set of results")
    lo, hi = bootstrap_ci(x)
    return Summary(
        n=int(x.size),
        p25=float(np.percentile(x, 25)),
        mean=float(np.mean(x)),
        std=float(np.std(x)),
        median=float(np.median(x)),
        p75=float(np.percentile(x, 75)),
        iqm=iqm(x),
        iqm_ci_low=lo,
        iqm_ci_high=hi,
    )
