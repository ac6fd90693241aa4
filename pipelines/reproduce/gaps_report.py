"""The verdicts of "The remaining gaps" (docs/reproduction.md), exactly as fixed there before the runs, from the
finished queue (`python -m ncbot.pipelines.reproduce.gaps run`) and the published seeds CSVs in results/.

A1, D1, E1 and E2 are the family: each at its own level (E1 at Pocock's 0.0304), Holm's adjustment over the four
printed beside. E3, the secondary readings of (a) and (d), and (b) and (c) describe; they decide nothing.
A question whose runs are not all finished is reported as not finished, never read.
"""
from __future__ import annotations

import csv
import json
import math
import statistics
import time
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.logs.acts import GAME_MOVES, REFUSED
from ncbot.pipelines.reproduce.gaps_plan import GapRun, plan
from ncbot.pipelines.reproduce.gaps_sources import SOURCES, reward_sources
from ncbot.pipelines.reproduce.seed_stats import power_of, proportion_interval, t_interval
from ncbot.pipelines.reproduce.two_sample import TwoSampleTest, holm, welch_difference

RESULTS = Path(__file__).parents[2] / "results"
POCOCK_SECOND_LOOK = 0.0304
FAMILY = ("A1", "D1", "E1", "E2")
LATE_CHECKPOINTS = tuple(range(200_000, 400_001, 50_000))  # E3: the five checkpoints from 200K to 400K frames
GAMES = 3000


def published(game: str, agent: str, metric: str = "first.task_success", csv_path: Path | None = None,
              seeds: range | None = None, suite: str | None = None) -> list[float]:
    """One metric of the published runs of a cell, in seed order, from a shipped seeds CSV."""
    with (csv_path or RESULTS / "paper_table_seeds.csv").open(newline="", encoding="utf-8") as handle:
        rows = [row for row in csv.DictReader(handle) if row["game"] == game and row["agent"] == agent
                and (suite is None or row["suite"] == suite) and (seeds is None or int(row["seed"]) in seeds)]
    return [float(row[metric]) for row in sorted(rows, key=lambda row: int(row["seed"]))]


class Runs:
    """The queue's finished runs, read by question and cell (no partial question is read)."""

    def __init__(self, runs: Path) -> None:
        self.root, self.plan = Path(runs), plan()

    def cell(self, question: str, row: str, cell: str) -> list[GapRun]:
        return [run for run in self.plan if (run.question, run.row, run.cell) == (question, row, cell)]

    def final_evaluation(self, run: GapRun) -> Path:
        """The run's eval.json: written last, so its presence marks the run finished."""
        return run.folder(self.root) / "eval.json"

    def finished(self, runs: list[GapRun]) -> bool:
        """Every run of the question has its eval.json (and there are at least two to spread)."""
        return len(runs) >= 2 and all(self.final_evaluation(run).is_file() for run in runs)

    def final(self, runs: list[GapRun], seat: str = "first", key: str = "task_success") -> list[float]:
        return [json.loads(self.final_evaluation(run).read_text())[seat][key] for run in runs]

    def checkpoint(self, run: GapRun, frames: int, seat: str = "first") -> float | None:
        path = run.folder(self.root) / "checkpoint_evals" / f"step-{frames:09d}-{seat}.json"
        return json.loads(path.read_text())["task_success"] if path.is_file() else None


def minimum_effect(a: list[float], b: list[float], alpha: float) -> float:
    """The smallest difference these runs detect with power 0.8 at their spreads (Welch test as run)."""
    spreads = [statistics.stdev(side) for side in (a, b)]
    low, high = 1e-6, 1.0
    for _ in range(60):
        middle = (low + high) / 2
        low, high = (middle, high) if power_of(middle, spreads[0], len(a), alpha, len(b), spreads[1]) < 0.8 else (low, middle)
    return high


def _test(name: str, larger: list[float], smaller: list[float], alpha: float, effect: float) -> dict[str, Any]:
    test = TwoSampleTest(tuple(larger), tuple(smaller), alpha)
    t, df, p = test.welch
    shown = p is not None and p < alpha
    power = test.power(effect)
    verdict = "shown" if shown else ("untested" if power < 0.8 else "not shown")
    return {"test": name, "n": (len(larger), len(smaller)), "means": (statistics.fmean(larger), statistics.fmean(smaller)),
            "difference": test.difference.mean, "interval": (test.difference.low, test.difference.high),
            "t": t, "df": df, "p": p, "alpha": alpha, "power_at": effect, "power": power,
            "minimum_effect": minimum_effect(larger, smaller, alpha), "verdict": verdict}


def family(runs: Runs) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """A1, D1, E1, E2 (the finished ones) with Holm's adjustment over the four, and the secondary readings."""
    tests, notes = [], {}
    steps = runs.cell("steps800k", "ultimate100", "proposed-temporal")
    if runs.finished(steps):
        long = runs.final(steps)
        tests.append(_test("A1: 800K frames above 400K (Ultimate (100), Proposed + temporal)", long,
                           published("ultimate100", "proposed-temporal"), 0.05, 0.029))
        at_400k = [runs.checkpoint(run, 400_000) for run in steps]
        if None not in at_400k:
            notes["A: paired 800K - 400K, same seeds"] = [b - a for a, b in zip(at_400k, long)]
        never = published("ultimate100", "proposed-temporal", csv_path=RESULTS / "readings" / "screening_seeds.csv",
                          seeds=range(2, 8), suite="earlier_never")
        found = welch_difference(long, never)
        notes["A: 800K - earlier_never seeds 2-7 (two-sided 95 % Welch)"] = (found.mean, found.low, found.high)
    offered = runs.cell("offered", "standard", "dqn_original-notemporal")
    if runs.finished(offered):
        success = runs.final(offered)
        tests.append(_test("D1: 3x3 DQN-Original below paper mode with every square offered",
                           published("standard", "dqn_original-notemporal"), success, 0.05, 0.9681 - 0.8258))
        rate = proportion_interval(success, GAMES)
        reward = t_interval(runs.final(offered, key="avg_reward"))
        notes["D: the paper's 0.8258 inside one new run"] = (rate.prediction_text(4), rate.holds(0.8258))
        notes["D: the paper's 0.0658 reward per act inside one new run"] = (reward.prediction_text(4), reward.holds(0.0658))
        notes["D: truncated share, dialogue length (paper 13.93)"] = (
            statistics.fmean(runs.final(offered, key="truncated")), statistics.fmean(runs.final(offered, key="avg_length")))
    temporal, plain = (runs.cell("paper", "ultimate150", cell) for cell in ("proposed-temporal", "proposed-notemporal"))
    if runs.finished(temporal + plain):
        with_features = published("ultimate150", "proposed-temporal") + runs.final(temporal)
        without = published("ultimate150", "proposed-notemporal") + runs.final(plain)
        tests.append(_test("E1: claim (ii) at 150 units, 10 seeds a side (second look)", with_features, without,
                           POCOCK_SECOND_LOOK, 0.9846 - 0.9473))
        tests.append(_test("E2: Proposed + temporal at 150 units (new seeds) below 100 units (difference: 100 - 150)",
                           published("ultimate100", "proposed-temporal"), runs.final(temporal), 0.05, 0.028))
        notes.update(snapshot_noise(runs, temporal, plain, with_features, without))
    # Holm's adjustment is over the whole family: until its four tests are read it is not printed
    adjusted = holm([test["p"] for test in tests]) if len(tests) == len(FAMILY) else [None] * len(tests)
    for test, holm_p in zip(tests, adjusted):
        test["holm_p"] = holm_p
    return tests, notes


def snapshot_noise(runs: Runs, temporal: list[GapRun], plain: list[GapRun], with_features: list[float],
                   without: list[float]) -> dict[str, Any]:
    """E3: the late checkpoints' spread within a run against one evaluation's and the seeds' spread, and the arms
    compared on each run's late level."""
    late = {name: [[runs.checkpoint(run, frames) for frames in LATE_CHECKPOINTS] for run in arm]
            for name, arm in (("with", temporal), ("without", plain))}
    if any(None in values for arm in late.values() for values in arm):
        return {"E3": "not every late checkpoint is evaluated"}
    within = statistics.fmean(statistics.stdev(values) for arm in late.values() for values in arm)
    level = statistics.fmean(value for arm in late.values() for values in arm for value in values)
    levels = {name: [statistics.fmean(values) for values in arm] for name, arm in late.items()}
    test = TwoSampleTest(tuple(levels["with"]), tuple(levels["without"]))
    return {"E3: mean within-run SD of the late checkpoints": within,
            "E3: binomial SD of one 3000-game evaluation": math.sqrt(level * (1 - level) / GAMES),
            "E3: between-seed SD of the final snapshots (with, without)": (statistics.stdev(with_features),
                                                                          statistics.stdev(without)),
            "E3: late levels per run (with; without)": (levels["with"], levels["without"]),
            "E3: with > without on the late levels, one-sided Welch (t, df, p)": test.welch}


def progress(runs: Runs) -> dict[str, tuple[int, int]]:
    """(finished, planned) runs of each question, (a) to (e)."""
    counts: dict[str, list[int]] = {}
    for run in runs.plan:
        done = counts.setdefault(run.part, [0, 0])
        done[0] += runs.final_evaluation(run).is_file()
        done[1] += 1
    return {part: (done[0], done[1]) for part, done in sorted(counts.items())}


def last_finished(runs: Runs) -> str:
    """The UTC date the latest finished run wrote its final evaluation: the date the verdicts were measured."""
    stamps = [path.stat().st_mtime for run in runs.plan if (path := runs.final_evaluation(run)).is_file()]
    return time.strftime("%Y-%m-%d", time.gmtime(max(stamps))) if stamps else "no date (no run finished)"


def complete(counts: dict[str, tuple[int, int]], part: str) -> bool:
    done, planned = counts.get(part, (0, 0))
    return planned > 0 and done == planned


def logged(runs: Runs) -> list[tuple[GapRun, Path]]:
    """Every logged evaluation of (b) and (c) that is written, with the run it belongs to."""
    found = []
    for run in runs.plan:
        for name in ("acts", "acts-step-000400000"):
            if (run.folder(runs.root) / name / "metrics.json").is_file():
                found.append((run, run.folder(runs.root) / name))
    return found


def _number(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_number(item) for item in value) + "]"
    if isinstance(value, float):
        return f"{value:.4f}" if abs(value) >= 1e-4 or value == 0 else f"{value:.1e}"
    return str(value)


def render(tests: list[dict[str, Any]], notes: dict[str, Any], sources: list[tuple[str, dict]], acts: list[tuple[str, dict]],
           command: str, finished: dict[str, tuple[int, int]], last_finished: str) -> str:
    lines = ["# The remaining gaps: the verdicts of the tests fixed before the runs", "",
             f"Made by `{command}` from the runs of `python -m ncbot.pipelines.reproduce.gaps run` and the published "
             "seeds CSVs; the plan, its seeds and what each outcome means: docs/reproduction.md, \"The remaining gaps\".",
             "", f"Runs finished by {last_finished}, by question: " + ", ".join(f"{part} {done} of {planned}" for part, (done, planned)
                                                            in finished.items()) + ". A question is read only when all"
             " its runs are finished; Holm's p over the four is printed once the four are read.",
             "", "## The family (A1, D1, E1, E2)", "",
             "One-sided Welch's t-test over seeds (one sample = one seed's 3000 robot-first test games), each at its "
             "level; Holm over the four beside. Power: the Welch test as run, each side at its measured spread, to "
             "detect the effect named in the plan; \"smallest effect\": detected with power 0.8.", "",
             "| test | seeds | means | difference [95 % Welch] | t, df | p | level | Holm p | power at | smallest effect "
             "| verdict |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for test in tests:
        holm_text = "pending" if test["holm_p"] is None else _number(test["holm_p"])
        lines.append(f"| {test['test']} | {test['n'][0]} vs {test['n'][1]} | {_number(test['means'])} | "
                     f"{_number(test['difference'])} {_number(test['interval'])} | {_number(test['t'])}, "
                     f"{_number(test['df'])} | {_number(test['p'])} | {test['alpha']} | {holm_text} | "
                     f"{test['power']:.2f} at {test['power_at']:.4f} | {test['minimum_effect']:.4f} | {test['verdict']} |")
    if not tests:
        lines.append("| no test's runs are all finished | – | – | – | – | – | – | – | – | – | – |")
    lines += ["", "## Secondary readings (describe, decide nothing)", ""]
    lines += [f"- {name}: {_number(value)}" for name, value in notes.items()] or ["- none finished"]
    lines += ["", "## (b) Average reward per act by source (500 robot-first test games a checkpoint)", "",
              "| run | games | acts | avg reward | " + " | ".join(SOURCES) + " |", "|---|---|---|---|" + "---|" * len(SOURCES)]
    for name, found in sources:
        lines.append(f"| {name} | {found['games']} | {found['acts']} | {found['avg_reward']:.4f} | "
                     + " | ".join(f"{found['per_act'][source]:.4f}" for source in SOURCES) + " |")
    lines += ["", "## (c) Where the dialogue length goes (`ncbot logs acts`, the same games)", "",
              "| run | dialogue length | game moves | of which refused | other acts, mean per game |", "|---|---|---|---|---|"]
    for name, table in acts:
        every = table["groups"]["all"]
        moves = every["acts"].get(GAME_MOVES, 0.0)
        others = ", ".join(f"{act} {count:.2f}" for act, count in every["acts"].items() if act not in (GAME_MOVES, REFUSED))
        lines.append(f"| {name} | {every['mean_length']:.2f} | {moves:.2f} | {every['acts'].get(REFUSED, 0.0):.2f} | {others} |")
    return "\n".join(lines) + "\n"


def write_gaps_report(runs: Path, out: Path, command: str | None = None) -> list[Path]:
    """results/gaps/README.md (and its JSON) from whatever questions are finished."""
    from ncbot.logs.acts import act_table

    finished = Runs(runs)
    tests, notes = family(finished)
    counts = progress(finished)
    sources, acts = [], []
    read_sources, read_acts = complete(counts, "(b)"), complete(counts, "(c)")
    for run, folder in logged(finished):  # (b) and (c) read every logged evaluation, once their own runs finished
        name = f"{run.name}{'' if folder.name == 'acts' else ' at 400K'}"
        if read_sources:
            sources.append((name, reward_sources(folder)))
        if read_acts:
            acts.append((name, act_table(folder)))
    command = command or f"python -m ncbot.pipelines.reproduce.gaps report --runs {runs} --out {out}"
    out.mkdir(parents=True, exist_ok=True)
    markdown, data = out / "README.md", out / "verdicts.json"
    atomic_write_text(render(tests, notes, sources, acts, command, counts, last_finished(finished)), markdown)
    atomic_write_text(json.dumps({"command": command, "finished": counts, "tests": tests, "notes": notes,
                                  "sources": dict(sources)}, indent=2, default=str) + "\n", data)
    return [markdown, data]
