"""`ncbot compare RUN... --against RUN...`: is one set of training runs ahead of another, over seeds?

Why a command of its own: the table and the memory report compare the arms of one grid; a researcher's own question
(a reading against paper mode, a change against main, a test planned before its runs on seeds chosen for it) pits
two sets of run folders that no grid groups. Each run is one sample (its eval.json's metric, e.g. robot-first task
success over 3000 test games); the decision is a one-sided Welch's t-test over runs, as in the claims, beside what
the field asks of few-seed comparisons (Henderson et al. 2018; Agarwal et al. 2021): the two-sided interval of the
difference, the power the runs have to detect a stated effect, the probability that a run of one set beats a run
of the other with its bootstrap interval, and a rank test that assumes no normality.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from ncbot.pipelines.reproduce.aggregate import interval_text
from ncbot.pipelines.reproduce.seed_stats import Interval, mean_and_variance, proportion_interval, t_interval
from ncbot.pipelines.reproduce.table import DEFAULT_GAMES
from ncbot.pipelines.reproduce.two_sample import ALPHA, NO, POWER, SHOWN, UNTESTED, TwoSampleTest

RATES = ("task_success", "win", "draw", "loss", "truncated", "all_negative")  # shares of test games: logit intervals


@dataclass(frozen=True)
class RunValue:
    folder: Path
    identity: str  # the run id `ncbot train` writes (a copied folder keeps it), else the folder
    value: float
    games: int


def run_folders(paths: list[str]) -> list[Path]:
    """Each path is a finished run folder (eval.json) or a folder of them (seed0/, seed1/, ...: a grid's cell)."""
    found: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if (path / "eval.json").is_file():
            found.append(path)
        elif path.is_dir() and (inner := sorted(p.parent for p in path.glob("*/eval.json"))):
            found.extend(inner)
        else:
            raise FileNotFoundError(f"{raw} is neither a finished run folder (with eval.json) nor a folder of them")
    return found


def read_values(paths: list[str], metric: str) -> list[RunValue]:
    """The metric of every run under ``paths`` (e.g. first.task_success: robot first)."""
    seat, _, key = metric.partition(".")
    values = []
    for folder in run_folders(paths):
        report: dict[str, Any] = json.loads((folder / "eval.json").read_text(encoding="utf-8"))
        block = report.get(seat)
        if not isinstance(block, dict) or not isinstance(block.get(key), (int, float)):
            known = sorted(f"{s}.{k}" for s in ("first", "second") if isinstance(report.get(s), dict)
                           for k, v in report[s].items() if isinstance(v, (int, float)))
            raise ValueError(f"--metric {metric!r} is not in {folder}/eval.json; expected one of {', '.join(known)}")
        values.append(RunValue(folder, str(report.get("run_id") or folder.resolve()), float(block[key]),
                               int(block.get("games", DEFAULT_GAMES))))
    return values


def _check(runs: list[RunValue], others: list[RunValue]) -> None:
    """Every run counts once (a folder named twice, on one side or both, or a copy of one: the same run id), and
    each side has the two runs a spread needs."""
    seen: dict[str, Path] = {}
    for run in runs + others:
        if run.identity in seen:
            raise ValueError(f"{seen[run.identity]} and {run.folder} are the same run (run id {run.identity}): "
                             "a run counts once")
        seen[run.identity] = run.folder
    for side, found in (("RUN", runs), ("--against", others)):
        if len(found) < 2:
            raise ValueError(f"{side} needs at least 2 finished runs (seeds) to compare over seeds, got {len(found)}")


@dataclass(frozen=True)
class Comparison:
    """H1: the metric's mean over ``runs`` is above (``larger=True``) or below the mean over ``others``."""

    metric: str
    runs: list[RunValue]
    others: list[RunValue]
    larger: bool = True
    effect: float | None = None
    alpha: float = ALPHA

    @cached_property
    def test(self) -> TwoSampleTest:
        """The one-sided test, on values negated when H1 says "below"."""
        sign = 1.0 if self.larger else -1.0
        return TwoSampleTest(tuple(sign * r.value for r in self.runs), tuple(sign * r.value for r in self.others),
                             self.alpha)

    def interval(self, runs: list[RunValue]) -> Interval:
        if self.metric.partition(".")[2] in RATES:
            return proportion_interval([r.value for r in runs], min(r.games for r in runs))
        return t_interval([r.value for r in runs])

    @cached_property
    def difference(self) -> Interval:
        """mean(RUN) - mean(--against), the test's two-sided 95 % Welch interval on the metric's own scale and sign."""
        tested = self.test.difference
        if self.larger:
            return tested
        return Interval(-tested.mean, -tested.high, -tested.low, tested.n)

    @cached_property
    def power(self) -> float | None:
        """Power of these runs to detect ``effect`` each side at its own spread, Welch df (None without an effect)."""
        return None if self.effect is None else self.test.power(self.effect)

    @property
    def verdict(self) -> str:
        reading, p = self.test.reading(self.effect), self.test.p
        word = "higher" if self.larger else "lower"
        if reading == SHOWN:
            return f"RUN {word} at alpha {self.alpha} (p = {p:.3g})"
        if reading == UNTESTED:
            return f"untested: power {self.power:.2f} < {POWER} to detect {self.effect:g}"
        if reading == NO:
            return f"no: RUN did not come out {word}"
        return f"not shown (p = {p:.3g} >= {self.alpha})"

    def to_dict(self) -> dict[str, Any]:
        t, df, p = self.test.welch
        difference = self.difference
        return {"metric": self.metric, "direction": "greater" if self.larger else "less", "alpha": self.alpha,
                "runs": [{"folder": str(r.folder), "value": r.value} for r in self.runs],
                "against": [{"folder": str(r.folder), "value": r.value} for r in self.others],
                "mean": self.interval(self.runs).mean, "against_mean": self.interval(self.others).mean,
                "difference": difference.mean, "difference_low": difference.low, "difference_high": difference.high,
                "t": t, "df": df, "p": p, "rank_p": self.test.rank_p,
                "p_run_ahead": list(self.test.improvement), "effect": self.effect, "power": self.power,
                "verdict": self.verdict}

    def plot(self, path: str | Path) -> Path:
        """Every run of both sides as a dot, each side's mean and interval as a bar (pipelines/plots.py)."""
        from ncbot.pipelines.plots import plot_two_sides

        sides = {}
        for side, runs in (("RUN", self.runs), ("--against", self.others)):
            interval = self.interval(runs)
            sides[side] = ([r.value for r in runs], (interval.mean, interval.low, interval.high))
        return plot_two_sides(sides, path, xlabel=self.metric,
                              title=f"{self.metric}: every run (dots), mean with its 95 % interval (bar)")

    def markdown(self, command: str, figure: str | None = None) -> str:
        t, df, p = self.test.welch
        op = ">" if self.larger else "<"
        drawn = f" Every run drawn: [{figure}]({figure})." if figure else ""
        lines = [f"# {self.metric}: RUN {op} --against", "", f"Made by `{command}`.{drawn}", "",
                 "| side | runs | mean [95 % interval] | s | per run |", "|---|---|---|---|---|"]
        for side, runs in (("RUN", self.runs), ("--against", self.others)):
            spread = math.sqrt(mean_and_variance([r.value for r in runs])[1])
            lines.append(f"| {side} | {len(runs)} | {self.interval(runs).text(4)} | {spread:.4f} | "
                         + ", ".join(f"{r.value:.4f}" for r in runs) + " |")
        difference = self.difference
        test = "t = –" if t is None else f"t = {t:.2f}, df = {df:.1f}"
        lines += ["", f"- difference RUN - against: {difference.text(4)} (two-sided 95 % Welch interval)",
                  f"- one-sided Welch's t-test, H1 mean(RUN) {op} mean(against): {test}, p = "
                  + ("–" if p is None else f"{p:.3g}"),
                  f"- one-sided Mann-Whitney U (no normality assumed): p = {self.test.rank_p:.3g}",
                  f"- P(a run of RUN is {'above' if self.larger else 'below'} a run of against): "
                  f"{interval_text(self.test.improvement)} (percentile bootstrap over runs: describes, the test decides)"]
        if self.power is not None:
            lines.append(f"- power to detect {self.effect:g} with these runs, each side at its own spread: {self.power:.2f}")
        lines += [f"- verdict: {self.verdict}", ""]
        return "\n".join(lines)


def compare(paths: list[str], against: list[str], metric: str = "first.task_success", larger: bool = True,
            effect: float | None = None, alpha: float = 0.05) -> Comparison:
    if not 0 < alpha < 1:
        raise ValueError(f"--alpha must be between 0 and 1, got {alpha}")
    if effect is not None and effect <= 0:
        raise ValueError(f"--effect is the size of the difference to detect, a positive number; got {effect}")
    runs, others = read_values(paths, metric), read_values(against, metric)
    _check(runs, others)
    return Comparison(metric, runs, others, larger, effect, alpha)
