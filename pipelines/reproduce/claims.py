"""The paper's claims tested over seeds: one-sided Welch's t-tests, alpha 0.05, at least 5 seeds a side.

A sample is one seed's evaluation mean (3000 test games); seeds are the independent repetitions, so the tests compare
seed means, never individual games. The claims are the comparisons the paper (Cuayahuitl 2019) makes, in our words,
per suite and game row of its results table (the automatic evaluation against the simulated user), and no other:
  (i.a)   task success: Proposed + temporal above both baselines, DQN-Variant and DQN-Original (abstract: the
          proposed policy learning "substantially outperform[s] DQN-based baselines"; the results table);
  (i.b)   task success: Proposed without temporal features above both baselines (the same);
  (ii)    task success: Proposed with temporal features above Proposed without them (the results table's two
          Proposed rows, with and without the temporal features of the state);
  (iii.a) dialogue length: Proposed + temporal shorter than both baselines (the results table);
  (iii.b) dialogue length: Proposed without temporal features shorter than both baselines (the same).
DQN-Variant above DQN-Original is not among them: the paper does not claim it. The paper's own table does not hold
every claim in every row (3x3: both Proposed agents' dialogues are the longest; Ultimate (100): Proposed without
temporal features 63.62 acts against DQN-Original's 63.54); `PAPER_HOLDS` says where, and the report prints it beside
each verdict.
A claim made of several comparisons is reproduced only when every comparison is significant (an intersection-union
test: valid at alpha without a multiplicity correction; its p-value is the largest one). Multiplicity: one family,
every claim of the report (five claims per game row); each verdict is at alpha on its own and the Holm-adjusted
p-value over the family is printed beside it for a family-wise reading.

The test itself, zero variance included, is `ncbot.pipelines.reproduce.two_sample`'s, shared with the memory
report and `ncbot compare`.
"""
from __future__ import annotations

import statistics
from dataclasses import asdict, dataclass, replace
from typing import Any

from ncbot.pipelines.reproduce.aggregate import BOOTSTRAP_REPS, interval_text
from ncbot.pipelines.reproduce.two_sample import ALPHA, POWER, TwoSampleTest, holm

MIN_SEEDS = 5
TOO_FEW = f"too few seeds (need >= {MIN_SEEDS})"

# The paper's table layout: game rows and agent cells (cell names are those `ncbot ablate` writes).
GAME_LABELS = {"standard": "3x3 (100)", "ultimate100": "Ultimate (100)", "ultimate150": "Ultimate (150)"}
ORIGINAL, VARIANT = "dqn_original-notemporal", "dqn_variant-notemporal"
PROPOSED_NOTEMPORAL, PROPOSED = "proposed-notemporal", "proposed-temporal"
UNIFORM = "uniform-notemporal"
CELL_LABELS = {UNIFORM: "Uniform in the masks (no learning)", ORIGINAL: "DQN-Original", VARIANT: "DQN-Variant",
               PROPOSED_NOTEMPORAL: "Proposed, no temporal", PROPOSED: "Proposed + temporal"}

# The paper's results table (Cuayahuitl 2019, automatic evaluation, 3000 test games against the simulated user):
# (average reward per action, task success, dialogue length).
PAPER = {
    ("standard", ORIGINAL): (0.0658, 0.8258, 13.93),
    ("standard", VARIANT): (0.5530, 0.9720, 13.99),
    ("standard", PROPOSED_NOTEMPORAL): (0.4710, 0.9868, 15.31),
    ("standard", PROPOSED): (0.6300, 0.9980, 14.06),
    ("ultimate100", ORIGINAL): (-0.6900, 0.7873, 63.54),
    ("ultimate100", VARIANT): (0.0177, 0.9074, 64.82),
    ("ultimate100", PROPOSED_NOTEMPORAL): (0.0693, 0.9377, 63.62),
    ("ultimate100", PROPOSED): (0.1440, 0.9753, 52.03),
    ("ultimate150", ORIGINAL): (-0.1120, 0.7290, 65.49),
    ("ultimate150", VARIANT): (-0.0310, 0.8663, 70.57),
    ("ultimate150", PROPOSED_NOTEMPORAL): (0.0997, 0.9473, 59.69),
    ("ultimate150", PROPOSED): (0.1640, 0.9846, 52.09),
}
PAPER_COLUMN = {"avg_reward": 0, "task_success": 1, "avg_length": 2}
# claim id -> (statement, [(metric, cell claimed larger, cell claimed smaller)]).
CLAIMS: dict[str, tuple[str, list[tuple[str, str, str]]]] = {
    "i.a": ("task success: Proposed + temporal above DQN-Variant and DQN-Original",
            [("task_success", PROPOSED, VARIANT), ("task_success", PROPOSED, ORIGINAL)]),
    "i.b": ("task success: Proposed, no temporal, above DQN-Variant and DQN-Original",
            [("task_success", PROPOSED_NOTEMPORAL, VARIANT), ("task_success", PROPOSED_NOTEMPORAL, ORIGINAL)]),
    "ii": ("task success: Proposed + temporal above Proposed, no temporal",
           [("task_success", PROPOSED, PROPOSED_NOTEMPORAL)]),
    "iii.a": ("dialogue length: Proposed + temporal shorter than DQN-Variant and DQN-Original",
              [("avg_length", VARIANT, PROPOSED), ("avg_length", ORIGINAL, PROPOSED)]),
    "iii.b": ("dialogue length: Proposed, no temporal, shorter than DQN-Variant and DQN-Original",
              [("avg_length", VARIANT, PROPOSED_NOTEMPORAL), ("avg_length", ORIGINAL, PROPOSED_NOTEMPORAL)]),
}


def paper_holds(claim: str, game: str) -> str:
    """Whether the paper's own table holds the claim in this game row: "yes", "no: <the numbers that fail>", or
    "–" where the paper has no such row."""
    failing = []
    for metric, larger, smaller in CLAIMS[claim][1]:
        if (game, larger) not in PAPER or (game, smaller) not in PAPER:
            return "–"
        column = PAPER_COLUMN[metric]
        high, low = PAPER[(game, larger)][column], PAPER[(game, smaller)][column]
        if not high > low:
            failing.append(f"{CELL_LABELS[larger]} {high:g} vs {CELL_LABELS[smaller]} {low:g}")
    return "yes" if not failing else "no: " + "; ".join(failing)


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


@dataclass(frozen=True)
class Claim:
    claim: str
    suite: str
    game: str
    statement: str
    tests: tuple[Welch, ...]
    # the power of these seeds to detect the paper's own difference at our spread (None: no paper difference, or
    # fewer than 2 seeds a side); a claim not reproduced with low power is untested rather than refuted
    power: float | None = None
    holm_p: float | None = None  # p adjusted over every claim of the report (Holm), for a family-wise reading
    # per test: P(a run of the claimed-larger side beats one of the other) with its stratified bootstrap interval
    # (`ncbot.pipelines.reproduce.aggregate`); None where a side has fewer than 2 seeds
    improvements: tuple[tuple[float, float, float] | None, ...] = ()

    @property
    def p(self) -> float | None:
        """Intersection-union p-value: the largest of the tests' (None if any test has none)."""
        ps = [test.p for test in self.tests]
        return None if None in ps else max(ps)

    @property
    def verdict(self) -> str:
        if not all(test.decided for test in self.tests):
            return TOO_FEW
        if self.p < ALPHA:
            return "reproduced"
        if self.power is not None and self.power < POWER:
            return f"not reproduced; power {self.power:.2f} < {POWER} to detect the paper's difference: untested"
        return "not reproduced"

    def to_dict(self) -> dict[str, Any]:
        return {"claim": self.claim, "suite": self.suite, "game": self.game, "statement": self.statement,
                "test": "one-sided Welch's t-test over seeds", "alpha": ALPHA, "min_seeds": MIN_SEEDS,
                "paper_holds": paper_holds(self.claim, self.game),
                "p": self.p, "holm_p": self.holm_p, "power_at_paper_difference": self.power,
                "verdict": self.verdict, "tests": [asdict(test) for test in self.tests],
                "probability_of_improvement": [None if found is None else dict(zip(("p", "low", "high"), found))
                                               for found in self.improvements]}

    def improvements_text(self) -> str:
        return "<br>".join("–" if found is None else interval_text(found) for found in self.improvements)


def evaluate_claims(samples: dict[tuple[str, str, str], dict[str, list[float]]]) -> list[Claim]:
    """Every claim for every (suite, game) whose agents all have at least one run, in table order.

    ``samples`` maps (suite, game row, agent cell) to per-seed values by metric name."""
    claims = []
    for suite, game in sorted({(s, g) for s, g, _ in samples}, key=_row_order):
        for claim, (statement, comparisons) in CLAIMS.items():
            if any((suite, game, cell) not in samples for _, a, b in comparisons for cell in (a, b)):
                continue
            tests, improvements, two_samples = [], [], []
            for metric, larger, smaller in comparisons:
                a, b = samples[(suite, game, larger)][metric], samples[(suite, game, smaller)][metric]
                test = TwoSampleTest(tuple(a), tuple(b))
                tests.append(Welch(metric, larger, smaller, (len(a), len(b)),
                                   (statistics.fmean(a), statistics.fmean(b)), *test.welch))
                improvements.append(test.improvement if min(len(a), len(b)) >= 2 else None)
                two_samples.append(test)
            claims.append(Claim(claim, suite, game, statement, tuple(tests),
                                power=_power(game, comparisons, two_samples), improvements=tuple(improvements)))
    return _with_holm(claims)


def _power(game: str, comparisons: list[tuple[str, str, str]], tests: list[TwoSampleTest]) -> float | None:
    """The smallest power over the claim's comparisons (``tests``, one each) to detect the paper's own difference
    (its table's two numbers) with our seeds, each side at its own spread (Welch df); None where the paper gives no number or a side
    has < 2 seeds."""
    powers = []
    for (metric, larger, smaller), test in zip(comparisons, tests):
        column = PAPER_COLUMN.get(metric)
        if column is None or (game, larger) not in PAPER or (game, smaller) not in PAPER:
            return None
        difference = PAPER[(game, larger)][column] - PAPER[(game, smaller)][column]
        if min(len(test.larger), len(test.smaller)) < 2 or difference <= 0:
            return None
        powers.append(test.power(difference))
    return min(powers) if powers else None


def _with_holm(claims: list[Claim]) -> list[Claim]:
    """Holm's step-down adjustment of the claims' p-values over the whole report (claims without p keep None)."""
    return [replace(claim, holm_p=holm_p) for claim, holm_p in zip(claims, holm([claim.p for claim in claims]))]


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
        "The claims are the comparisons the paper (Cuayáhuitl 2019) makes, in our words, per game row of its results "
        "table, and no other: (i.a) and (i.b) each Proposed agent, with and without the temporal features, above both "
        "baselines in task success (its abstract: the proposed policy learning \"substantially outperform[s] "
        "DQN-based baselines\"); (ii) the temporal features raise the Proposed agent's task success; (iii.a) and "
        "(iii.b) each Proposed agent's dialogues shorter than both baselines'. DQN-Variant above DQN-Original is not "
        "a claim of the paper and is not tested. \"The paper's own table\" says whether the paper's numbers themselves "
        "hold the claim in that row.",
        "",
        f"Each comparison is a one-sided Welch's t-test over seeds (one sample = one seed's evaluation mean; unequal "
        f"variances, Welch-Satterthwaite df), alpha {ALPHA}. A claim made of several comparisons is reproduced only "
        f"when every one is significant (intersection-union test; its p-value is the largest). A claim needs >= "
        f"{MIN_SEEDS} seeds on every side, else it is \"{TOO_FEW}\" and its p-values (shown when each side has >= 2 "
        "seeds) are for information only. Both sides constant across seeds: p = 0 if the claimed side is larger, "
        f"else 1. Multiplicity: one family, every claim in this file; each verdict is at alpha {ALPHA} on its own, and "
        "the Holm-adjusted p-value over the family is given beside it for a family-wise reading. Power: the "
        "probability that these seeds detect the difference the paper itself reports, for the Welch test as run "
        "(noncentral t, each side at its own spread between seeds, Welch-Satterthwaite df); a claim that is not "
        f"reproduced with power below {POWER} is untested, not refuted; none where the paper's own difference does "
        "not point the claimed way.",
        "",
        "Beside each test, read without a normality assumption (Agarwal et al. 2021, as the `rliable` package): the "
        "probability that a run of the claimed-larger side beats a run of the other, P(X > Y) over every pair of "
        f"seeds (ties count half), with the 95 % percentile interval of a bootstrap over seeds ({BOOTSTRAP_REPS} "
        "resamples, fixed generator seed). An interval above 0.5 says the claimed side's runs come out ahead more "
        "often than not. With 5 seeds a side a percentile bootstrap covers less than its nominal 95 %, so these "
        "describe the runs; the verdicts stay those of the Welch tests, fixed before the runs.",
        "",
        "| claim | game (units) | settings | statement | the paper's own table | comparisons (one-sided Welch's t-test) "
        "| p-value | Holm p | power at the paper's difference | P(run ahead) [95% bootstrap] | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for claim in claims:
        lines.append(f"| ({claim.claim}) | {GAME_LABELS.get(claim.game, claim.game)} | {claim.suite} | "
                     f"{claim.statement} | {paper_holds(claim.claim, claim.game)} | "
                     f"{'<br>'.join(test.text() for test in claim.tests)} | {_p(claim.p)} | "
                     f"{_p(claim.holm_p)} | {'–' if claim.power is None else f'{claim.power:.2f}'} | "
                     f"{claim.improvements_text()} | {claim.verdict} |")
    if not claims:
        lines.append("| – | – | – | no game row has runs of every agent a claim compares | – | – | – | – | – | – | – |")
    return "\n".join(lines) + "\n"


def render_reward_order(samples: dict[tuple[str, str, str], dict[str, list[float]]]) -> str:
    """Markdown: per game row, the learning agents ordered by average reward per act, ours (mean over seeds) beside
    the paper's. The paper reports this column without stating a claim on it; this compares, it tests nothing."""
    lines = ["## Average reward per act, ours beside the paper's", "",
             "The paper reports the average reward per act of every agent without stating a claim on it; its table "
             "has Proposed + temporal highest in every row. Here each row's learning agents in order of their mean "
             "over seeds (robot first), the paper's order beside; whether the paper's value lies inside the "
             "prediction interval of one new run of ours is in the table. Descriptive: no test.", "",
             "| game (units) | settings | ours, highest first | the paper's, highest first |", "|---|---|---|---|"]
    rows = sorted({(suite, game) for suite, game, _ in samples}, key=_row_order)
    for suite, game in rows:
        cells = [cell for cell in CELL_LABELS if (game, cell) in PAPER and (suite, game, cell) in samples
                 and samples[(suite, game, cell)].get("avg_reward")]
        if len(cells) < 2:
            continue
        ours = sorted(cells, key=lambda cell: -statistics.fmean(samples[(suite, game, cell)]["avg_reward"]))
        theirs = sorted(cells, key=lambda cell: -PAPER[(game, cell)][0])
        lines.append(f"| {GAME_LABELS.get(game, game)} | {suite} | "
                     + " > ".join(f"{CELL_LABELS[c]} {statistics.fmean(samples[(suite, game, c)]['avg_reward']):.4f}"
                                  for c in ours) + " | "
                     + " > ".join(f"{CELL_LABELS[c]} {PAPER[(game, c)][0]:.4f}" for c in theirs) + " |")
    return "\n".join(lines) + "\n"
