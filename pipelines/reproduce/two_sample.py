"""Is one set of training runs ahead of another, over seeds? The test the paper's claims, the memory report and
`ncbot compare` all ask, in one place so that they decide and word it alike.

One sample is one run (one seed's evaluation mean over its test games); seeds are the independent repetitions.
The decision is a one-sided Welch's t-test (unequal variances, Welch-Satterthwaite df). Beside it, what the field
asks of few-seed comparisons (Henderson et al. 2018; Agarwal et al. 2021): the two-sided 95 % interval of the
difference, the power these runs have to detect a stated difference (the test as run: n seeds on one side, m on
the other, each at its own spread, Welch df), the probability that a run of one side beats a run of the other with its
bootstrap interval, a rank test that assumes no normality, and Holm's adjustment over a family of questions.

The reading ladder: significant at alpha is SHOWN; otherwise, below power 0.8 to detect the stated difference the
question is UNTESTED (not refuted); powered, it is NO where the claimed side did not come out ahead at all, and
NOT_SHOWN where it came out ahead but not significantly.

Zero variance (every seed gave the same value, common for task success near 1): Welch's statistic is undefined
only when BOTH sides are constant; then the difference is exact and p is 0 when the claimed side is larger, 1
otherwise (t and df are None). One constant side is ordinary Welch (df = n - 1 of the other side). Constancy is
decided on the values themselves, so rounding in a mean never fakes a spread.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

from ncbot.pipelines.reproduce.aggregate import improvement_interval
from ncbot.pipelines.reproduce.seed_stats import Interval, mean_and_variance, power_of

ALPHA = 0.05
POWER = 0.8  # below this power to detect the stated difference, a question not shown is untested, not refuted
SHOWN, UNTESTED, NO, NOT_SHOWN, TOO_FEW_RUNS = "shown", "untested", "no", "not shown", "too few runs"


def welch_greater(larger: list[float], smaller: list[float]) -> tuple[float | None, float | None, float | None]:
    """(t, df, p) of the one-sided Welch's t-test H1: mean(larger) > mean(smaller); see the module docstring for
    zero variance. (None, None, None) when a side has fewer than 2 values."""
    from scipy.stats import t as student_t

    if min(len(larger), len(smaller)) < 2:
        return None, None, None
    (mean_a, var_a), (mean_b, var_b) = mean_and_variance(larger), mean_and_variance(smaller)
    se_a, se_b = var_a / len(larger), var_b / len(smaller)
    if se_a + se_b == 0.0:
        return None, None, 0.0 if mean_a > mean_b else 1.0
    t = (mean_a - mean_b) / math.sqrt(se_a + se_b)
    df = (se_a + se_b) ** 2 / (se_a ** 2 / (len(larger) - 1) + se_b ** 2 / (len(smaller) - 1))
    return t, df, float(student_t.sf(t, df))


def welch_difference(a: list[float], b: list[float]) -> Interval:
    """mean(a) - mean(b) with its two-sided 95 % Welch interval (unequal variances, Welch-Satterthwaite df)."""
    from scipy.stats import t as student_t

    (mean_a, var_a), (mean_b, var_b) = mean_and_variance(a), mean_and_variance(b)
    se2 = var_a / len(a) + var_b / len(b)
    if se2 == 0:
        return Interval(mean_a - mean_b, mean_a - mean_b, mean_a - mean_b, len(a) + len(b))
    df = se2 ** 2 / ((var_a / len(a)) ** 2 / (len(a) - 1) + (var_b / len(b)) ** 2 / (len(b) - 1))
    half = float(student_t.ppf(0.975, df)) * math.sqrt(se2)
    return Interval(mean_a - mean_b, mean_a - mean_b - half, mean_a - mean_b + half, len(a) + len(b))


@dataclass(frozen=True)
class TwoSampleTest:
    """H1: the mean over ``larger`` is above the mean over ``smaller`` (negate both to test "below")."""

    larger: tuple[float, ...]
    smaller: tuple[float, ...]
    alpha: float = ALPHA

    @cached_property
    def welch(self) -> tuple[float | None, float | None, float | None]:
        """(t, df, p) of the one-sided test."""
        return welch_greater(list(self.larger), list(self.smaller))

    @property
    def p(self) -> float | None:
        return self.welch[2]

    @cached_property
    def difference(self) -> Interval:
        """mean(larger) - mean(smaller) with its two-sided 95 % Welch interval."""
        return welch_difference(list(self.larger), list(self.smaller))

    @cached_property
    def improvement(self) -> tuple[float, float, float]:
        """P(a run of ``larger`` beats a run of ``smaller``) with its percentile bootstrap interval over runs."""
        return improvement_interval([list(self.larger)], [list(self.smaller)])

    @cached_property
    def rank_p(self) -> float:
        """One-sided Mann-Whitney U p-value (no normality assumed)."""
        from scipy.stats import mannwhitneyu

        return float(mannwhitneyu(self.larger, self.smaller, alternative="greater").pvalue)

    def power(self, effect: float) -> float:
        """Power of this test as run, with these runs on each side at each side's own spread (Welch df), to detect
        ``effect`` (`ncbot.pipelines.reproduce.seed_stats.power_of`)."""
        spreads = [math.sqrt(mean_and_variance(list(side))[1]) for side in (self.larger, self.smaller)]
        return power_of(effect, spreads[0], len(self.larger), self.alpha, len(self.smaller), spreads[1])

    def reading(self, effect: float | None = None) -> str:
        """SHOWN, UNTESTED (only with an ``effect`` to power against), NO, NOT_SHOWN or TOO_FEW_RUNS."""
        if self.p is None:
            return TOO_FEW_RUNS
        if self.p < self.alpha:
            return SHOWN
        if effect is not None and self.power(effect) < POWER:
            return UNTESTED
        return NO if self.difference.mean <= 0 else NOT_SHOWN


def holm(ps: list[float | None]) -> list[float | None]:
    """Holm's step-down adjustment over a family of p-values, in their order (None stays None, out of the family)."""
    ranked = sorted((p, i) for i, p in enumerate(ps) if p is not None)
    adjusted: dict[int, float] = {}
    running = 0.0
    for rank, (p, i) in enumerate(ranked):
        running = max(running, min(1.0, (len(ranked) - rank) * p))
        adjusted[i] = running
    return [adjusted.get(i) for i in range(len(ps))]
