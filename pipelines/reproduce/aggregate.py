"""Few-seed statistics that look at every run rather than at seed means: the interquartile mean, the probability
of improvement and stratified bootstrap intervals, after Agarwal et al., "Deep RL at the edge of the statistical
precipice" (NeurIPS 2021; the `rliable` package).

Why beside the Welch tests: with 2-5 seeds a t-test leans on normality and a mean leans on its outliers. The
interquartile mean (the mean of the middle half of the runs) is robust to one bad seed, and the probability of
improvement, P(X > Y) for a run X of one agent and a run Y of another, says how often one agent's run beats the
other's, with no assumption on the shape of either. Both get percentile intervals from a stratified bootstrap:
runs are resampled with replacement within each game row (stratum), never across, so every resample keeps each
game's number of runs, as rliable does.

Scores are pooled over games without normalising: task success and dialogue length have the same meaning on every
game row, and a game row is a stratum only when both agents compared have runs in it.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

BOOTSTRAP_REPS = 2000
BOOTSTRAP_SEED = 0  # fixed: the same runs give the same intervals
CONFIDENCE = 0.95

Strata = Sequence[Sequence[float]]  # one sequence of run scores per game row


def iqm(scores: Sequence[float]) -> float:
    """Interquartile mean: the mean of the runs left after cutting a quarter (rounded down) from each end, as
    rliable computes it (`scipy.stats.trim_mean(scores, 0.25)`; 5 runs give the mean of the middle 3)."""
    from scipy.stats import trim_mean

    values = np.asarray(scores, dtype=float).ravel()
    if values.size == 0:
        raise ValueError("the interquartile mean needs at least one score")
    return float(trim_mean(values, 0.25))


def probability_of_improvement(larger: Strata, smaller: Strata) -> float:
    """P(X > Y) averaged over strata: in each stratum, the share of (run of ``larger``, run of ``smaller``) pairs in
    which the first scores higher, ties counting half (the Mann-Whitney U statistic over m·n); rliable's definition."""
    _check_strata(larger, smaller)
    return float(np.mean([_p_greater(np.asarray(a, float)[None, :], np.asarray(b, float)[None, :])[0]
                          for a, b in zip(larger, smaller)]))


def _p_greater(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise P(X > Y) + P(X = Y)/2 for samples a (reps, m) and b (reps, n)."""
    diff = a[:, :, None] - b[:, None, :]
    return ((diff > 0).mean(axis=(1, 2)) + 0.5 * (diff == 0).mean(axis=(1, 2)))


def _check_strata(*sides: Strata) -> None:
    counts = {len(side) for side in sides}
    if len(counts) != 1 or 0 in counts:
        raise ValueError(f"every side needs runs in the same, non-empty list of strata; got {sorted(counts)} strata")
    if any(len(runs) == 0 for side in sides for runs in side):
        raise ValueError("every stratum needs at least one run on every side")


def _resampled(runs: Sequence[float], reps: int, rng: np.random.Generator) -> np.ndarray:
    """(reps, n): each row n runs drawn with replacement from the stratum's n runs."""
    values = np.asarray(runs, dtype=float)
    return values[rng.integers(0, values.size, size=(reps, values.size))]


def _percentile(draws: np.ndarray, confidence: float) -> tuple[float, float]:
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(draws, [tail, 100 - tail])
    return float(low), float(high)


def iqm_interval(strata: Strata, reps: int = BOOTSTRAP_REPS, seed: int = BOOTSTRAP_SEED,
                 confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """(IQM over every run of every stratum, low, high): the percentile interval of a stratified bootstrap."""
    from scipy.stats import trim_mean

    _check_strata(strata)
    rng = np.random.default_rng(seed)
    draws = np.concatenate([_resampled(runs, reps, rng) for runs in strata], axis=1)
    point = iqm(np.concatenate([np.asarray(runs, float) for runs in strata]))
    return (point, *_percentile(trim_mean(draws, 0.25, axis=1), confidence))


def improvement_interval(larger: Strata, smaller: Strata, reps: int = BOOTSTRAP_REPS, seed: int = BOOTSTRAP_SEED,
                         confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """(P(larger's run > smaller's run), low, high): both sides resampled within each stratum, independently."""
    _check_strata(larger, smaller)
    rng = np.random.default_rng(seed)
    per_stratum = [_p_greater(_resampled(a, reps, rng), _resampled(b, reps, rng)) for a, b in zip(larger, smaller)]
    return (probability_of_improvement(larger, smaller), *_percentile(np.mean(per_stratum, axis=0), confidence))


def performance_profile(scores: Sequence[float], thresholds: Sequence[float]) -> np.ndarray:
    """The share of runs scoring above each threshold (rliable's run-score distribution)."""
    values = np.asarray(scores, dtype=float).ravel()
    if values.size == 0:
        raise ValueError("a performance profile needs at least one score")
    return (values[None, :] > np.asarray(thresholds, dtype=float)[:, None]).mean(axis=1)


def interval_text(found: tuple[float, float, float]) -> str:
    """(point, low, high) as the reports print a probability and its interval: "0.76 [0.40, 1.00]"."""
    return f"{found[0]:.2f} [{found[1]:.2f}, {found[2]:.2f}]"


def reading(low: float, high: float) -> str:
    """What an interval of P(X > Y) says of "X beats Y": above 1/2 as claimed, below against it, else neither."""
    return "as claimed" if low > 0.5 else ("against the claim" if high < 0.5 else "not separated")
