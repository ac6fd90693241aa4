"""`ncbot table`: the paper-style results table (mean and 95 % t-interval over seeds, the paper's numbers beside
ours, whether the paper's task success lies inside our interval), the paper's claims tested over seeds
(`pipelines.reproduce.claims`) and learning-curve PNGs per agent, read from the run folders of `ncbot ablate`.

Runs are found as RUNS_DIR/<suite>/<game row>/<agent cell>/seed<N>/eval.json. The table reports the robot-first
seat (the paper's set-up) and adds the robot-second task success. Seeds are the repetitions: each seed's
evaluation mean is one sample, so the intervals describe how much a result moves between training runs.
"""
from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from fileio import atomic_write_text
from pipelines.reproduce.claims import CELL_LABELS, GAME_LABELS, Claim, evaluate_claims, mean_and_variance, render_claims

# Paper (Cuayahuitl 2019) table: (avg reward per action, task success, dialogue length); paper-notes section 5.
PAPER = {
    ("standard", "dqn_original-notemporal"): (0.0658, 0.8258, 13.93),
    ("standard", "dqn_variant-notemporal"): (0.5530, 0.9720, 13.99),
    ("standard", "proposed-notemporal"): (0.4710, 0.9868, 15.31),
    ("standard", "proposed-temporal"): (0.6300, 0.9980, 14.06),
    ("ultimate100", "dqn_original-notemporal"): (-0.6900, 0.7873, 63.54),
    ("ultimate100", "dqn_variant-notemporal"): (0.0177, 0.9074, 64.82),
    ("ultimate100", "proposed-notemporal"): (0.0693, 0.9377, 63.62),
    ("ultimate100", "proposed-temporal"): (0.1440, 0.9753, 52.03),
    ("ultimate150", "dqn_original-notemporal"): (-0.1120, 0.7290, 65.49),
    ("ultimate150", "dqn_variant-notemporal"): (-0.0310, 0.8663, 70.57),
    ("ultimate150", "proposed-notemporal"): (0.0997, 0.9473, 59.69),
    ("ultimate150", "proposed-temporal"): (0.1640, 0.9846, 52.09),
}
GAME_ORDER = list(GAME_LABELS)
CELL_ORDER = list(CELL_LABELS)
CONFIDENCE = 0.95

# metric name -> where it sits in eval.json; the first three are the paper's columns, robot first.
METRICS = {
    "avg_reward": ("first", "avg_reward"), "task_success": ("first", "task_success"),
    "avg_length": ("first", "avg_length"), "task_success_second": ("second", "task_success"),
    "train_wall_time_s": ("train_wall_time_s",),
}
EXPECTED = ("expected the JSON object `ncbot train` writes, with numbers 'frames', 'train_wall_time_s', "
            "'first.avg_reward', 'first.task_success', 'first.avg_length' and 'second.task_success'")


@dataclass(frozen=True)
class Interval:
    """Mean over seeds and its two-sided Student t-interval (low/high None with a single seed)."""

    mean: float
    low: float | None
    high: float | None
    n: int

    def holds(self, value: float) -> str:
        """"yes"/"no": is ``value`` inside the interval; "n<2" when there is no interval."""
        if self.low is None:
            return "n<2"
        return "yes" if self.low <= value <= self.high else "no"

    def text(self, digits: int) -> str:
        if self.low is None:
            return f"{self.mean:.{digits}f} [n<2]"
        return f"{self.mean:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def t_interval(values: list[float], confidence: float = CONFIDENCE) -> Interval:
    """mean ± t(1 - (1 - confidence) / 2, n - 1) * s / sqrt(n), s the sample std over seeds; identical values give
    a zero-width interval at that value (no NaN); a single value has no interval."""
    from scipy.stats import t as student_t

    if not values:
        raise ValueError("t_interval needs at least one value")
    mean, variance = mean_and_variance(values)
    if len(values) < 2:
        return Interval(mean, None, None, 1)
    half = float(student_t.ppf(1 - (1 - confidence) / 2, len(values) - 1)) * math.sqrt(variance / len(values))
    return Interval(mean, mean - half, mean + half, len(values))


@dataclass(frozen=True)
class Row:
    """One (suite, game, agent) row: per-metric intervals over seeds and the paper's numbers, if any."""

    suite: str
    game: str
    cell: str
    frames: tuple[int, ...]
    stats: dict[str, Interval]

    @property
    def paper(self) -> tuple[float, float, float] | None:
        return PAPER.get((self.game, self.cell))

    @property
    def paper_inside(self) -> str | None:
        """Whether the paper's task success lies inside our task-success interval (None: no paper number)."""
        return None if self.paper is None else self.stats["task_success"].holds(self.paper[1])

    def to_dict(self) -> dict[str, Any]:
        paper = dict(zip(("avg_reward", "task_success", "avg_length"), self.paper)) if self.paper else None
        return {"suite": self.suite, "game": self.game, "agent": self.cell,
                "game_label": GAME_LABELS.get(self.game, self.game), "agent_label": CELL_LABELS.get(self.cell, self.cell),
                "seeds": self.stats["task_success"].n, "frames": list(self.frames),
                **{name: asdict(interval) for name, interval in self.stats.items()},
                "paper": paper, "paper_inside_ours": self.paper_inside}


def _number(data: dict, where: tuple[str, ...], path: Path) -> float:
    value: Any = data
    for key in where:
        if not isinstance(value, dict) or key not in value:
            raise ValueError(f"{path} has no '{'.'.join(where)}'; {EXPECTED}")
        value = value[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{path}: '{'.'.join(where)}' is {value!r}, not a finite number; {EXPECTED}")
    return value


def read_eval(path: Path) -> dict[str, Any]:
    """A finished run's eval.json, checked: a bad file is one ValueError naming it and what was expected."""
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path} is not JSON ({error}); {EXPECTED}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} holds a JSON {type(data).__name__}, not an object; {EXPECTED}")
    for where in (("frames",), *METRICS.values()):
        _number(data, where, path)
    history = data.get("history", [])
    if not isinstance(history, list) or not all(isinstance(h, dict) and "frames" in h for h in history):
        raise ValueError(f"{path}: 'history' must be a list of objects with 'frames' (the learning curve)")
    return data


def collect_runs(runs_dir: str | Path) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """(suite, game row, agent cell) -> finished runs' eval.json contents, seeds in order."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        raise FileNotFoundError(f"runs folder {str(runs_dir)!r} not found (expected the folder ncbot ablate wrote)")
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = defaultdict(list)
    for path in sorted(runs_dir.glob("*/*/*/seed*/eval.json")):
        suite, game, cell = path.relative_to(runs_dir).parts[:3]
        groups[(suite, game, cell)].append(read_eval(path))
    if not groups:
        raise FileNotFoundError(f"no finished runs (*/*/*/seed*/eval.json) under {str(runs_dir)!r}")
    return dict(groups)


def seed_samples(groups: dict[tuple[str, str, str], list[dict[str, Any]]]) -> dict[tuple[str, str, str], dict[str, list[float]]]:
    """(suite, game, cell) -> metric name -> one value per seed."""
    def value(run: dict[str, Any], where: tuple[str, ...]) -> float:
        for key in where:
            run = run[key]
        return run

    return {key: {name: [value(run, where) for run in runs] for name, where in METRICS.items()}
            for key, runs in groups.items()}


def _order(key: tuple[str, str, str]) -> tuple:
    suite, game, cell = key
    return (GAME_ORDER.index(game) if game in GAME_ORDER else 99, game,
            CELL_ORDER.index(cell) if cell in CELL_ORDER else 99, cell, suite != "fast", suite)


def table_rows(groups: dict[tuple[str, str, str], list[dict[str, Any]]]) -> list[Row]:
    samples = seed_samples(groups)
    return [Row(*key, frames=tuple(sorted({run["frames"] for run in groups[key]})),
                stats={name: t_interval(values) for name, values in samples[key].items()})
            for key in sorted(groups, key=_order)]


def render_table(rows: list[Row], command: str, claims_name: str = "paper_claims.md") -> str:
    """Markdown: how the statistics were computed, then one row per (game, agent, suite), the paper's beside."""
    pct = f"{CONFIDENCE:.0%}"
    lines = [
        "# Our results beside the paper's table",
        "",
        f"Made by `{command}`; the paper's claims tested over seeds are in `{claims_name}`.",
        "",
        f"Each of our cells: mean over seeds [{pct} Student t-interval over seeds: mean ± t(0.975, n-1)·s/√n, "
        "s = sample std of the per-seed evaluation means]; \"[n<2]\" = a single seed, no interval. Metrics are "
        "robot-first (the paper's set-up) except \"task success, robot second\"; train time is the mean wall time "
        "over seeds. \"paper inside ours?\" = whether the paper's task success lies inside our task-success "
        f"interval (\"n<2\": one seed, not tested; \"–\": no paper number). Paper columns: Cuayáhuitl 2019.",
        "",
        "| game (units) | agent | settings | seeds | frames | avg reward | task success | paper inside ours? "
        "| dialogue length | task success, robot second | train time (s) | paper avg reward | paper task success "
        "| paper length |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        paper = ([f"{row.paper[0]:.4f}", f"{row.paper[1]:.4f}", f"{row.paper[2]:.2f}"] if row.paper else ["–"] * 3)
        stats = row.stats
        lines.append(" | ".join([
            f"| {GAME_LABELS.get(row.game, row.game)}", CELL_LABELS.get(row.cell, row.cell), row.suite,
            str(stats["task_success"].n), "/".join(str(f) for f in row.frames),
            stats["avg_reward"].text(4), stats["task_success"].text(4), row.paper_inside or "–",
            stats["avg_length"].text(2), stats["task_success_second"].text(4),
            f"{stats['train_wall_time_s'].mean:.0f}", *paper,
        ]) + " |")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Report:
    command: str
    rows: list[Row]
    claims: list[Claim]
    table: str
    claims_text: str

    def to_dict(self) -> dict[str, Any]:
        return {"command": self.command, "confidence": CONFIDENCE, "interval": "Student t over seeds",
                "rows": [row.to_dict() for row in self.rows], "claims": [claim.to_dict() for claim in self.claims]}


def write_report(runs_dir: str | Path, out: str | Path | None = None, claims_out: str | Path | None = None,
                 command: str | None = None) -> Report:
    """Write the table (default RUNS_DIR/table.md), the claims (default paper_claims.md beside it) and
    curves_<suite>_<game>.png next to the table."""
    from pipelines.plots import plot_agent_curves

    runs_dir = Path(runs_dir)
    out = Path(out) if out else runs_dir / "table.md"
    claims_out = Path(claims_out) if claims_out else out.parent / "paper_claims.md"
    if out.resolve() == claims_out.resolve():
        raise ValueError(f"the table and the claims would both be written to {str(out)!r}; pass --claims FILE")
    command = command or f"ncbot table {runs_dir} --out {out} --claims {claims_out}"
    groups = collect_runs(runs_dir)
    rows, claims = table_rows(groups), evaluate_claims(seed_samples(groups))
    report = Report(command, rows, claims, render_table(rows, command, claims_out.name), render_claims(claims, command))
    for path, text in ((out, report.table), (claims_out, report.claims_text)):
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(text, path)
    by_plot: dict[tuple[str, str], dict[str, list]] = defaultdict(dict)
    for (suite, game, cell), runs in groups.items():
        by_plot[(suite, game)][CELL_LABELS.get(cell, cell)] = [r.get("history", []) for r in runs]
    for (suite, game), curves in by_plot.items():
        plot_agent_curves(curves, out.parent / f"curves_{suite}_{game}.png",
                          title=f"{GAME_LABELS.get(game, game)}, {suite} settings: mean over seeds, band min..max")
    return report


def write_table(runs_dir: str | Path, out: str | Path | None = None) -> str:
    """Write the table, claims and curves (see `write_report`) and return the table's markdown."""
    return write_report(runs_dir, out).table
