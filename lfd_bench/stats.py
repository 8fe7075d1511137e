"""Statistics for the leaderboard.

* The thesis table: 25th percentile, mean ± std, median and 75th percentile of the final
  normalised performance p̂(H) over evaluation episodes × seeds (plain numpy).
* Interval estimates from ``rliable``: interquartile mean (IQM) and mean with
  stratified-bootstrap 95% confidence intervals, performance profiles and the probability of
  improvement. Score matrices follow rliable's convention: shape ``(runs, tasks)``, and a run is
  one training seed (its evaluation episodes averaged), never one episode.

Bootstraps use a fixed seed, so a leaderboard regenerated from the same results is identical.
rliable's stratified bootstrap draws its resampling indices from NumPy's global generator (the
``random_state`` it passes on is not used for them), so every bootstrap here runs inside
:func:`seeded_global_rng`, which seeds that generator and restores the caller's state afterwards.
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np

#: bootstrap replications for every interval (rliable's default of 50000 is minutes per table)
REPS = 2000
#: replications of the probability of improvement (a Mann-Whitney statistic per replication: slower)
POI_REPS = 1000
SEED = 0


@contextmanager
def seeded_global_rng(seed: int = SEED) -> Iterator[None]:
    """Seed NumPy's global generator for the block and restore its previous state afterwards."""
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


@contextmanager
def _bootstrap() -> Iterator[None]:
    """The setting of every rliable bootstrap here: global generator seeded (and restored),
    arch's ``RandomState`` deprecation notice and degenerate-sample warnings silenced."""
    with warnings.catch_warnings(), seeded_global_rng():
        warnings.simplefilter("ignore", FutureWarning)  # arch's RandomState deprecation notice
        warnings.simplefilter("ignore", RuntimeWarning)  # degenerate (constant) bootstrap samples
        yield


def _rliable():
    from rliable import library as rly
    from rliable import metrics

    return rly, metrics


def _scores(values: np.ndarray) -> np.ndarray:
    x = np.asarray(values, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.size == 0:
        raise ValueError(f"scores must be a non-empty (runs, tasks) array, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("scores must be finite")
    return x


def interval_estimates(score_dict: Mapping[str, np.ndarray], func: Callable[[np.ndarray], np.ndarray]
                       ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """rliable point estimates and stratified-bootstrap 95% CIs of ``func`` for each entry."""
    rly, _ = _rliable()
    scores = {k: _scores(v) for k, v in score_dict.items()}
    with _bootstrap():
        return rly.get_interval_estimates(scores, func, reps=REPS, random_state=np.random.RandomState(SEED))


def iqm_and_mean(score_dict: Mapping[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """``{name: {iqm, iqm_ci_low, iqm_ci_high, mean, mean_ci_low, mean_ci_high}}`` (rliable)."""
    _, metrics = _rliable()
    point, ci = interval_estimates(
        score_dict, lambda x: np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x)]))
    return {k: {"iqm": float(point[k][0]), "iqm_ci_low": float(ci[k][0, 0]), "iqm_ci_high": float(ci[k][1, 0]),
                "mean": float(point[k][1]), "mean_ci_low": float(ci[k][0, 1]), "mean_ci_high": float(ci[k][1, 1])}
            for k in point}


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """P(X > Y) of rliable (Mann-Whitney statistic averaged over tasks) with its 95% CI."""
    rly, metrics = _rliable()
    with _bootstrap():
        point, ci = rly.get_interval_estimates({"pair": [_scores(x), _scores(y)]}, metrics.probability_of_improvement,
                                               reps=POI_REPS, random_state=np.random.RandomState(SEED))
    return float(np.ravel(point["pair"])[0]), float(np.ravel(ci["pair"])[0]), float(np.ravel(ci["pair"])[-1])


def performance_profiles(score_dict: Mapping[str, np.ndarray], taus: np.ndarray
                         ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Fraction of runs with score > τ for each τ, with stratified-bootstrap CIs (rliable)."""
    rly, _ = _rliable()
    scores = {k: _scores(v) for k, v in score_dict.items()}
    with _bootstrap():  # create_performance_profile takes no random_state
        return rly.create_performance_profile(scores, taus, reps=REPS)


@dataclass
class Summary:
    """Final normalised performances p̂(H) of one agent on one env: the thesis's percentiles over
    every evaluation episode of every seed, and interval estimates with **seeds as runs** (each
    seed's episodes averaged first, as rliable recommends: episodes of one seed are not independent
    runs of the training)."""

    n: int  #: evaluation episodes in all
    seeds: int
    p25: float
    mean: float
    std: float
    median: float
    p75: float
    seed_means: list[float]  #: mean p̂ of each seed's episodes, in seed order
    iqm: float  #: IQM of the per-seed means
    iqm_ci_low: float
    iqm_ci_high: float
    mean_ci_low: float  #: CI of the mean of the per-seed means (the point estimate is ``mean``)
    mean_ci_high: float

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def summarize(per_seed: Sequence[Sequence[float]]) -> Summary:
    """Thesis percentiles (numpy, over all episodes) and IQM / mean with bootstrap CIs (rliable,
    seeds as runs) of ``per_seed``: one sequence of episode scores per seed. With one seed the
    interval has zero width (one run says nothing about the spread between runs)."""
    seeds = [np.asarray(v, dtype=np.float64).ravel() for v in per_seed]
    if not seeds or any(v.size == 0 for v in seeds):
        raise ValueError("cannot summarise an empty set of results (every seed needs episodes)")
    x = np.concatenate(seeds)
    means = np.array([v.mean() for v in seeds])
    est = iqm_and_mean({"x": means})["x"]
    return Summary(
        n=int(x.size),
        seeds=len(seeds),
        p25=float(np.percentile(x, 25)),
        mean=float(np.mean(x)),
        std=float(np.std(x)),
        median=float(np.median(x)),
        p75=float(np.percentile(x, 75)),
        seed_means=[float(m) for m in means],
        iqm=est["iqm"],
        iqm_ci_low=est["iqm_ci_low"],
        iqm_ci_high=est["iqm_ci_high"],
        mean_ci_low=est["mean_ci_low"],
        mean_ci_high=est["mean_ci_high"],
    )
