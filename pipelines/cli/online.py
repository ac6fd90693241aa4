"""`ncbot learn LOGS...`: the robot learns from robot games recorded earlier, as `ncbot robot play --learn` does while
it plays (logic in `ncbot.pipelines.online`; this file only parses options and prints).

Bad input (a missing or foreign log, a log without robot games, bad weights or checkpoint, a share outside [0, 1])
raises ValueError/FileNotFoundError, which `ncbot.pipelines.cli.app.main` prints as one line with exit code 2.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Optional

import typer

from ncbot.pipelines.cli.conventions import json_option, no_progress_option, out_folder, print_json, progress_alias, wrote
from ncbot.pipelines.outputs import check_writable_dir


def learn_command(
    logs: list[Path] = typer.Argument(..., help="Run folders (or .mcap files) of ncbot robot play / robot serve, in the order the games were played."),
    out: Path = out_folder(..., "the learning (state.json, reader/, play/, learning.png); one that holds learning resumes after its games."),
    weights: Optional[Path] = typer.Option(None, help="Cell classifier to start from (default: the shipped one)."),
    agent: Optional[Path] = typer.Option(None, help="The agent whose play learns too: a checkpoint .pt of ncbot train or its run folder; without it only the reader learns."),
    every: int = typer.Option(1, min=1, help="Update the reader after every N games."),
    seed: int = typer.Option(0, min=0, help="Seed of the updates' batches and of the simulation."),
    wrong_claims: float = typer.Option(0.0, help="Share of the person's moves settled in another cell on purpose (a person who lies; for measuring)."),
    updates: int = typer.Option(100, min=0, help="Gradient steps of the play's update after each game (its compute bound)."),
    label_check: bool = typer.Option(True, help="Leave out settled cells whose ink contradicts their label (--no-label-check: learn from every label, to measure what the check guards against)."),
    opponent: str = typer.Option("random", help="Also test the play before / after against this opponent (envs.opponents name)."),
    test_games: int = typer.Option(600, min=2, help="Test games per opponent for the play's before / after."),
    as_json: bool = json_option(),
    no_progress: bool = no_progress_option(),
    _progress: bool = progress_alias(),
) -> None:
    """Learn the reader (and, with --agent, the play) from logged robot games, game by game."""
    from ncbot.pipelines.online.learning import LearnSettings
    from ncbot.pipelines.online.offline import learn_from_logs
    from ncbot.pipelines.online.summary import draw_learning, play_before_after, reader_before_after
    from ncbot.pipelines.progress import progress_bar

    if not 0.0 <= wrong_claims <= 1.0:
        raise ValueError(f"--wrong-claims must be a share in [0, 1]; got {wrong_claims}")
    for log in logs:
        if not log.exists():
            raise FileNotFoundError(f"log {log} does not exist; expected the --out folder of ncbot robot play or serve")
    check_writable_dir(out, "--out")
    import torch

    torch.set_num_threads(1)
    settings = LearnSettings.default(agent, every, seed, updates)
    if not label_check:
        settings = replace(settings, reader=replace(settings.reader, filter_labels=False))
    learning = learn_from_logs(logs, out, settings, weights, agent, wrong_claims,
                               None if no_progress else progress_bar)
    styles = sorted({entry.get("handwriting") or "pen" for entry in learning.per_game} or {"pen"})
    summary = {"folder": str(out), "games_learned": learning.games, "reader": reader_before_after(learning, styles),
               "play": play_before_after(learning, [opponent], test_games), "play_weights": learning.play_weights}
    summary["figure"] = str(draw_learning(learning.per_game, summary["reader"], out / "learning.png",
                                          f"learning from {len(logs)} log(s): handwriting {', '.join(styles)}"))
    report = {"per_game": learning.per_game, "learned_weights": learning.reader_weights, "learning": summary}
    if as_json:
        print_json({**report, "written": [str(out)]})
        wrote(f"the learned state to {out}")
        return
    for entry in learning.per_game:
        reader = entry.get("reader") or {}
        typer.echo(f"game {entry['game']}: {entry.get('outcome')}, misread {entry.get('misrecognised_moves')}, "
                   f"unseen {entry.get('unseen_moves')}; reader update "
                   f"{'kept' if reader.get('kept') else 'rolled back' if reader.get('updated') else 'none'}")
    for style, values in (summary["reader"] or {}).get("accuracy", {}).items():
        typer.echo(f"held-out {style} cells read right: {100 * values['before']:.2f}% -> {100 * values['after']:.2f}%")
    wrote(f"the learned state to {out} (reader {learning.reader_weights}, figure {summary['figure']})")


def register(app: typer.Typer) -> None:
    """Add this area's commands to the root app."""
    app.command("learn")(learn_command)
