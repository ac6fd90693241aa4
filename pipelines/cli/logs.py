"""`ncbot logs ...`: look into the MCAP episode logs of a run (logic in `logs/`; this file only parses options).

Bad input (missing path, empty or non-MCAP file, an MCAP without ncbot channels, an unknown episode) raises
ValueError/FileNotFoundError, which `ncbot.pipelines.cli.app.main` prints as one line with exit code 2.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ncbot.pipelines.cli.conventions import json_option, no_progress_option, out_file, print_json, wrote
from ncbot.pipelines.extras import require
from ncbot.pipelines.outputs import check_writable_file
from ncbot.pipelines.progress import progress_bar  # light: tqdm loads only when a bar is drawn

logs_app = typer.Typer(help="Inspect, replay, plot and export the MCAP episode logs of a run.",
                       no_args_is_help=True)

PATH_HELP = "an episodes-NNNN.mcap file or a run directory holding them"
#: the phases a log records (ncbot.logs.schemas.PHASES, which loads the log reader: too heavy for `--help`;
#: tests/cli/test_cli_convention.py checks the two agree)
PHASES_TEXT = "train, eval, robot or play"


@logs_app.command("inspect")
def inspect_log(path: Path = typer.Argument(..., help=PATH_HELP), as_json: bool = json_option(),
                no_progress: bool = no_progress_option()) -> None:
    """Channels and schemas, message counts, time span, episodes by phase, and whether a file was cut off."""
    from ncbot.logs.reader import LogReader
    from ncbot.logs.summary import format_study, format_summary, study_sessions, summarize, summarize_study

    if study_sessions(path):  # a browser study: one session-<id>/ folder per tab (`ncbot robot serve`)
        study = summarize_study(path)
        print_json(study) if as_json else typer.echo(format_study(study))
        return
    summary = summarize(path, LogReader(path, progress=progress_bar))
    print_json(summary) if as_json else typer.echo(format_summary(summary))


@logs_app.command("episodes")
def list_episodes(path: Path = typer.Argument(..., help=PATH_HELP),
                  phase: Optional[str] = typer.Option(None, help=f"only this phase: {PHASES_TEXT}"),
                  outcome: Optional[str] = typer.Option(None, help="win, loss, draw or none (robot's view)"),
                  agent: Optional[str] = typer.Option(None, help="only this agent"),
                  limit: int = typer.Option(50, min=1, help="show at most this many (the first matches)"),
                  as_json: bool = json_option(), no_progress: bool = no_progress_option()) -> None:
    """A table of the episodes that match the filters."""
    from ncbot.logs.reader import LogReader
    from ncbot.logs.schemas import EPISODE_TOPIC, OUTCOMES, PHASES

    if phase is not None and phase not in PHASES:
        raise ValueError(f"--phase must be one of {', '.join(PHASES)}, got {phase!r}")
    if outcome is not None and outcome not in OUTCOMES:
        raise ValueError(f"--outcome must be one of {', '.join(OUTCOMES)}, got {outcome!r}")
    reader = LogReader(path, progress=progress_bar)
    episodes = [m.data for m in reader.messages([EPISODE_TOPIC])]
    reader.require_ncbot()
    matches = [e for e in episodes if (phase is None or e.get("phase") == phase)
               and (outcome is None or e.get("outcome") == outcome)
               and (agent is None or e.get("agent") == agent)]
    shown = min(limit, len(matches))
    if as_json:
        print_json({"episodes": matches[:limit], "shown": shown, "matching": len(matches), "in_log": len(episodes)})
        return
    header = f"{'id':>7} {'phase':<6} {'game':<8} {'agent':<16} {'seed':>4} {'seat':<6} {'outcome':<7} " \
             f"{'return':>8} {'length':>6} {'env_steps':>9} {'epsilon':>7}"
    typer.echo(header)
    for e in matches[:limit]:
        steps = "" if e.get("env_steps") is None else e["env_steps"]
        epsilon = "" if e.get("epsilon") is None else f"{e['epsilon']:.3f}"
        typer.echo(f"{e['episode']:>7} {e['phase']:<6} {e['game']:<8} {str(e['agent'])[:16]:<16} {e['seed']:>4} "
                   f"{e['seat']:<6} {e['outcome']:<7} {e['return']:>8.3f} {e['length']:>6} {steps:>9} {epsilon:>7}"
                   + (" truncated" if e.get("truncated") else ""))
    typer.echo(f"{shown} of {len(matches)} matching episodes shown ({len(episodes)} in the log)")


@logs_app.command("show")
def show_episode(path: Path = typer.Argument(..., help=PATH_HELP),
                 episode_id: int = typer.Argument(..., help="episode id (see `ncbot logs episodes`)"),
                 max_q: int = typer.Option(8, min=1, help="Q-values shown per decision (highest first)"),
                 as_json: bool = json_option(), no_progress: bool = no_progress_option()) -> None:
    """Replay one dialogue: utterances, the board after each move, Q-values and masks of each robot decision."""
    from dataclasses import asdict

    from ncbot.logs.replay import format_episode, load_episode

    record, names = load_episode(path, episode_id, progress=progress_bar)
    if as_json:  # the record as logged, with the act names as the text replay shows them
        print_json({**asdict(record), "act_names": [names.action_name(act) for act in range(len(names.action_names))]})
        return
    typer.echo(format_episode(record, names, max_q=max_q))


@logs_app.command("acts")
def act_mix(path: Path = typer.Argument(..., help=PATH_HELP),
            phase: Optional[str] = typer.Option("eval", help=f"only this phase: {PHASES_TEXT}; 'all' for every phase"),
            seat: Optional[str] = typer.Option(None, help="first or second: only games with the robot in this seat"),
            as_json: bool = json_option(), no_progress: bool = no_progress_option()) -> None:
    """Where the dialogue length goes: mean robot acts per game by act (game moves, the refused ones among them,
    each spoken act), for all games and per outcome."""
    from ncbot.logs.acts import act_table, format_act_table

    table = act_table(path, None if phase == "all" else phase, seat, progress=progress_bar)
    print_json(table) if as_json else typer.echo(format_act_table(table))


@logs_app.command("curve")
def learning_curve(path: Path = typer.Argument(..., help=PATH_HELP),
                   output: Path = out_file(..., "the learning curve (.png)."),
                   window: int = typer.Option(200, min=1, help="moving-average window over training episodes"),
                   as_json: bool = json_option(), no_progress: bool = no_progress_option()) -> None:
    """Draw the learning curve (task success, reward per step, dialogue length) from the log alone."""
    from ncbot.logs.curve import plot_learning_curve

    check_writable_file(output, "--out", (".png",))

    series = plot_learning_curve(path, output, window, progress=progress_bar)
    if as_json:
        print_json({"series": series, "written": [str(output)]})
        wrote(str(output))
        return
    for label, entry in series.items():
        last = []
        if "train" in entry and len(entry["train"]["x"]):
            last.append(f"train task success {entry['train']['task_success'][-1]:.3f}")
        if "eval" in entry:
            last.append(f"last eval task success {entry['eval']['task_success'][-1]:.3f} "
                        f"({entry['eval']['games'][-1]} games at {int(entry['eval']['x'][-1])} env steps)")
        typer.echo(f"{label}: " + ", ".join(last))
    wrote(str(output))


@logs_app.command("to-rerun")
def to_rerun(path: Path = typer.Argument(..., help=PATH_HELP),
             output: Path = out_file(..., "the rerun recording (.rrd)."),
             episodes: Optional[str] = typer.Option(None, help="ids and ranges, e.g. '3,7,10-12' (default: the last "
                                                               "--max-episodes)"),
             max_episodes: int = typer.Option(200, min=1, help="cap on exported episodes"),
             as_json: bool = json_option(), no_progress: bool = no_progress_option()) -> None:
    """Export episodes to a rerun recording: boards, dialogue text, Q-values and rewards, camera frames."""
    require("rerun", "rerun", what="ncbot logs to-rerun")
    from ncbot.logs.rerun_export import export_to_rerun, parse_episode_spec

    check_writable_file(output, "--out", (".rrd",))

    counts = export_to_rerun(path, output, parse_episode_spec(episodes), max_episodes, progress=progress_bar)
    if as_json:
        print_json({**counts, "written": [str(output)]})
    else:
        typer.echo(f"{counts['episodes']} episodes, {counts['steps']} steps, {counts['camera_frames']} camera frames, "
                   f"{counts['joint_states']} joint states, {counts['transforms']} transforms")
    wrote(f"{output} ({counts['bytes']} bytes; open it with `rerun {output}`)")


def register(app: typer.Typer) -> None:
    """Add `ncbot logs ...` to the root app."""
    app.add_typer(logs_app, name="logs")
