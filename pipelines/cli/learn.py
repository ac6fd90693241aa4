"""`ncbot train`, `ncbot eval`, `ncbot table`: the learning area's commands (`ncbot ablate`: pipelines/cli/grid.py).

Heavy imports (torch, torchrl) happen inside the commands so `ncbot --help` stays fast. Library errors
(ValueError / FileNotFoundError) become one line and exit code 2 in `ncbot.pipelines.cli.app.main`.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from ncbot.pipelines.agents import check_value_option  # light: pathlib only
from ncbot.pipelines.config import MAX_GAMES, MAX_SEED  # light: pydantic and yaml, no torch
from ncbot.pipelines.outputs import check_writable_dir, check_writable_file  # light: os and pathlib only

CHECKPOINT_HELP = "A checkpoint .pt written by ncbot train, or its run folder."


def train_command(
    config: Optional[str] = typer.Argument(None, help="YAML run config: a file or a shipped name (default, ultimate, paper/standard_original; ncbot configs lists them)."),
    overrides: Optional[list[str]] = typer.Argument(None, help="section.key=value overrides, e.g. optim.lr=0.0005."),
    out: Optional[str] = typer.Option(None, "--out", "-o", help="Run folder (default runs/<config name>)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed (overrides train.seed)."),
    episodes: Optional[int] = typer.Option(None, "--episodes", help="Stop after N training games instead of frames."),
    resume: Optional[str] = typer.Option(None, "--resume", help="Continue the run in this folder from its last checkpoint."),
    no_mcap: bool = typer.Option(False, "--no-mcap", help="Do not write the MCAP episode log."),
    no_progress: bool = typer.Option(False, "--no-progress", help="Hide the progress bar."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the run already in --out (its checkpoints, "
                                   "log, eval.json); without it such a folder is refused."),
) -> None:
    """Train an agent (competitive DQN or a baseline) and write checkpoint, eval.json, curve PNG and MCAP log."""
    from ncbot.pipelines.train.run import resolve_run, train

    config_path, extra = config, list(overrides or [])
    if resume and config_path and "=" in config_path:  # `ncbot train --resume DIR key=value`
        config_path, extra = None, [config_path, *extra]
    run_config, run_dir, resuming = resolve_run(config_path, extra, out=out, seed=seed, episodes=episodes,
                                                resume=resume, mcap=not no_mcap)
    if no_progress:
        run_config.logger.progress = False
    if overwrite and resuming:
        raise ValueError("give --resume or --overwrite, not both (--overwrite replaces the run --resume continues)")
    report = train(run_config, run_dir, resume=resuming, overwrite=overwrite)
    typer.echo(f"run folder: {run_dir}")
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
) -> None:
    """List the configs shipped with ncbot (name, kind, what it is), or print one to start your own from."""
    from ncbot.pipelines.config import shipped_configs

    configs = shipped_configs()
    if name is not None:
        path = configs.get(name.removesuffix(".yaml"))
        if path is None:
            raise ValueError(f"no shipped config named {name!r}; shipped: {', '.join(configs)}")
        typer.echo(path.read_text(encoding="utf-8"), nl=False)
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
    games: int = typer.Option(3000, "--games", max=MAX_GAMES, help="Number of greedy test games."),
    opponent: str = typer.Option("random", "--opponent", help="Simulated user's move policy (envs.opponents name)."),
    first: str = typer.Option("alternate", "--first", help="Who opens: robot | human | alternate (half the games each)."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the test games."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object with the metrics."),
    out: Optional[str] = typer.Option(None, "--out", "-o", help="Also log the test games to MCAP in this folder."),
    search: Optional[int] = typer.Option(None, "--search", max=100_000, help="Game moves by MCTS guided by the Q-network, N simulations."),
    exhaustive: bool = typer.Option(False, "--exhaustive", help="3x3: every game branch of the random user, exact probabilities (ignores --games/--opponent)."),
    dialogue_seeds: int = typer.Option(8, "--dialogue-seeds", help="With --exhaustive: dialogue draws (words, ASR confidences) to enumerate under."),
    value: Optional[str] = typer.Option(None, "--value", help="With --search on Ultimate: a value network (ncbot train-value) scores the search's leaves."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show games done, rate and ETA on stderr "
                                  "(a bar on a terminal, a line every tenth of the games in a pipe)."),
) -> None:
    """Play greedy test games with a trained agent and report the paper's metrics."""
    from ncbot.pipelines.run_env import check_first, robot_seat

    check_first(first, name="--first")
    check_value_option(value, search)
    if out is not None:
        check_writable_dir(out, "--out")
    import torch

    from ncbot.pipelines.evaluate.games import evaluate_checkpoint
    from ncbot.pipelines.agents import register_agent_opponent

    torch.set_num_threads(1)
    if exhaustive:
        _exhaustive_eval(checkpoint, first, seed, dialogue_seeds, as_json)
        return
    register_agent_opponent()  # --opponent agent:CKPT / qmcts:N:CKPT
    result = evaluate_checkpoint(checkpoint, games=games, opponent=opponent, first=first, seed=seed, mcap_dir=out,
                                 search=search, value=value, progress=progress)
    if as_json:
        typer.echo(json.dumps(result.to_dict()))
    else:
        typer.echo(_results_header())
        typer.echo(_results_row(result.to_dict(), "alternate" if first == "alternate" else robot_seat(first)))


def _exhaustive_eval(checkpoint: str, first: str, seed: int, dialogue_seeds: int, as_json: bool) -> None:
    """`ncbot eval --exhaustive`: exact win/draw/loss per seat and the lost games, if any."""
    from ncbot.pipelines.evaluate.exact import exact_checkpoint

    results = exact_checkpoint(checkpoint, first=first, seed=seed, dialogue_seeds=dialogue_seeds)
    if as_json:
        typer.echo(json.dumps({result.seat: result.to_dict() for result in results}))
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


def table_command(
    runs_dir: str = typer.Argument(..., help="Folder of runs written by ncbot ablate."),
    out: Optional[str] = typer.Option(None, "--out", "-o", help="Markdown table to write (default RUNS_DIR/table.md)."),
    claims: Optional[str] = typer.Option(None, "--claims", help="Markdown claims table to write (default paper_claims.md beside --out)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object {command, rows, claims} instead of the markdown (files are still written)."),
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
    typer.echo(json.dumps(report.to_dict()) if as_json else report.table + "\n" + report.claims_text)


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
    out: Optional[str] = typer.Option(None, "--out", "-o", help="Also write the report to this markdown file, "
                               "and every run drawn beside it (the same name, .png)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object instead of the markdown."),
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
    typer.echo(json.dumps(found.to_dict()) if as_json else text)


def train_value_command(
    out: str = typer.Option(..., "--out", "-o", help="Folder for positions.pt, value.pt, value.json and value.png."),
    free_move: str = typer.Option("anywhere", "--free-move", help="Ultimate rule: anywhere | open_subgrids (the agent's env.free_move)."),
    positions: int = typer.Option(100_000, "--positions", max=10_000_000, help="Labelled positions to generate."),
    simulations: int = typer.Option(300, "--simulations", max=100_000, help="UCT playouts behind each label."),
    hidden: str = typer.Option("256,256", "--hidden", help="Hidden layer sizes, comma-separated."),
    epochs: int = typer.Option(20, "--epochs", max=10_000, help="Training passes over the positions."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the games and the training."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show progress (rate, ETA) while labelling."),
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
                         epochs=epochs, seed=seed, progress=progress)
    typer.echo(f"value network: validation MSE {report['val_mse']:.4f} (predicting the mean label: "
               f"{report['val_mse_of_mean_label']:.4f}) on {report['val_positions']} positions of held-out games; "
               f"labelling {report['labelling_cpu_s']} CPU s, training {report['training_cpu_s']} CPU s")
    typer.echo(f"Wrote {out}/value.pt, value.json and value.png")


def register(app: typer.Typer) -> None:
    """Add this area's commands to the root app."""
    app.command("train")(train_command)
    app.command("eval")(eval_command)
    app.command("train-value")(train_value_command)
    app.command("table")(table_command)
    app.command("compare")(compare_command)
    app.command("configs")(configs_command)
