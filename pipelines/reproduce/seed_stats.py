"""Intervals over seeds for results tables: Student t on the raw scale for unbounded metrics, on the logit scale
for proportions (so an interval of a rate never leaves [0, 1]), and prediction intervals for a single new run.

Why two kinds: a confidence interval says where the mean over training runs lies; a reader who asks whether a
paper's single run agrees with ours needs where ONE new run would land: mean ± t·s·√(1 + 1/n) (a prediction
interval), which is wider by √(n + 1).

Why the logit scale for proportions: with few seeds a raw t-interval of a rate near 1 reaches past 1 (and one of a
rate near 0 below 0). The interval is computed for logit(p) and mapped back, with each seed's rate pulled off
0 and 1 by half a game, (p·N + 0.5) / (N + 1) for N test games (the empirical logit), so a seed that won every
game still has a finite logit. The point estimate stays the plain mean over seeds; where one seed lies far from the
others that mean can fall outside the logit-scale interval, which is then marked (`Interval.mean_outside`) rather
than widened.
"""
from __future__ import annotations

import math
import statistics
from dataclasses import dataclass

CONFIDENCE = 0.95


def mean_and_variance(values: list[float]) -> tuple[float, float]:
    """(mean, sample variance) of n >= 2 values; identical values give exactly 0 variance and the value itself as
    mean (so no rounding residue turns into a spurious spread)."""
    if max(values) == min(values):
        return values[0], 0.0
    return statistics.fmean(values), statistics.variance(values)


@dataclass(frozen=True)
class Interval:
    """Mean over seeds, its two-sided confidence interval and the prediction interval of one new run (bounds None
    with a single seed)."""

    mean: float
    low: float | None
    high: float | None
    n: int
    predict_low: float | None = None
    predict_high: float | None = None

    def holds(self, value: float) -> str:
        """"yes"/"no": is ``value`` inside the PREDICTION interval (where a single new run lands); "n<2" without one."""
        if self.predict_low is None:
            return "n<2"
        return "yes" if self.predict_low <= value <= self.predict_high else "no"

    @property
    def mean_outside(self) -> bool:
        """The plain mean lies outside the interval: possible for a rate, whose interval is computed on the logit
        scale (centred on the mean logit) while the point is the plain mean; one seed far from the others pulls the
        plain mean away. Shown as "†" after the interval, never hidden by widening it."""
        return self.low is not None and not self.low <= self.mean <= self.high

    def text(self, digits: int) -> str:
        if self.low is None:
            return f"{self.mean:.{digits}f} [n<2]"
        mark = "†" if self.mean_outside else ""
        return f"{self.mean:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]{mark}"

    def prediction_text(self, digits: int) -> str:
        if self.predict_low is None:
            return "n<2"
        return f"[{self.predict_low:.{digits}f}, {self.predict_high:.{digits}f}]"


def _t(n: int, confidence: float) -> float:
    from scipy.stats import t as student_t

    return float(student_t.ppf(1 - (1 - confidence) / 2, n - 1))


def t_interval(values: list[float], confidence: float = CONFIDENCE) -> Interval:
    """mean ± t(1 - (1 - confidence) / 2, n - 1)·s/√n and the prediction interval mean ± t·s·√(1 + 1/n); s the
    sample std over seeds. Identical values give zero-width intervals at that value; a single value has none."""
    if not values:
        raise ValueError("t_interval needs at least one value")
    mean, variance = mean_and_variance(values)
    n = len(values)
    if n < 2:
        return Interval(mean, None, None, 1)
    t, s = _t(n, confidence), math.sqrt(variance)
    half, predict = t * s / math.sqrt(n), t * s * math.sqrt(1 + 1 / n)
    return Interval(mean, mean - half, mean + half, n, mean - predict, mean + predict)


def _logit(p: float) -> float:
    return math.log(p / (1 - p))


def _expit(x: float) -> float:
    return 1 / (1 + math.exp(-x))


def proportion_interval(values: list[float], games: int, confidence: float = CONFIDENCE) -> Interval:
    """The intervals of a rate over seeds on the logit scale (module docstring); ``games``: test games behind each
    seed's rate. Bounds stay strictly inside (0, 1); the mean is the plain mean of the rates."""
    if not values:
        raise ValueError("proportion_interval needs at least one value")
    if games < 1:
        raise ValueError(f"games must be a positive number of test games, got {games}")
    if any(not 0.0 <= v <= 1.0 for v in values):
        raise ValueError(f"a rate must lie in [0, 1], got {values}")
    if len(values) < 2:
        return Interval(values[0], None, None, 1)
    if max(values) == min(values):  # no spread between seeds: zero-width at the value, as t_interval
        return Interval(values[0], values[0], values[0], len(values), values[0], values[0])
    mean = statistics.fmean(values)
    logits = [_logit((v * games + 0.5) / (games + 1)) for v in values]
    on_logit = t_interval(logits, confidence)
    bounds = (on_logit.low, on_logit.high, on_logit.predict_low, on_logit.predict_high)
    low, high, predict_low, predict_high = (_expit(b) for b in bounds)
    return Interval(mean, low, high, len(values), predict_low, predict_high)


def power_of(difference: float, std: float, n: int, alpha: float = 0.05, n_other: int | None = None,
             std_other: float | None = None) -> float:
    """Power of the one-sided Welch test as it is run, with ``n`` seeds at spread ``std`` on one side and
    ``n_other`` (default ``n``) at ``std_other`` (default ``std``) on the other, to detect ``difference``.

    Noncentral t with noncentrality difference / sqrt(std²/n + std_other²/n_other) and the Welch-Satterthwaite df
    of those spreads, the df the test itself uses (with equal spreads and equal sides it is 2n - 2). Why not the
    pooled spread with df = n + m - 2: when one side spreads more (0.033 against 0.0135), the Welch test has fewer
    degrees of freedom than that, and the pooled figure overstates its power."""
    from scipy.stats import nct, t as student_t

    m = n if n_other is None else n_other
    other = std if std_other is None else std_other
    if min(n, m) < 2:
        return float("nan")
    a, b = std ** 2 / n, other ** 2 / m
    if a + b == 0:
        return 1.0
    df = (a + b) ** 2 / ((a ** 2 / (n - 1) if a else 0.0) + (b ** 2 / (m - 1) if b else 0.0))
    return float(nct.sf(student_t.ppf(1 - alpha, df), df, difference / math.sqrt(a + b)))
