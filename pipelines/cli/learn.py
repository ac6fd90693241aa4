"""`ncbot train`, `ncbot eval`, `ncbot table`: the learning area's commands (`ncbot ablate`: pipelines/cli/grid.py).

Heavy imports (torch, torchrl) happen inside the commands so `ncbot --help` stays fast. Library errors
(ValueError / FileNotFoundError) become one line and exit code 2 in `ncbot.pipelines.cli.app.main`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ncbot.pipelines.agents import check_value_option  # light: pathlib only
from ncbot.pipelines.config import MAX_GAMES, MAX_SEED  # light: pydantic and yaml, no torch
from ncbot.pipelines.cli.conventions import (RETIRED_ALIAS_HELP, json_option, no_log_option, no_progress_option,
                                             listing, out_file, out_folder, print_json, progress_alias, wrote)
from ncbot.pipelines.outputs import check_writable_dir, check_writable_file  # light: os and pathlib only

CHECKPOINT_HELP = "A checkpoint .pt written by ncbot train, or its run folder."


def train_command(
    config: Optional[str] = typer.Argument(None, help="YAML run config: a file or a shipped name (default, ultimate, paper/standard_original; ncbot configs lists them)."),
    overrides: Optional[list[str]] = typer.Argument(None, help="section.key=value overrides, e.g. optim.lr=0.0005."),
    out: Optional[str] = out_folder(None, "the run: checkpoints, eval.json, learning-curve PNG, MCAP log "
                                    "(default runs/<config name>)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed (overrides train.seed)."),
    episodes: Optional[int] = typer.Option(None, "--episodes", help="Stop after N training games instead of frames."),
    resume: Optional[str] = typer.Option(None, "--resume", help="Continue the run in this folder from its last checkpoint."),
    no_log: bool = no_log_option(),
    no_mcap: bool = typer.Option(False, "--no-mcap", hidden=True, help=RETIRED_ALIAS_HELP.format(new="--no-log")),
    no_progress: bool = no_progress_option(),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the run already in --out (its checkpoints, "
                                   "log, eval.json); without it such a folder is refused."),
    as_json: bool = json_option(),
) -> None:
    """Train an agent (competitive DQN or a baseline) and write checkpoint, eval.json, curve PNG and MCAP log."""
    from ncbot.pipelines.errors import continue_with
    from ncbot.pipelines.run_folder import finished_report
    from ncbot.pipelines.train.run import resolve_run, train

    config_path, extra = config, list(overrides or [])
    if resume and config_path and "=" in config_path:  # `ncbot train --resume DIR key=value`
        config_path, extra = None, [config_path, *extra]
    run_config, run_dir, resuming = resolve_run(config_path, extra, out=out, seed=seed, episodes=episodes,
                                                resume=resume, mcap=not (no_log or no_mcap))
    if no_progress:
        run_config.logger.progress = False
    if overwrite and resuming:
        raise ValueError("give --resume or --overwrite, not both (--overwrite replaces the run --resume continues)")
    report = finished_report(run_config, run_dir) if resuming else None
    if report is not None:  # nothing left to train: show its results, rewrite nothing
        typer.echo(f"ncbot: note: the run in {run_dir} is finished ({report['frames']} frames, {report['episodes']} "
                   f"games); nothing to train, its eval.json is shown (to train on, raise its budget, e.g. ncbot train "
                   f"--resume {run_dir} collector.total_frames=N)", err=True)
        _print_training(report, as_json, run_dir, written=[])
        return
    continue_with(f"ncbot train --resume {run_dir}")
    report = train(run_config, run_dir, resume=resuming, overwrite=overwrite)
    continue_with(None)
    written = [run_dir / name for name in ("checkpoint.pt", "eval.json", "learning_curve.png", "config.yaml")]
    written = [path for path in written if path.is_file()]  # no learning (uniform): no checkpoint or curve
    _print_training(report, as_json, run_dir, written)
    log = ", the MCAP log" if run_config.logger.mcap else ""
    wrote(f"{run_dir} ({', '.join(path.name for path in written)}{log})")


def _print_training(report: dict, as_json: bool, run_dir: Path, written: list[Path]) -> None:
    """The run's results: both seats' metrics, then its frames, games and times (or one JSON object)."""
    if as_json:
        print_json({"out": str(run_dir), **{key: value for key, value in report.items() if key != "history"},
                    "written": [str(path) for path in written]})
        return
    typer.echo(_results_header())
    for seat in ("first", "second"):
        typer.echo(_results_row(report[seat], seat))
    if report["frames"] == 0:
        typer.echo(f"no learning: a uniform choice inside the {report['lookahead']} masks "
                   f"({report['eval_wall_time_s']:.1f} s of test games)")
        return
    reached, cpu = report["time_to_0995_s"], report.get("train_cpu_time_s")
    typer.echo(f"frames {report['frames']}, updates {report['updates']}, games {report['episodes']}, "
               f"train wall time {report['train_wall_time_s']:.1f} s"
               f"{f' (CPU {cpu:.1f} s)' if cpu is not None else ''}, " + (
                   f"periodic task success first reached 0.995 at {reached:.1f} s" if reached is not None
                   else "periodic task success never reached 0.995"))


def configs_command(
    name: Optional[str] = typer.Argument(None, help="A shipped config's name: print its YAML (e.g. ncbot configs default > mine.yaml)."),
    as_json: bool = json_option(),
) -> None:
    """List the configs shipped with ncbot (name, kind, what it is), or print one to start your own from."""
    from ncbot.pipelines.config import shipped_configs

    configs = shipped_configs()
    if name is not None:
        path = configs.get(name.removesuffix(".yaml"))
        if path is None:
            raise ValueError(f"no shipped config named {name!r}; shipped: {', '.join(configs)}")
        text = path.read_text(encoding="utf-8")
        if as_json:
            print_json({"name": name.removesuffix(".yaml"), "path": str(path), "kind": _config_kind(path), "yaml": text})
        else:
            typer.echo(text, nl=False)
        return
    if as_json:
        print_json({"configs": [{"name": config_name, "kind": _config_kind(path), "summary": _config_summary(path),
                                 "path": str(path)} for config_name, path in configs.items()]})
        return
    typer.echo(f"{'name':<36} {'kind':<5} what it is (ncbot train NAME, ncbot ablate NAME; ncbot configs NAME prints it)")
    for config_name, path in configs.items():
        typer.echo(f"{config_name:<36} {_config_kind(path):<5} {_config_summary(path)}")


def _config_kind(path) -> str:
    """`grid` for an ablation grid (ncbot ablate), `run` for a run config (ncbot train)."""
    import yaml

    data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    return "grid" if isinstance(data, dict) and "suites" in data and "grid" in data else "run"


def _config_summary(path, width: int = 90) -> str:
    """The first sentence of the file's opening comment, cut to `width` characters."""
    lines = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    first = " ".join(lines).split(". ", 1)[0].rstrip(".")
    return first if len(first) <= width else first[: width - 3].rstrip() + "..."


def _results_header() -> str:
    return "| seat | games | win | draw | loss | truncated | task success (95% CI) | avg reward | avg return | avg length |\n" \
           "|---|---|---|---|---|---|---|---|---|---|"


def _results_row(result: dict, seat: str) -> str:
    low, high = result["task_success_ci95"]
    return (f"| {seat} | {result['games']} | {result['win']:.4f} | {result['draw']:.4f} | {result['loss']:.4f} | "
            f"{result['truncated']:.4f} | {result['task_success']:.4f} [{low:.4f}, {high:.4f}] | {result['avg_reward']:.4f} | "
            f"{result['avg_return']:.3f} | {result['avg_length']:.2f} |")


def eval_command(
    checkpoint: str = typer.Argument(..., help=CHECKPOINT_HELP),
    games: int = typer.Option(3000, "--games", min=1, max=MAX_GAMES, help="Number of greedy test games."),
    opponent: str = typer.Option("random", "--opponent", help="Simulated user's move policy (envs.opponents name)."),
    first: str = typer.Option("alternate", "--first", help="Who opens: robot | human | alternate (half the games each)."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the test games."),
    as_json: bool = json_option(),
    out: Optional[str] = out_folder(None, "the MCAP log of the test games (none by default)."),
    search: Optional[int] = typer.Option(None, "--search", max=100_000, help="Game moves by MCTS guided by the Q-network, N simulations."),
    exhaustive: bool = typer.Option(False, "--exhaustive", help="3x3: every game branch of the random user, exact probabilities (ignores --games/--opponent)."),
    dialogue_seeds: int = typer.Option(8, "--dialogue-seeds", help="With --exhaustive: dialogue draws (words, ASR confidences) to enumerate under."),
    value: Optional[str] = typer.Option(None, "--value", help="With --search on Ultimate: a value network (ncbot train-value) scores the search's leaves."),
    no_progress: bool = no_progress_option(),
    _progress: bool = progress_alias(),
    game: Optional[str] = typer.Option(None, "--game", help="The run's game class (my_pkg.games:Misere, "
                                       "path/to/file.py:Misere) for a run of your own game: ncbot imports a game's "
                                       "code only when you name it."),
) -> None:
    """Play greedy test games with a trained agent and report the paper's metrics."""
    from ncbot.pipelines.game_option import name_game
    from ncbot.pipelines.run_env import check_first

    check_first(first, name="--first")
    check_value_option(value, search)
    if out is not None:
        check_writable_dir(out, "--out")
    import torch

    from ncbot.pipelines.evaluate.games import evaluate_checkpoint
    from ncbot.pipelines.agents import register_agent_opponent

    torch.set_num_threads(1)
    name_game(game, checkpoint)
    if exhaustive:
        _exhaustive_eval(checkpoint, first, seed, dialogue_seeds, as_json)
        return
    register_agent_opponent()  # --opponent agent:CKPT / qmcts:N:CKPT
    check_opponent(opponent)
    result = evaluate_checkpoint(checkpoint, games=games, opponent=opponent, first=first, seed=seed, mcap_dir=out,
                                 search=search, value=value, progress=not no_progress)
    metrics = seat_metrics(result.to_dict(), first)
    if as_json:
        print_json({**metrics, **({"written": [out]} if out is not None else {})})
    else:
        typer.echo(_results_header())
        for seat in ("alternate", "first", "second"):
            if seat == "alternate" and first == "alternate":
                typer.echo(_results_row(metrics, seat))
            elif seat in metrics:
                typer.echo(_results_row(metrics[seat], seat))
    if out is not None:
        wrote(f"the MCAP log of the {games} test games to {out}")


def _exhaustive_eval(checkpoint: str, first: str, seed: int, dialogue_seeds: int, as_json: bool) -> None:
    """`ncbot eval --exhaustive`: exact win/draw/loss per seat and the lost games, if any."""
    from ncbot.pipelines.evaluate.exact import exact_checkpoint

    results = exact_checkpoint(checkpoint, first=first, seed=seed, dialogue_seeds=dialogue_seeds)
    if as_json:
        print_json({result.seat: result.to_dict() for result in results})
        return
    typer.echo(f"exact over every game branch of the random user, under {dialogue_seeds} dialogue draw(s) "
               f"(env seeds {seed}..{seed + dialogue_seeds - 1})")
    typer.echo("| seat | branches | win | draw | loss | task success | worst loss over draws | lost games |\n"
               "|---|---|---|---|---|---|---|---|")
    for result in results:
        typer.echo(f"| {result.seat} | {result.branches} | {result.win:.4f} | {result.draw:.4f} | {result.loss:.4f} | "
                   f"{result.task_success:.4f} | {result.worst_loss:.4f} | {len(result.losing_lines)} |")
    for result in results:
        for line in result.losing_lines[:10]:
            typer.echo(f"lost ({result.seat}): {line}")
        if len(result.losing_lines) > 10:
            typer.echo(f"... and {len(result.losing_lines) - 10} more lost games ({result.seat}); --json lists all")


def seat_metrics(result: dict, first: str) -> dict:
    """eval's metrics keyed as eval.json keys them: the games of each seat under "first" / "second" (the robot's
    seat), beside the totals, and "opens" saying who opened (robot | human | alternate)."""
    from ncbot.pipelines.run_env import robot_seat

    seats = result.pop("seats", None)
    if seats is not None:
        result.update({seat.removeprefix("robot_"): metrics for seat, metrics in seats.items()})
    else:
        result[robot_seat(first)] = {key: value for key, value in result.items()}
    return {"opens": first, **result}


def check_opponent(name: str) -> None:
    """A bad --opponent is one line before any game starts (and before any progress line)."""
    from ncbot.envs.opponents import make_opponent, opponent_choices

    if name.partition(":")[0] not in {choice.partition(":")[0] for choice in opponent_choices()}:
        make_opponent(name)  # raises the one line naming the choices


def table_command(
    runs_dir: str = typer.Argument(..., help="Folder of runs written by ncbot ablate."),
    out: Optional[str] = out_file(None, "the table (.md; default RUNS_DIR/table.md); its seeds CSV, run profiles and "
                                  "learning-curve PNGs are written beside it."),
    claims: Optional[str] = typer.Option(None, "--claims", metavar="FILE", help="File for the claims table (.md; "
                                         "default paper_claims.md beside --out)."),
    as_json: bool = json_option(),
) -> None:
    """Paper-style table (mean and 95% t-interval over seeds, the paper's numbers beside ours), the paper's claims
    tested over seeds (one-sided Welch's t-tests) and learning-curve PNGs per agent."""
    import shlex
    import sys

    from ncbot.pipelines.reproduce.table import write_report

    for path, option in ((out, "--out"), (claims, "--claims")):
        if path is not None:
            check_writable_file(path, option, (".md",))

    report = write_report(runs_dir, out, claims, command="ncbot " + shlex.join(sys.argv[1:]))
    table = Path(out) if out else Path(runs_dir) / "table.md"
    written = [table, Path(claims) if claims else table.parent / "paper_claims.md",
               table.with_name(f"{table.stem}_seeds.csv"), table.with_name(f"{table.stem}_profiles.png")]
    if as_json:
        print_json({**report.to_dict(), "written": [str(path) for path in written]})
    else:
        typer.echo(report.table + "\n" + report.claims_text)
    wrote(f"{listing(written)}, and the learning curves (curves_*.png) beside them")


def compare_command(
    runs: list[str] = typer.Argument(..., help="Finished run folders (eval.json), or folders of them such as a grid "
                                     "cell (seed0/, seed1/, ...): the set expected to be ahead."),
    against: list[str] = typer.Option(..., "--against", help="The runs to compare with (repeat the option, or "
                                      "name a folder of run folders)."),
    metric: str = typer.Option("first.task_success", "--metric", help="SEAT.KEY of eval.json: first (robot first, "
                               "the paper's set-up) or second, e.g. task_success, win, truncated, avg_length."),
    less: bool = typer.Option(False, "--less", help="H1: RUN's mean is below --against's (e.g. avg_length: "
                              "shorter dialogues)."),
    effect: Optional[float] = typer.Option(None, "--effect", help="The difference worth detecting, fixed before the "
                                           "runs: prints the runs' power to detect it; below 0.8 a result that is "
                                           "not significant reads untested, not refuted."),
    alpha: float = typer.Option(0.05, "--alpha", help="Significance level of the one-sided test."),
    out: Optional[str] = out_file(None, "the report (.md), also printed; every run is drawn beside it (the same "
                                  "name, .png). None by default."),
    as_json: bool = json_option(),
) -> None:
    """Is one set of runs ahead of another over seeds? One-sided Welch's t-test, the difference's interval, power,
    P(a run beats a run) and a rank test."""
    import shlex
    import sys

    from ncbot.fileio import atomic_write_text
    from ncbot.pipelines.reproduce.compare import compare

    if out is not None:
        check_writable_file(out, "--out", (".md",))
    found = compare(runs, against, metric, larger=not less, effect=effect, alpha=alpha)
    figure = None if out is None else Path(out).with_suffix(".png")
    text = found.markdown("ncbot " + shlex.join(sys.argv[1:]), figure=None if figure is None else figure.name)
    if out is not None:
        found.plot(figure)
        atomic_write_text(text, out)
    if as_json:
        print_json({**found.to_dict(), **({"written": [out, str(figure)]} if out is not None else {})})
    else:
        typer.echo(text)
    if out is not None:
        wrote(listing([out, figure]))


def train_value_command(
    out: str = out_folder(..., "positions.pt, value.pt, value.json and value.png."),
    free_move: str = typer.Option("anywhere", "--free-move", help="Ultimate rule: anywhere | open_subgrids (the agent's env.free_move)."),
    positions: int = typer.Option(100_000, "--positions", max=10_000_000, help="Labelled positions to generate."),
    simulations: int = typer.Option(300, "--simulations", max=100_000, help="UCT playouts behind each label."),
    hidden: str = typer.Option("256,256", "--hidden", help="Hidden layer sizes, comma-separated."),
    epochs: int = typer.Option(20, "--epochs", max=10_000, help="Training passes over the positions."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the games and the training."),
    no_progress: bool = no_progress_option(),
    _progress: bool = progress_alias(),
    as_json: bool = json_option(),
) -> None:
    """Train the Ultimate value network that scores the Q-guided search's leaves (use it with --search N --value)."""
    try:
        sizes = [int(h) for h in hidden.split(",") if h.strip()]
    except ValueError:
        raise ValueError(f"--hidden must be comma-separated layer sizes such as 256,256, got {hidden!r}") from None
    check_writable_dir(out, "--out")
    import torch

    from ncbot.pipelines.train.value_training import train_value

    torch.set_num_threads(1)
    report = train_value(out, free_move=free_move, positions=positions, simulations=simulations, hidden=sizes,
                         epochs=epochs, seed=seed, progress=not no_progress)
    written = [Path(out) / name for name in ("positions.pt", "value.pt", "value.json", "value.png")]
    if as_json:
        print_json({**report, "written": [str(path) for path in written]})
    else:
        typer.echo(f"value network: validation MSE {report['val_mse']:.4f} (predicting the mean label: "
                   f"{report['val_mse_of_mean_label']:.4f}) on {report['val_positions']} positions of held-out games; "
                   f"labelling {report['labelling_cpu_s']} CPU s, training {report['training_cpu_s']} CPU s")
    wrote(listing(written))


def register(app: typer.Typer) -> None:
    """Add this area's commands to the root app."""
    app.command("train")(train_command)
    app.command("eval")(eval_command)
    app.command("train-value")(train_value_command)
    app.command("table")(table_command)
    app.command("compare")(compare_command)
    app.command("configs")(configs_command)
