"""`ncbot reproduce games-data RUN...`: the data each game needed, one row per trained run folder.

Why: the paper claims little data ("a few hundred images, a dozen dialogues") and that the more complex game
needed no more data than the simpler one. For any game (3x3, Ultimate or a declared one) this page puts side by
side what its run learnt from: the example dialogues the env fitted its act filter and simulated user to (counted
from the dialogue model the env builds for that game and set), the labelled cell images (one classifier for every
game: the shipped weights' own count, 0 new per game), and the simulated training games until the periodic task
success first reached 0.95 and 0.99. Every number is read from the run folders, the env's data and the weights.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ncbot.fileio import atomic_write_text

THRESHOLDS = (0.95, 0.99)
MARKDOWN = "games_data.md"
FIGURE = "games_data.png"
LABELS = {"standard": "3x3", "ultimate": "Ultimate"}  # how the tables name the built-in games (by game id)


@dataclass(frozen=True)
class GameRun:
    """What one finished run learnt from and how fast it got there."""

    run_dir: Path
    name: str
    rows: int
    cols: int
    k: int
    gravity: bool
    dialogue_set: str
    dialogues: int
    dialogue_turns: int  # the act filter's training examples: one per robot turn of those dialogues
    history: tuple[tuple[int, int, float], ...]  # (training games, frames, task success) per periodic evaluation
    periodic_games: int
    first: dict[str, Any]  # final evaluation, robot first: games, task_success, task_success_ci95
    second: dict[str, Any]
    seed: int
    created: float  # run.json's creation time (epoch seconds)

    def first_reaching(self, threshold: float) -> tuple[int, int] | None:
        """(training games, frames) at the first periodic evaluation with task success >= ``threshold``."""
        return next(((games, frames) for games, frames, success in self.history if success >= threshold), None)


def _read_json(path: Path, what: str) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: {what} could not be read ({type(error).__name__})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: {what} must be a JSON object")
    return data


def _game_of(run_dir: Path, config: dict[str, Any]) -> str:
    """The run's env.game; a declaration file that moved since the run is looked for next to the run folder."""
    game = str((config.get("env") or {}).get("game", "standard"))
    if game.endswith((".yaml", ".yml")) and not Path(game).is_file():
        beside = run_dir.resolve().parent / Path(game).name
        if not beside.is_file():
            raise ValueError(f"{run_dir}/config.yaml names the game file {game}, which no longer exists (nor "
                             f"{beside}): restore the declaration the run was trained on")
        return str(beside)
    return game


def count_dialogues(game: str, dialogue_set: str, subset: tuple[int, int] | None) -> tuple[int, int]:
    """(example dialogues, their robot turns) the env fits its act filter and simulated user to for ``game``: the
    shipped files for 3x3 / Ultimate, the generated ones for a declared game (``DialogueEnv``'s dialogue model)."""
    from ncbot.envs.dialogue import build_dialogue_model, examples_of

    return len(examples_of(game, dialogue_set, subset)), build_dialogue_model(game, dialogue_set, subset).n_examples


def _board(game: str) -> tuple[str, int, int, int, bool]:
    """(label, rows, cols, marks in a line that win (0: not a line game), gravity) of a run's game."""
    from ncbot.envs.games import make_game

    rules = make_game(game)
    declaration = getattr(rules, "declaration", None)
    k = declaration.k if declaration is not None else 3 if game in LABELS else 0
    return LABELS.get(game, rules.name), rules.rows, rules.cols, k, rules.gravity


def read_run(run_dir: str | Path) -> GameRun:
    """One finished run folder (config.yaml, run.json, eval.json with its periodic ``history``); one-line
    ValueError naming the folder when it is not one."""
    from ncbot.pipelines.config.files import load_config

    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ValueError(f"run folder {run_dir} does not exist")
    for name in ("config.yaml", "run.json", "eval.json"):
        if not (run_dir / name).is_file():
            unfinished = " (the run is not finished: eval.json is written at its end)" if name == "eval.json" else ""
            raise ValueError(f"run folder {run_dir} holds no {name}{unfinished}")
    raw = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    config = load_config(run_dir / "config.yaml", [f"env.game={_game_of(run_dir, raw)}"])
    result = _read_json(run_dir / "eval.json", "eval.json")
    history = result.get("history")
    if not isinstance(history, list) or not history:
        raise ValueError(f"{run_dir}/eval.json holds no periodic evaluations ('history')")
    try:
        points = tuple((int(h["episodes"]), int(h["frames"]), float(h["task_success"])) for h in history)
        first, second = result["first"], result["second"]
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{run_dir}/eval.json lacks {error} (expected episodes, frames, task_success per "
                         "periodic evaluation and the final 'first' / 'second' seats)") from None
    name, rows, cols, k, gravity = _board(config.env.game)
    dialogues, turns = count_dialogues(config.env.game, config.env.dialogues, config.env.subset)
    return GameRun(run_dir=run_dir, name=name, rows=rows, cols=cols, k=k, gravity=gravity,
                   dialogue_set=config.env.dialogues,
                   dialogues=dialogues, dialogue_turns=turns,
                   history=points, periodic_games=int(history[0].get("games", config.eval.periodic_games)),
                   first=first, second=second, seed=config.train.seed,
                   created=float(_read_json(run_dir / "run.json", "run.json").get("created", 0.0)))


def shared_cells() -> int:
    """Labelled cell images behind the shipped classifier (its weights' metadata): every game reads its sheet
    with it."""
    from ncbot.vision.classifier.inference import weights_meta

    return int(weights_meta()["n_training_cells"])


def _reached(run: GameRun, threshold: float) -> str:
    found = run.first_reaching(threshold)
    return "not reached" if found is None else f"{found[0]:,} ({found[1]:,} frames)"


def _seat(seat: dict[str, Any]) -> str:
    low, high = seat["task_success_ci95"]
    return f"{seat['task_success']:.4f} [{low:.4f}, {high:.4f}] ({seat['games']})"


def _game_text(run: GameRun) -> str:
    board = "Ultimate (3x3 boards of 3x3)" if run.name == "Ultimate" else f"{run.rows}x{run.cols}"
    return f"`{run.name}` | {board}, k {run.k}, {'gravity' if run.gravity else 'no gravity'}"


def render(runs: list[GameRun], cells: int, command: str) -> str:
    lines = ["# The data each game needed", "",
             f"Made by `{command}` from the run folders below; every number is read by "
             "`ncbot.pipelines.reproduce.games_data` from the runs, the env's example dialogues and the classifier's "
             f"weights. Figure: `{FIGURE}` (periodic task success against training games).", "",
             "Columns: **example dialogues**: the dialogues the act filter and the simulated user are learnt from (the "
             "env's dialogue model for that game and set: shipped files for 3x3 and Ultimate, generated from the "
             "declaration for a declared game). **labelled cell images**: the cells the shipped cell classifier was "
             "trained on; one classifier reads every game's sheet, so no game adds any. **games to 0.95 / 0.99**: "
             "simulated training games (and env frames) at the first periodic evaluation whose task success (robot "
             "alternating seats, the games given in **periodic eval**) reached the threshold; \"not reached\" when "
             "none did. **final**: task success of the final evaluation per seat, 95 % interval and games. "
             "**run**: the config it replays (`ncbot train RUN/config.yaml --out NEW`) and its start (run.json, UTC).",
             "",
             "| game | board | example dialogues | labelled cell images | games to 0.95 | games to 0.99 | "
             "periodic eval | final, robot first | final, robot second | run |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for run in runs:
        started = time.strftime("%Y-%m-%d %H:%M", time.gmtime(run.created))
        lines.append(f"| {_game_text(run)} | {run.dialogues} ({run.dialogue_set}; {run.dialogue_turns} robot turns) | {cells:,} shared, 0 new | "
                     f"{_reached(run, 0.95)} | {_reached(run, 0.99)} | {run.periodic_games} games | "
                     f"{_seat(run.first)} | {_seat(run.second)} | `ncbot train {run.run_dir}/config.yaml` "
                     f"(seed {run.seed}), {started} |")
    return "\n".join(lines) + "\n"


def plot(runs: list[GameRun], path: Path) -> Path:
    from ncbot.pipelines.plots import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for run in runs:
        ax.plot([g for g, _, _ in run.history], [s for _, _, s in run.history], marker=".", label=run.name)
    for threshold in THRESHOLDS:
        ax.axhline(threshold, color="grey", linestyle="--", linewidth=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("simulated training games")
    ax.set_ylabel("task success (periodic evaluation)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def write_games_data(run_dirs: list[str | Path], out: str | Path, command: str) -> dict[str, Any]:
    """Write OUT/games_data.md and OUT/games_data.png for the run folders (all read before anything is written)."""
    if not run_dirs:
        raise ValueError("games-data needs at least one run folder (a finished `ncbot train` run)")
    runs = [read_run(path) for path in run_dirs]
    cells = shared_cells()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(render(runs, cells, command), out / MARKDOWN)
    figure = plot(runs, out / FIGURE)
    return {"files": [str(out / MARKDOWN), str(figure)], "runs": len(runs)}
