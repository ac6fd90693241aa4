"""The paper's comparisons and every agent's task success pooled over the table's game rows: the aggregate view of
Agarwal et al. 2021 (`ncbot.pipelines.reproduce.aggregate`), appended to the claims report.

Why pooled: the paper states its claims over the whole table (3x3 and Ultimate at two widths), and five seeds per
row leave each row's test weak; pooling every run of every row, with the bootstrap stratified by row, asks whether
one agent's runs beat another's across the table. A row enters a comparison only when both agents have at least
two seeds there, and the rows used are listed, so a partial table is never read as the whole.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ncbot.pipelines.reproduce.aggregate import (BOOTSTRAP_REPS, improvement_interval, interval_text, iqm_interval,
                                                 reading)
from ncbot.pipelines.reproduce.claims import CELL_LABELS, CLAIMS, GAME_LABELS

Samples = dict[tuple[str, str, str], dict[str, list[float]]]
MIN_RUNS = 2  # seeds a side for a game row to enter a pooled comparison


@dataclass(frozen=True)
class PooledScore:
    """One agent's task success (robot first) over every run of every game row it has."""

    suite: str
    cell: str
    game_labels: tuple[str, ...]  # its game rows, as the table names them
    runs: int
    iqm: float
    low: float
    high: float


@dataclass(frozen=True)
class PooledComparison:
    """P(a run of ``larger`` beats a run of ``smaller``) averaged over the game rows both have."""

    suite: str
    metric: str
    larger: str
    smaller: str
    games: tuple[str, ...]
    runs: tuple[int, int]
    p: float
    low: float
    high: float

    @property
    def reading(self) -> str:
        return reading(self.low, self.high)


def _games(samples: Samples, suite: str, cell: str, metric: str) -> list[str]:
    order = list(GAME_LABELS)
    found = [game for s, game, c in samples if s == suite and c == cell and len(samples[(s, game, c)].get(metric, [])) >= MIN_RUNS]
    return sorted(found, key=lambda game: (order.index(game) if game in order else len(order), game))


def pooled_scores(samples: Samples, labels: dict[tuple[str, str, str], str] | None = None,
                  metric: str = "task_success") -> list[PooledScore]:
    """Every (suite, agent) with at least 2 seeds in some game row: the IQM of ``metric`` over those rows' runs.
    ``labels``: how the table names each (suite, game, agent) row (its widths), else the paper's row names."""
    scores = []
    for suite, cell in sorted({(s, c) for s, _, c in samples}, key=_cell_order):
        games = _games(samples, suite, cell, metric)
        if not games:
            continue
        strata = [samples[(suite, game, cell)][metric] for game in games]
        names = tuple((labels or {}).get((suite, game, cell), GAME_LABELS.get(game, game)) for game in games)
        scores.append(PooledScore(suite, cell, names, sum(map(len, strata)), *iqm_interval(strata)))
    return scores


def pooled_comparisons(samples: Samples) -> list[PooledComparison]:
    """Every comparison of the claims, per suite, over the game rows where both sides have at least 2 seeds."""
    comparisons, seen = [], set()
    for suite in sorted({s for s, _, _ in samples}):
        for _, tests in CLAIMS.values():
            for metric, larger, smaller in tests:
                if (suite, metric, larger, smaller) in seen:
                    continue
                seen.add((suite, metric, larger, smaller))
                other = _games(samples, suite, smaller, metric)
                games = [game for game in _games(samples, suite, larger, metric) if game in other]
                if not games:
                    continue
                a = [samples[(suite, game, larger)][metric] for game in games]
                b = [samples[(suite, game, smaller)][metric] for game in games]
                comparisons.append(PooledComparison(suite, metric, larger, smaller, tuple(games),
                                                    (sum(map(len, a)), sum(map(len, b))), *improvement_interval(a, b)))
    return comparisons


def _cell_order(key: tuple[str, str]) -> tuple:
    suite, cell = key
    order = list(CELL_LABELS)
    return (suite, order.index(cell) if cell in order else len(order), cell)


def _labels(games: tuple[str, ...]) -> str:
    return ", ".join(GAME_LABELS.get(game, game) for game in games)


def render_pooled(scores: list[PooledScore], comparisons: list[PooledComparison]) -> str:
    """The markdown section appended to the claims report."""
    lines = [
        "",
        "## Pooled over game rows",
        "",
        "Every run of every game row together (Agarwal et al. 2021): the interquartile mean (IQM, the mean of the middle "
        "half of the runs) and the probability that a run of one agent beats a run of the other, averaged over the rows "
        f"both have; 95 % percentile intervals of a bootstrap stratified by game row ({BOOTSTRAP_REPS} resamples, "
        f"fixed generator seed). A row counts only where the agent has at least {MIN_RUNS} seeds; the rows used are "
        "listed. Robot first, as the tests above. These read the same runs as the tests; they decide no claim.",
        "",
        "| settings | agent | game rows | runs | task success IQM [95% bootstrap] |",
        "|---|---|---|---|---|",
    ]
    for score in scores:
        lines.append(f"| {score.suite} | {CELL_LABELS.get(score.cell, score.cell)} | {', '.join(score.game_labels)} | "
                     f"{score.runs} | {score.iqm:.4f} [{score.low:.4f}, {score.high:.4f}] |")
    if not scores:
        lines.append("| – | – | no agent has 2 seeds in a game row | – | – |")
    lines += [
        "",
        "| settings | comparison | metric | game rows | runs | P(run ahead) [95% bootstrap] | reading |",
        "|---|---|---|---|---|---|---|",
    ]
    for found in comparisons:
        lines.append(f"| {found.suite} | {CELL_LABELS.get(found.larger, found.larger)} > "
                     f"{CELL_LABELS.get(found.smaller, found.smaller)} | {found.metric} | {_labels(found.games)} | "
                     f"{found.runs[0]} vs {found.runs[1]} | {interval_text((found.p, found.low, found.high))} | "
                     f"{found.reading} |")
    if not comparisons:
        lines.append("| – | no comparison has 2 seeds a side in a common game row | – | – | – | – | – |")
    return "\n".join(lines) + "\n"


def pooled_dict(scores: list[PooledScore], comparisons: list[PooledComparison]) -> dict[str, Any]:
    from dataclasses import asdict

    return {"bootstrap_reps": BOOTSTRAP_REPS, "scores": [asdict(score) for score in scores],
            "comparisons": [{**asdict(found), "reading": found.reading} for found in comparisons]}
