"""`ncbot table`: the paper-style results table (mean over seeds with a 95 % confidence interval, the prediction
interval of one new run, the paper's numbers beside ours and whether the paper's single run lies inside that
prediction interval), every seed's values as CSV beside it, the paper's claims tested over seeds
(`ncbot.pipelines.reproduce.claims`) and learning-curve PNGs per agent, read from the run folders of `ncbot ablate`.

Runs are found as RUNS_DIR/<suite>/<game row>/<agent cell>/seed<N>/eval.json. The table reports the robot-first
seat (the paper's set-up), the outcome broken down (truncated games, games that reached an all-negative state) and
the robot-second task success. Seeds are the repetitions: each seed's evaluation mean is one sample, so the
intervals describe how much a result moves between training runs (`ncbot.pipelines.reproduce.seed_stats`). Two seed
folders holding the same run (a copied folder) are refused, since they would count one run twice.
"""
from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.reproduce.claims import (CELL_LABELS, GAME_LABELS, PAPER, Claim, evaluate_claims, render_claims,
                                              render_reward_order)
from ncbot.pipelines.reproduce.pooled import pooled_comparisons, pooled_dict, pooled_scores, render_pooled
from ncbot.pipelines.reproduce.seed_stats import CONFIDENCE, Interval, proportion_interval, t_interval
from ncbot.pipelines.reproduce.seeds_csv import is_seeds_csv, read_seeds_csv

GAME_ORDER = list(GAME_LABELS)
CELL_ORDER = list(CELL_LABELS)

# metric name -> where it sits in eval.json; the first three are the paper's columns, robot first.
METRICS = {
    "avg_reward": ("first", "avg_reward"), "task_success": ("first", "task_success"),
    "avg_length": ("first", "avg_length"), "task_success_second": ("second", "task_success"),
    "train_wall_time_s": ("train_wall_time_s",),
}
# rates measured over test games: their intervals are computed on the logit scale (they stay inside [0, 1])
RATES = {"task_success": "first", "task_success_second": "second", "truncated": "first", "all_negative": "first"}
# metrics an older eval.json may lack (shown as "–")
OPTIONAL = {"truncated": ("first", "truncated"), "all_negative": ("first", "all_negative")}
CSV_COLUMNS = ("suite", "game", "agent", "seed", "run_id", "frames", "episodes", "train_wall_time_s",
               *(f"{seat}.{key}" for seat in ("first", "second") for key in
                 ("games", "win", "draw", "loss", "truncated", "all_negative", "task_success", "avg_reward",
                  "avg_length")))
DEFAULT_GAMES = 3000  # test games per seat when an eval.json does not say
EXPECTED = ("expected the JSON object `ncbot train` writes, with numbers 'frames', 'train_wall_time_s', "
            "'first.avg_reward', 'first.task_success', 'first.avg_length' and 'second.task_success'")


@dataclass(frozen=True)
class Row:
    """One (suite, game, agent) row: per-metric intervals over seeds and the paper's numbers, if any."""

    suite: str
    game: str
    cell: str
    frames: tuple[int, ...]  # one per seed, in seed order
    stats: dict[str, Interval]
    widths: tuple[tuple[int, ...], ...] = ()  # the runs' hidden layer widths (config.yaml), distinct, in seed order
    played: str | None = None  # the runs' env.game (config.yaml), when they say

    @property
    def game_label(self) -> str:
        """The game and the hidden widths the runs were trained with (from their config.yaml): "3x3 (256, 256)".
        Without a config.yaml the row key's label, which assumes the paper's widths ("3x3 (100)"); an agent that
        learns nothing (0 frames) has no network: the game alone ("3x3")."""
        game = self.played or ("ultimate" if self.game.startswith("ultimate") else "standard")
        base = {"standard": "3x3", "ultimate": "Ultimate"}.get(game, game)
        if set(self.frames) == {0}:
            return base
        if not self.widths:
            return GAME_LABELS.get(self.game, self.game)
        return f"{base} (" + " | ".join(", ".join(str(w) for w in hidden) for hidden in self.widths) + ")"

    @property
    def paper(self) -> tuple[float, float, float] | None:
        return PAPER.get((self.game, self.cell))

    @property
    def paper_inside(self) -> str | None:
        """Whether the paper's single run lies inside the prediction interval of one new run of ours (None: no
        paper number)."""
        return None if self.paper is None else self.stats["task_success"].holds(self.paper[1])

    @property
    def paper_reward_inside(self) -> str | None:
        """The same for the paper's average reward per act."""
        return None if self.paper is None else self.stats["avg_reward"].holds(self.paper[0])

    def to_dict(self) -> dict[str, Any]:
        paper = dict(zip(("avg_reward", "task_success", "avg_length"), self.paper)) if self.paper else None
        return {"suite": self.suite, "game": self.game, "agent": self.cell,
                "game_label": self.game_label, "agent_label": CELL_LABELS.get(self.cell, self.cell),
                "seeds": self.stats["task_success"].n, "frames": list(self.frames),
                **{name: asdict(interval) for name, interval in self.stats.items()},
                "paper": paper, "paper_inside_ours": self.paper_inside,
                "paper_avg_reward_inside_ours": self.paper_reward_inside}


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


def _seed_of(path: Path) -> int:
    folder = path.parent.name
    try:
        return int(folder.removeprefix("seed"))
    except ValueError:
        raise ValueError(f"{path}: run folder {folder!r} is not seed<N> (the layout ncbot ablate writes)") from None


def _identity(run: dict[str, Any]) -> str:
    """What makes two runs the same run: the run id `ncbot train` writes, else the whole evaluation."""
    return run.get("run_id") or json.dumps({k: run.get(k) for k in ("frames", "first", "second", "history")},
                                           sort_keys=True)


def run_settings(run_dir: Path) -> dict[str, Any]:
    """What a run was trained with, from its config.yaml: the hidden widths and game (the table's row labels) and
    its temporal information (memory, temporal features, batch size) and reward (the memory report's arms and
    recipes). A setting the file
    does not hold (or no readable file) is left out: the table then labels the row by its key."""
    import yaml

    try:
        config = yaml.safe_load((run_dir / "config.yaml").read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return {}
    if not isinstance(config, dict):
        return {}
    env, agent, buffer, loss = (config.get(key) if isinstance(config.get(key), dict) else {}
                                for key in ("env", "agent", "buffer", "loss"))
    settings: dict[str, Any] = {"memory": str(agent.get("memory", "none")), "reward": str(loss.get("reward", "paper"))}
    if isinstance(agent.get("hidden"), list):
        settings["hidden"] = tuple(int(width) for width in agent["hidden"])
    if isinstance(env.get("game"), str):
        settings["played"] = env["game"]
    if "temporal" in env:
        settings["temporal"] = bool(env["temporal"])
    if isinstance(buffer.get("batch_size"), int):
        settings["batch_size"] = buffer["batch_size"]
    return settings


def collect_runs(runs_dir: str | Path) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """(suite, game row, agent cell) -> finished runs' eval.json contents (with their "seed"), seeds in order.

    Two seed folders of a cell that hold the same run are one ValueError naming both."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        raise FileNotFoundError(f"runs folder {str(runs_dir)!r} not found (expected the folder ncbot ablate wrote)")
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = defaultdict(list)
    seen: dict[tuple[tuple[str, str, str], str], Path] = {}
    paths = sorted(runs_dir.glob("*/*/*/seed*/eval.json"), key=lambda path: (path.parts[:-2], _seed_of(path)))
    for path in paths:
        key = tuple(path.relative_to(runs_dir).parts[:3])
        run = {**read_eval(path), "seed": _seed_of(path), **run_settings(path.parent)}
        twin = seen.setdefault((key, _identity(run)), path)
        if twin != path:
            raise ValueError(f"{twin.parent} and {path.parent} hold the same run (same run id or identical results): "
                             "a copied seed folder; keep one and re-run the other seed")
        groups[key].append(run)
    if not groups:
        raise FileNotFoundError(f"no finished runs (*/*/*/seed*/eval.json) under {str(runs_dir)!r}")
    return dict(groups)


def _value(run: dict[str, Any], where: tuple[str, ...]) -> float | None:
    for key in where:
        if not isinstance(run, dict) or key not in run:
            return None
        run = run[key]
    return run


def seed_samples(groups: dict[tuple[str, str, str], list[dict[str, Any]]]) -> dict[tuple[str, str, str], dict[str, list[float]]]:
    """(suite, game, cell) -> metric name -> one value per seed (an optional metric only where every seed has it)."""
    samples = {}
    for key, runs in groups.items():
        values = {name: [_value(run, where) for run in runs] for name, where in {**METRICS, **OPTIONAL}.items()}
        samples[key] = {name: found for name, found in values.items() if None not in found}
    return samples


def _interval(name: str, values: list[float], runs: list[dict[str, Any]]) -> Interval:
    """A rate over test games gets the logit-scale interval (stays inside [0, 1]); the rest Student t."""
    if name not in RATES:
        return t_interval(values)
    games = min(int(_value(run, (RATES[name], "games")) or DEFAULT_GAMES) for run in runs)
    return proportion_interval(values, games)


def _order(key: tuple[str, str, str]) -> tuple:
    suite, game, cell = key
    return (GAME_ORDER.index(game) if game in GAME_ORDER else 99, game,
            CELL_ORDER.index(cell) if cell in CELL_ORDER else 99, cell, suite != "fast", suite)


def table_rows(groups: dict[tuple[str, str, str], list[dict[str, Any]]],
               samples: dict[tuple[str, str, str], dict[str, list[float]]]) -> list[Row]:
    """One row per (suite, game row, agent cell), in table order, from the runs and their `seed_samples`. An agent
    without a network (0 frames, e.g. the uniform choice inside the masks) plays the same games at every width, so
    its second game row of one game (Ultimate 100 and 150) is the same row again and is shown once."""
    rows = [Row(*key, frames=tuple(run["frames"] for run in groups[key]),
                stats={name: _interval(name, values, groups[key]) for name, values in samples[key].items()},
                widths=tuple(dict.fromkeys(run["hidden"] for run in groups[key] if "hidden" in run)),
                played=next((run["played"] for run in groups[key] if "played" in run), None))
            for key in sorted(groups, key=_order)]
    shown, seen = [], set()
    for row in rows:
        untrained = (row.suite, row.cell, row.game_label) if set(row.frames) == {0} else None
        if untrained is not None and untrained in seen:
            continue
        shown.append(row)
        if untrained is not None:
            seen.add(untrained)
    return shown


def seeds_csv(groups: dict[tuple[str, str, str], list[dict[str, Any]]]) -> str:
    """Every seed's numbers, one row per run, in table order (CSV_COLUMNS; empty where a run lacks a value)."""
    import csv
    import io

    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for key in sorted(groups, key=_order):
        for run in groups[key]:
            found = [_value(run, tuple(column.split("."))) for column in CSV_COLUMNS[3:]]
            writer.writerow([*key, *("" if value is None else value for value in found)])
    return buffer.getvalue()


def _optional(stats: dict[str, Interval], name: str, digits: int) -> str:
    return stats[name].text(digits) if name in stats else "–"


def render_table(rows: list[Row], command: str, claims_name: str = "paper_claims.md", seeds_name: str = "table_seeds.csv") -> str:
    """Markdown: how the statistics were computed, then one row per (game, agent, suite), the paper's beside."""
    pct = f"{CONFIDENCE:.0%}"
    lines = [
        "# Our results beside the paper's table",
        "",
        f"Made by `{command}`; every seed's values are in `{seeds_name}`; the paper's claims tested over seeds are in "
        f"`{claims_name}`.",
        "",
        f"Each of our cells: mean over seeds [{pct} confidence interval of that mean]. Rates over test games (task "
        "success, truncated, all-negative) get a Student t-interval of the per-seed logits, mapped back (so it stays "
        "inside [0, 1]; each seed's rate is taken as (p·N + 0.5) / (N + 1) for N test games); the other metrics a "
        "Student t-interval, mean ± t(0.975, n-1)·s/√n. \"one new run\" is the prediction interval of a single "
        "further run of ours (±t·s·√(1 + 1/n), on the logit scale), the interval the paper's single run is held "
        "against in \"paper inside?\" (\"n<2\": one seed, not tested; \"–\": no paper number), and the paper's "
        "average reward in \"paper avg reward inside?\" (the same interval of our average reward). \"[n<2]\" = a "
        "single seed, no interval; \"†\": the plain mean over seeds lies outside its logit-scale interval (one seed far "
        "from the others). Metrics are robot-first (the paper's set-up) except \"task success, robot second\". "
        "Truncated: games cut at the act cap with the game unfinished (counted as not won or drawn). All-negative: "
        "games that reached a state where every offered game move had a negative look-ahead reward, where the "
        "masks fall back. Frames: per seed, in seed order. Train time: mean wall time over seeds. Paper columns: "
        "Cuayáhuitl 2019.",
        "",
        "| game (units) | agent | settings | seeds | frames | avg reward | task success | one new run "
        "| paper task success | paper inside? | truncated | all-negative | dialogue length "
        "| task success, robot second | train time (s) | paper avg reward | paper avg reward inside? | paper length |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        stats = row.stats
        paper = row.paper
        lines.append(" | ".join([
            f"| {row.game_label}", CELL_LABELS.get(row.cell, row.cell), row.suite,
            str(stats["task_success"].n), "/".join(str(f) for f in row.frames),
            stats["avg_reward"].text(4), stats["task_success"].text(4), stats["task_success"].prediction_text(4),
            f"{paper[1]:.4f}" if paper else "–", row.paper_inside or "–",
            _optional(stats, "truncated", 4), _optional(stats, "all_negative", 4),
            stats["avg_length"].text(2), stats["task_success_second"].text(4),
            f"{stats['train_wall_time_s'].mean:.0f}",
            f"{paper[0]:.4f}" if paper else "–", row.paper_reward_inside or "–", f"{paper[2]:.2f}" if paper else "–",
        ]) + " |")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Report:
    command: str
    rows: list[Row]
    claims: list[Claim]
    table: str
    claims_text: str
    pooled: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {"command": self.command, "confidence": CONFIDENCE,
                "interval": "Student t over seeds (rates: on the logit scale); prediction interval of one new run",
                "rows": [row.to_dict() for row in self.rows], "claims": [claim.to_dict() for claim in self.claims],
                "pooled": self.pooled}


def write_report(runs_dir: str | Path, out: str | Path | None = None, claims_out: str | Path | None = None,
                 command: str | None = None) -> Report:
    """Write the table (default RUNS_DIR/table.md), the claims (default paper_claims.md beside it),
    curves_<suite>_<game>.png and every run's task success as <table>_profiles.png next to the table.

    ``runs_dir`` may also be a table's <table>_seeds.csv (`ncbot.pipelines.reproduce.seeds_csv`): the same table,
    claims, seeds CSV and profiles from the numbers it holds (default out: <table>.md beside it), no curves."""
    from ncbot.pipelines.plots import plot_agent_curves, plot_run_profiles

    runs_dir = Path(runs_dir)
    from_csv = is_seeds_csv(runs_dir)  # a published <table>_seeds.csv in place of the run folders
    default_out = runs_dir.with_name(runs_dir.stem.removesuffix("_seeds") + ".md") if from_csv else runs_dir / "table.md"
    out = Path(out) if out else default_out
    claims_out = Path(claims_out) if claims_out else out.parent / "paper_claims.md"
    if out.resolve() == claims_out.resolve():
        raise ValueError(f"the table and the claims would both be written to {str(out)!r}; pass --claims FILE")
    command = command or f"ncbot table {runs_dir} --out {out} --claims {claims_out}"
    groups = read_seeds_csv(runs_dir) if from_csv else collect_runs(runs_dir)
    seeds_out = out.with_name(f"{out.stem}_seeds.csv")
    samples = seed_samples(groups)
    rows, claims = table_rows(groups, samples), evaluate_claims(samples)
    shown = {(row.suite, row.game, row.cell): row.game_label for row in rows}  # an untrained agent's Ultimate once
    scores = pooled_scores({key: values for key, values in samples.items() if key in shown}, shown)
    comparisons = pooled_comparisons(samples)
    report = Report(command, rows, claims, render_table(rows, command, claims_out.name, seeds_out.name),
                    render_claims(claims, command) + "\n" + render_reward_order(samples) + render_pooled(scores, comparisons),
                    pooled_dict(scores, comparisons))
    for path, text in ((out, report.table), (claims_out, report.claims_text), (seeds_out, seeds_csv(groups))):
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(text, path)
    by_plot: dict[tuple[str, str], dict[str, list]] = defaultdict(dict)
    levels: dict[tuple[str, str], dict[str, tuple[float, float]]] = defaultdict(dict)
    for (suite, game, cell), runs in groups.items():
        label = CELL_LABELS.get(cell, cell)
        if all(run["frames"] == 0 for run in runs):  # no learning: a level, not a curve
            levels[(suite, game)][label] = tuple(
                sum(run[seat]["task_success"] for run in runs) / len(runs) for seat in ("first", "second"))
        else:
            by_plot[(suite, game)][label] = [r.get("history", []) for r in runs]
    profiles: dict[str, dict[str, list[float]]] = defaultdict(dict)
    for (suite, game, cell), values in sorted(samples.items(), key=lambda item: (item[0][0], _order(item[0]))):
        profiles[f"{GAME_LABELS.get(game, game)}, {suite} settings"][CELL_LABELS.get(cell, cell)] = values["task_success"]
    plot_run_profiles(profiles, out.with_name(f"{out.stem}_profiles.png"),
                      title="every run: the share of an agent's seeds above each task success, robot first")
    for (suite, game) in ([] if from_csv else sorted(set(by_plot) | set(levels))):  # a CSV holds no curves
        plot_agent_curves(by_plot.get((suite, game), {}), out.parent / f"curves_{suite}_{game}.png",
                          title=f"{GAME_LABELS.get(game, game)}, {suite} settings: mean over seeds, band min..max",
                          levels=levels.get((suite, game)))
    return report


def write_table(runs_dir: str | Path, out: str | Path | None = None) -> str:
    """Write the table, claims and curves (see `write_report`) and return the table's markdown."""
    return write_report(runs_dir, out).table
