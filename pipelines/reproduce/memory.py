"""`ncbot reproduce memory RUNS_DIR...`: temporal information three ways (none, the paper's temporal features, a
recurrent Q-network, both), compared over seeds from the runs of `ncbot ablate` grids such as
pipelines/configs/memory_question.yaml (3x3) and memory_ultimate.yaml (Ultimate), one report for every game.

Why its own report: the paper's table compares agents; this one compares how the Proposed agent learns the order of
the moves, so each arm is told apart by what its runs were trained with (config.yaml: `agent.memory`,
`env.temporal`, `buffer.batch_size`) and its recipe (`loss.reward`: the paper's protocol trains on the paper's
rewards, the default recipes on game outcomes; arms of two recipes are never compared), and the report adds what
the choice costs: parameters, training time per
frame and training games to 0.95. Every comparison is a one-sided Welch's t-test over seeds (one sample = one
seed's robot-first task success), with the 95 % interval of the difference, its power to detect the paper's own
difference for claim (ii) on that game and a Holm-adjusted p over the family of comparisons.
"""
from __future__ import annotations

import statistics
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.reproduce.aggregate import BOOTSTRAP_REPS, interval_text
from ncbot.pipelines.reproduce.memory_records import (CURVES_CSV, SEEDS_CSV, THRESHOLDS, ArmKey, curves_csv,
                                                      games_to, read_records, seeds_csv)
from ncbot.pipelines.reproduce.seed_stats import Interval, proportion_interval, t_interval
from ncbot.pipelines.reproduce.table import DEFAULT_GAMES, collect_runs
from ncbot.pipelines.reproduce.two_sample import (ALPHA, NOT_SHOWN, POWER, SHOWN, UNTESTED, TwoSampleTest, holm,
                                                  welch_difference)

MARKDOWN = "table.md"
FIGURE = "curves.png"
GAME_LABELS = {"standard": "3x3", "ultimate": "Ultimate"}
#: claim (ii), Proposed + temporal minus Proposed in the paper's table: 3x3, and Ultimate at 100 units (the width of
#: the memory grids)
PAPER_DIFFERENCE = {"standard": 0.9980 - 0.9868, "ultimate": 0.9753 - 0.9377}
#: the recipe, told by the reward the learner trains on (`loss.reward`)
RECIPES = {"paper": "the paper's protocol", "outcome": "default recipe"}


@dataclass(frozen=True)
class Arm:
    """The runs of one way of giving the agent the move order, at one batch size, on one game."""

    game: str
    reward: str  # paper | outcome: the recipe (RECIPES)
    memory: str  # none | gru | lstm
    temporal: bool
    batch_size: int
    runs: tuple[dict[str, Any], ...]  # eval.json contents with "seed", "params" and "config" added

    @property
    def key(self) -> ArmKey:
        return self.game, self.reward, self.memory, self.temporal, self.batch_size

    @property
    def label(self) -> str:
        features = "temporal features" if self.temporal else "no temporal features"
        network = "feed-forward" if self.memory == "none" else self.memory.upper()
        return f"{network}, {features}, batch {self.batch_size}{recipe_suffix(self.reward)}"

    def values(self, metric: str) -> list[float]:
        return [value for run in self.runs if (value := run_metric(run, metric)) is not None]


def recipe_suffix(reward: str) -> str:
    """What a label adds for the recipe: nothing for the paper's protocol (the report's first and main setting)."""
    return "" if reward == "paper" else f", {RECIPES.get(reward, reward)}"


def run_metric(run: dict[str, Any], metric: str) -> float | None:
    """One seed's value of ``metric`` (None when the run does not have it, e.g. 0.95 never reached)."""
    if metric == "ms_per_frame":
        return 1000 * run["train_wall_time_s"] / run["frames"] if run["frames"] else None
    if metric.startswith("games_to_"):
        return games_to(run, float(metric.removeprefix("games_to_")))
    if metric == "params":
        return run.get("params")
    seat, _, key = metric.partition(".")
    return run[seat][key]


def _params(checkpoint: Path) -> int | None:
    """Parameters of the run's Q-network, counted from its checkpoint (None without one)."""
    import torch

    if not checkpoint.is_file():
        return None
    state = torch.load(checkpoint, map_location="cpu", weights_only=True)
    return sum(tensor.numel() for tensor in state["qnet"].values())


def _folder_runs(runs_dir: Path) -> list[tuple[ArmKey, dict[str, Any], str]]:
    """(arm key, run, where) for every finished run under a runs folder (the layout `ncbot ablate` writes)."""
    found = []
    for (suite, game, cell), runs in collect_runs(runs_dir).items():  # refuses copied seed folders
        for run in runs:
            folder = runs_dir / suite / game / cell / f"seed{run['seed']}"
            if not {"played", "temporal", "batch_size"} <= run.keys():
                raise ValueError(f"{folder}/config.yaml does not say the game, env.temporal and buffer.batch_size "
                                 "the run was trained with (the arm it belongs to)")
            key = (run["played"], run.get("reward", "paper"), run["memory"], run["temporal"], run["batch_size"])
            found.append((key, {**run, "params": _params(folder / "checkpoint.pt")}, str(folder)))
    return found


def read_arms(inputs: str | Path | list[str | Path]) -> list[Arm]:
    """Every finished run under the runs folders (the layout `ncbot ablate` writes) or in the seeds CSVs an earlier
    report wrote, grouped by what it was trained with. One arm's seeds may come from several inputs, but not the
    same seed twice (one ValueError naming both), unless both hold the same run (same run id): then the run folder's
    copy is kept, since a seeds CSV may lack its curve."""
    groups: dict[ArmKey, dict[int, dict[str, Any]]] = {}
    where: dict[tuple[ArmKey, int], str] = {}
    for source in map(Path, inputs if isinstance(inputs, list) else [inputs]):
        if source.is_file():
            found = [(key, run, f"{source} (seed {run['seed']})") for key, run in read_records(source)]
        else:
            found = _folder_runs(source)
        for key, run, place in found:
            seed = run["seed"]
            kept = groups.setdefault(key, {}).get(seed)
            if kept is not None and not (run.get("run_id") and kept.get("run_id") == run["run_id"]):
                raise ValueError(f"{where[(key, seed)]} and {place} are the same seed of one arm (game, recipe, memory, "
                                 "temporal features, batch size): keep one")
            if kept is None or (run.get("history") and not kept.get("history")):
                groups[key][seed], where[(key, seed)] = run, place
    order = {"none": 0, "gru": 1, "lstm": 2}
    return [Arm(*key, runs=tuple(runs[seed] for seed in sorted(runs)))
            for key, runs in sorted(groups.items(), key=lambda item: (item[0][0], item[0][1] != "paper", item[0][1],
                                                                          order.get(item[0][2], 9), item[0][4],
                                                                          item[0][3]))]


@dataclass(frozen=True)
class Comparison:
    """H1: arm ``better`` has a higher mean robot-first task success than arm ``worse``."""

    question: str
    better: Arm
    worse: Arm
    holm_p: float | None = None

    @cached_property
    def test(self) -> TwoSampleTest:
        return TwoSampleTest(tuple(self.better.values("first.task_success")),
                             tuple(self.worse.values("first.task_success")))

    @property
    def difference_second(self) -> Interval:
        """The same robot second: shown beside the test, not tested (the paper's set-up is robot first)."""
        return welch_difference(self.better.values("second.task_success"), self.worse.values("second.task_success"))

    @property
    def power(self) -> float:
        """Power to detect the paper's difference on this game with these seeds, each arm at its own spread (Welch df)."""
        return self.test.power(PAPER_DIFFERENCE[self.better.game])

    @property
    def verdict(self) -> str:
        if min(self.test.larger + self.test.smaller) == 1.0:  # every test game of every seed won or drawn
            return "at the ceiling (every seed 1.0000): cannot tell"
        reading = self.test.reading(PAPER_DIFFERENCE[self.better.game])
        if reading == SHOWN:
            return "yes"
        if reading == UNTESTED:
            return f"untested (power {self.power:.3f} < {POWER})"
        if reading == NOT_SHOWN:
            return f"not shown (p >= {ALPHA})"
        return reading  # no, or too few runs


def comparisons(arms: list[Arm]) -> list[Comparison]:
    """The questions the grid can answer, each between two arms of the same game and recipe that differ in one thing
    (or, for "memory instead of the features", in the way the move order is given); Holm-adjusted over the family."""
    found = []
    by_key = {arm.key: arm for arm in arms}
    for (game, reward, memory, temporal, batch), arm in by_key.items():
        recipe = recipe_suffix(reward)
        network = "feed-forward" if memory == "none" else memory.upper()
        twin = by_key.get((game, reward, memory, False, batch))
        if temporal and twin is not None and len(arm.runs) > 1 and len(twin.runs) > 1:
            found.append(Comparison(f"temporal features help ({network}, batch {batch}{recipe})", arm, twin))
        plain = by_key.get((game, reward, "none", temporal, batch))
        if memory != "none" and plain is not None and len(arm.runs) > 1 and len(plain.runs) > 1:
            found.append(Comparison(f"{network} helps ({'with' if temporal else 'no'} temporal features, "
                                    f"batch {batch}{recipe})", arm, plain))
        if memory != "none" and not temporal:
            for (other_game, other_reward, other_memory, other_temporal, other_batch), features in by_key.items():
                if (other_game, other_reward, other_memory, other_temporal) == (game, reward, "none", True) \
                        and len(features.runs) > 1 and len(arm.runs) > 1:
                    found.append(Comparison(f"{network} instead of the features (batch {batch} vs "
                                            f"{other_batch}{recipe})", arm, features))
    return _holm(found)


def _holm(found: list[Comparison]) -> list[Comparison]:
    adjusted = holm([c.test.p for c in found])
    return [Comparison(c.question, c.better, c.worse, holm_p) for c, holm_p in zip(found, adjusted)]


def _rate(arm: Arm, metric: str) -> str:
    values = arm.values(metric)
    seat = metric.partition(".")[0]
    games = min(int(run[seat].get("games", DEFAULT_GAMES)) for run in arm.runs)
    return proportion_interval(values, games).text(4) if values else "–"


def _plain(arm: Arm, metric: str, digits: int) -> str:
    """Mean [95 % t-interval] over seeds, for a metric that is near normal between seeds (dialogue length)."""
    values = arm.values(metric)
    return t_interval(values).text(digits) if values else "–"


def _spread(arm: Arm, metric: str, digits: int) -> str:
    """Median [min, max] over seeds, for a skewed positive metric (games to a threshold, time per frame on a
    shared machine); seeds without a value (never reached) are counted, not averaged in."""
    values = sorted(arm.values(metric))
    if not values:
        return f"not reached (0 of {len(arm.runs)} seeds)"
    text = f"{statistics.median(values):.{digits}f} [{values[0]:.{digits}f}, {values[-1]:.{digits}f}]"
    return text if len(values) == len(arm.runs) else f"{text} ({len(values)} of {len(arm.runs)} seeds)"


def _undrawn_seeds(arm: Arm) -> str:
    missing = [str(run["seed"]) for run in arm.runs if not run.get("history")]
    return "every seed" if len(missing) == len(arm.runs) else f"seeds {', '.join(missing)}"


def render(arms: list[Arm], found: list[Comparison], command: str) -> str:
    lines = ["# Temporal information three ways", "",
             f"Made by `{command}`; every seed's numbers are in `{SEEDS_CSV}`, the learning curves in `{FIGURE}` "
             f"(their points in `{CURVES_CSV}`). Both CSVs can be given back to `ncbot reproduce memory` in place of "
             "the run folders.", "",
             "Each cell: mean over seeds [95 % interval of that mean]. Rates over test games (task success, wins) get a "
             "Student t-interval of the per-seed logits, mapped back; dialogue length a Student t-interval. "
             "Robot first is the paper's set-up. **games to 0.95**: training games at the first periodic evaluation "
             "(both seats) with task success >= 0.95 (seeds that never reached it are left out and counted). "
             "**ms per frame**: training wall time over env frames, on a shared machine (compare within one table). "
             "**parameters**: the Q-network's, from the checkpoint.", "",
             "| game | arm | seeds | task success, robot first | task success, robot second | wins, robot first | "
             "dialogue length | games to 0.95 | games to 0.99 | ms per frame | parameters |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for arm in arms:
        params = arm.values("params")
        params_text = f"{int(params[0]):,}" if params else "–"
        lines.append(f"| {GAME_LABELS.get(arm.game, arm.game)} | {arm.label} | {', '.join(str(run['seed']) for run in arm.runs)} | "
                     f"{_rate(arm, 'first.task_success')} | {_rate(arm, 'second.task_success')} | "
                     f"{_rate(arm, 'first.win')} | {_plain(arm, 'first.avg_length', 2)} | "
                     f"{_spread(arm, 'games_to_0.95', 0)} | {_spread(arm, 'games_to_0.99', 0)} | {_spread(arm, 'ms_per_frame', 2)} | {params_text} |")
    undrawn = [arm for arm in arms if not all(run.get("history") for run in arm.runs)]
    if undrawn:
        lines += ["", f"Not drawn in `{FIGURE}` (seeds read from a seeds CSV without their periodic evaluations): "
                  + "; ".join(f"{GAME_LABELS.get(arm.game, arm.game)}, {arm.label} ({_undrawn_seeds(arm)})"
                              for arm in undrawn) + "."]
    lines += ["", "## The questions", "",
              f"One-sided Welch's t-test over seeds of robot-first task success, H1: the first arm is higher; alpha "
              f"{ALPHA}. Difference: first minus second, with its two-sided 95 % Welch interval. Power: the chance "
              "these seeds detect the paper's own claim-(ii) difference on that game ("
              + ", ".join(f"{GAME_LABELS[game]} {difference:.4f}" for game, difference in PAPER_DIFFERENCE.items())
              + f") with these seeds, each arm at its own spread between seeds (Welch df); below power {POWER} a question is untested, not refuted; "
              "above it, \"no\" when the first arm did not come out ahead, \"not shown\" when it did but not "
              "significantly; \"at the ceiling\" when every seed of both arms won or drew every test game. Holm p: "
              "adjusted "
              "over every question below, for a family-wise reading. P(run ahead): the probability that a seed of "
              "the first arm beats a seed of the second (every pair, ties half; Agarwal et al. 2021) with the 95 % "
              f"percentile interval of a bootstrap over seeds ({BOOTSTRAP_REPS} resamples, fixed generator seed), "
              "free of a normality assumption but narrower than nominal at 5 seeds a side: it describes, the test "
              "decides.", "",
              "| question | game | first arm | second arm | difference | p | Holm p | power | higher? | "
              "P(run ahead) | difference, robot second (not tested) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in found:
        p = "–" if c.test.p is None else f"{c.test.p:.3f}"
        holm = "–" if c.holm_p is None else f"{c.holm_p:.3f}"
        lines.append(f"| {c.question} | {GAME_LABELS.get(c.better.game, c.better.game)} | {c.better.label} | {c.worse.label} | "
                     f"{c.test.difference.text(4)} | {p} | {holm} | {c.power:.2f} | {c.verdict} | "
                     f"{interval_text(c.test.improvement)} | {c.difference_second.text(4)} |")
    return "\n".join(lines) + "\n"


def _keyed_runs(arms: list[Arm]) -> list[tuple[ArmKey, dict[str, Any]]]:
    return [(arm.key, run) for arm in arms for run in arm.runs]


def plot(arms: list[Arm], path: Path) -> Path:
    """Mean periodic task success (both seats) against training games, one panel per game and recipe (their
    budgets differ by tens of thousands of games) and one line per arm, seeds' range shaded."""
    from ncbot.pipelines.plots import pyplot, save_figure

    plt = pyplot()
    drawn = [arm for arm in arms if any(run.get("history") for run in arm.runs)]
    panels = list(dict.fromkeys((arm.game, arm.reward) for arm in drawn)) or [(None, None)]
    fig, axes = plt.subplots(1, len(panels), figsize=(8 * len(panels), 4.5), squeeze=False)
    for ax, (game, reward) in zip(axes[0], panels):
        if game is None:
            ax.text(0.5, 0.5, "no periodic evaluations in the inputs", ha="center", va="center")
            continue
        for arm in (arm for arm in drawn if (arm.game, arm.reward) == (game, reward)):
            runs = [run for run in arm.runs if run.get("history")]
            length = min(len(run["history"]) for run in runs)
            played = [sum(run["history"][i]["episodes"] for run in runs) / len(runs) for i in range(length)]
            success = [[run["history"][i]["task_success"] for run in runs] for i in range(length)]
            seeds = "" if len(runs) == len(arm.runs) else f" ({len(runs)} of {len(arm.runs)} seeds)"
            ax.plot(played, [sum(s) / len(s) for s in success], marker=".", label=arm.label + seeds)
            ax.fill_between(played, [min(s) for s in success], [max(s) for s in success], alpha=0.12)
        for threshold in THRESHOLDS:
            ax.axhline(threshold, color="grey", linestyle="--", linewidth=0.8)
        ax.set_title(f"{GAME_LABELS.get(game, game)}, {RECIPES.get(reward, reward)}")
        ax.set_xlabel("simulated training games (mean over seeds)")
        ax.set_ylabel("task success, periodic evaluation (both seats)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, path)


def write_memory_report(inputs: str | Path | list[str | Path], out: str | Path, command: str) -> dict[str, Any]:
    """Write OUT/table.md, OUT/table_seeds.csv, OUT/table_curves.csv and OUT/curves.png from the finished runs under
    the runs folders and in the seeds CSVs given (an earlier report's, read before anything is written)."""
    arms = read_arms(inputs)
    found = comparisons(arms)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(render(arms, found, command), out / MARKDOWN)
    keyed = _keyed_runs(arms)
    atomic_write_text(seeds_csv(keyed), out / SEEDS_CSV)
    atomic_write_text(curves_csv(keyed), out / CURVES_CSV)
    figure = plot(arms, out / FIGURE)
    return {"files": [str(out / MARKDOWN), str(out / SEEDS_CSV), str(out / CURVES_CSV), str(figure)], "arms": len(arms),
            "runs": sum(len(arm.runs) for arm in arms)}
