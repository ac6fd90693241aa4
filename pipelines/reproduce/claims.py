"""The paper's claims tested over seeds: one-sided Welch's t-tests, alpha 0.05, at least 5 seeds a side.

A sample is one seed's evaluation mean (3000 test games); seeds are the independent repetitions, so the
tests compare seed means, never individual games. The claims (Cuayahuitl 2019), per suite and game row:
  (i)   task success: Proposed + temporal > DQN-Variant > DQN-Original;
  (ii)  task success of the proposed agent: with temporal features > without;
  (iii) dialogue length: Proposed + temporal shorter than DQN-Variant and than DQN-Original.
A claim made of several comparisons is reproduced only when every comparison is significant (an
intersection-union test: valid at alpha without a multiplicity correction; its p-value is the largest one).
Each claim is tested on its own: no correction across the claims and rows of the table.

Zero variance (every seed gave the same value, common for task success near 1): Welch's statistic is
undefined only when BOTH sides are constant; then the difference is exact and p is 0 when the claimed side is
larger, 1 otherwise (t and df are reported as None). One constant side is ordinary Welch (df = n - 1 of the
other side). Constancy is decided on the values themselves, so rounding in a mean never fakes a spread.
"""
from __future__ import annotations

import math
import statistics
from dataclasses import asdict, dataclass
from typing import Any

ALPHA = 0.05
MIN_SEEDS = 5
TOO_FEW = f"too few seeds (need >= {MIN_SEEDS})"

# The paper's table layout: game rows and agent cells (cell names are those `ncbot ablate` writes).
GAME_LABELS = {"standard": "3x3 (100)", "ultimate100": "Ultimate (100)", "ultimate150": "Ultimate (150)"}
ORIGINAL, VARIANT = "dqn_original-notemporal", "dqn_variant-notemporal"
PROPOSED_NOTEMPORAL, PROPOSED = "proposed-notemporal", "proposed-temporal"
CELL_LABELS = {ORIGINAL: "DQN-Original", VARIANT: "DQN-Variant", PROPOSED_NOTEMPORAL: "Proposed, no temporal",
               PROPOSED: "Proposed + temporal"}

# claim id -> (statement, [(metric, cell claimed larger, cell claimed smaller)]).
CLAIMS: dict[str, tuple[str, list[tuple[str, str, str]]]] = {
    "i": ("task success: Proposed + temporal > DQN-Variant > DQN-Original",
          [("task_success", PROPOSED, VARIANT), ("task_success", VARIANT, ORIGINAL)]),
    "ii": ("task success: Proposed + temporal > Proposed, no temporal",
           [("task_success", PROPOSED, PROPOSED_NOTEMPORAL)]),
    "iii": ("dialogue length: Proposed + temporal shorter than DQN-Variant and DQN-Original",
            [("avg_length", VARIANT, PROPOSED), ("avg_length", ORIGINAL, PROPOSED)]),
}


@dataclass(frozen=True)
class Welch:
    """One one-sided Welch's t-test of "mean(larger) > mean(smaller)" over seeds."""

    metric: str
    larger: str
    smaller: str
    n: tuple[int, int]
    mean: tuple[float, float]
    t: float | None
    df: float | None
    p: float | None  # None: a side has fewer than 2 seeds (no variance to estimate)

    @property
    def decided(self) -> bool:
        return min(self.n) >= MIN_SEEDS and self.p is not None

    def text(self) -> str:
        sides = [f"{CELL_LABELS.get(cell, cell)} {mean:.4f} (n={n})" for cell, mean, n in
                 zip((self.larger, self.smaller), self.mean, self.n)]
        stat = "–" if self.p is None else ("both sides constant" if self.t is None else
                                            f"t={self.t:.2f}, df={self.df:.1f}")
        return f"{sides[0]} > {sides[1]}: {stat}, p={_p(self.p)}"


def mean_and_variance(values: list[float]) -> tuple[float, float]:
    """(mean, sample variance) of n >= 2 values; identical values give exactly 0 variance and the value itself as
    mean (so no rounding residue turns into a spurious spread)."""
    if max(values) == min(values):
        return values[0], 0.0
    return statistics.fmean(values), statistics.variance(values)


def welch_greater(larger: list[float], smaller: list[float]) -> tuple[float | None, float | None, float | None]:
    """(t, df, p) of the one-sided Welch's t-test H1: mean(larger) > mean(smaller); see the module docstring
    for zero variance. (None, None, None) when a side has fewer than 2 values."""
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


@dataclass(frozen=True)
class Claim:
    claim: str
    suite: str
    game: str
    statement: str
    tests: tuple[Welch, ...]

    @property
    def p(self) -> float | None:
        """Intersection-union p-value: the largest of the tests' (None if any test has none)."""
        ps = [test.p for test in self.tests]
        return None if None in ps else max(ps)

    @property
    def verdict(self) -> str:
        if not all(test.decided for test in self.tests):
            return TOO_FEW
        return "reproduced" if self.p < ALPHA else "not reproduced"

    def to_dict(self) -> dict[str, Any]:
        return {"claim": self.claim, "suite": self.suite, "game": self.game, "statement": self.statement,
                "test": "one-sided Welch's t-test over seeds", "alpha": ALPHA, "min_seeds": MIN_SEEDS,
                "p": self.p, "verdict": self.verdict, "tests": [asdict(test) for test in self.tests]}


def evaluate_claims(samples: dict[tuple[str, str, str], dict[str, list[float]]]) -> list[Claim]:
    """Every claim for every (suite, game) whose agents all have at least one run, in table order.

    ``samples`` maps (suite, game row, agent cell) to per-seed values by metric name."""
    claims = []
    for suite, game in sorted({(s, g) for s, g, _ in samples}, key=_row_order):
        for claim, (statement, comparisons) in CLAIMS.items():
            if any((suite, game, cell) not in samples for _, a, b in comparisons for cell in (a, b)):
                continue
            tests = []
            for metric, larger, smaller in comparisons:
                a, b = samples[(suite, game, larger)][metric], samples[(suite, game, smaller)][metric]
                t, df, p = welch_greater(a, b)
                tests.append(Welch(metric, larger, smaller, (len(a), len(b)),
                                   (statistics.fmean(a), statistics.fmean(b)), t, df, p))
            claims.append(Claim(claim, suite, game, statement, tuple(tests)))
    return claims


def _row_order(row: tuple[str, str]) -> tuple:
    suite, game = row
    order = list(GAME_LABELS)
    return (order.index(game) if game in order else len(order), game, suite)


def _p(p: float | None) -> str:
    return "–" if p is None else (f"{p:.4f}" if p >= 1e-4 else f"{p:.1e}")


def render_claims(claims: list[Claim], command: str) -> str:
    """Markdown: one row per claim with its tests, p-value and verdict, and how they were decided."""
    lines = [
        "# The paper's claims, tested over seeds",
        "",
        f"Made by `{command}`.",
        "",
        f"Each comparison is a one-sided Welch's t-test over seeds (one sample = one seed's evaluation mean; unequal "
        f"variances, Welch-Satterthwaite df), alpha {ALPHA}. A claim made of several comparisons is reproduced only "
        f"when every one is significant (intersection-union test; its p-value is the largest). A claim needs >= "
        f"{MIN_SEEDS} seeds on every side, else it is \"{TOO_FEW}\" and its p-values (shown when each side has >= 2 "
        "seeds) are for information only. Both sides constant across seeds: p = 0 if the claimed side is larger, "
        "else 1. No correction across claims or rows.",
        "",
        "| claim | game (units) | settings | statement | comparisons (one-sided Welch's t-test) | p-value | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for claim in claims:
        lines.append(f"| ({claim.claim}) | {GAME_LABELS.get(claim.game, claim.game)} | {claim.suite} | "
                     f"{claim.statement} | {'<br>'.join(test.text() for test in claim.tests)} | {_p(claim.p)} | "
                     f"{claim.verdict} |")
    if not claims:
        lines.append("| – | – | – | no game row has runs of every agent a claim compares | – | – | – |")
    return "\n".join(lines) + "\n"
