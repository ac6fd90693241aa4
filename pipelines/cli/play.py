"""`ncbot play` (a person plays the robot in the terminal) and `ncbot ladder` (a checkpoint against stronger opponents)."""
from __future__ import annotations

from typing import Optional

import typer

from ncbot.pipelines.agents import LOOKAHEAD_CHOICES  # light: the module imports torch only inside its functions
from ncbot.pipelines.config import MAX_GAMES, MAX_SEED
from ncbot.pipelines.agents import check_value_option  # light: pathlib only
from ncbot.pipelines.cli.conventions import (json_option, listing, no_log_option, no_progress_option, out_folder,
                                             print_json, wrote)
from ncbot.pipelines.outputs import check_writable_dir


def play_command(
    checkpoint: Optional[str] = typer.Argument(None, help="A checkpoint .pt written by ncbot train, or its run folder "
                                               "(its game is played); without it the robot uses the look-ahead masks "
                                               "alone, choosing at random inside them."),
    game: Optional[str] = typer.Option(None, "--game", help="standard | ultimate | a declared game (four, connect_four, "
                                       "a game YAML file) | a game class (path/to/file.py:Misere), without a checkpoint "
                                       "(default standard); with one, it names the game class of a run of your own game."),
    first: str = typer.Option("robot", "--first", help="Who opens: robot | human (you draw the first mark)."),
    free_move: Optional[str] = typer.Option(None, "--free-move", help="Ultimate rule: anywhere | open_subgrids."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the robot's random choices (look-ahead policy) and the env."),
    out: str = out_folder("runs/play", "the MCAP log of the game."),
    no_log: bool = no_log_option(),
) -> None:
    """Play noughts & crosses against the robot: answer it in a few words, type cells like b2 (e5 on ultimate)."""
    if game is not None:
        from ncbot.envs.games import load_game

        game = load_game(game).id
    from ncbot.pipelines.run_env import check_first

    check_first(first, ("robot", "human"), "--first")
    if free_move is not None and free_move not in ("anywhere", "open_subgrids"):
        raise ValueError(f"--free-move must be anywhere or open_subgrids, got {free_move!r}")
    if not no_log:
        check_writable_dir(out, "--out")
    from ncbot.pipelines.evaluate.play import QuitGame, play_dialogue  # torch and the env load only now: errors above stay fast

    try:
        summary = play_dialogue(game=game, checkpoint=checkpoint, first=first, free_move=free_move, seed=seed,
                                log_dir=None if no_log else out)
    except QuitGame:
        typer.echo("\nGame stopped. Goodbye!")
        return
    except KeyboardInterrupt:
        typer.echo("\nGame interrupted (Ctrl-C). Goodbye!")
        raise typer.Exit(130)
    typer.echo(f"Result: {summary['outcome']} after {summary['actions']} robot actions.")
    if not no_log:
        wrote(f"the game's MCAP log to {out} (ncbot logs show {out} ID replays it)")


def ladder_command(
    checkpoint: str = typer.Argument(..., help="A checkpoint .pt written by ncbot train, or its run folder."),
    games: int = typer.Option(200, "--games", max=MAX_GAMES, help="Games per opponent and seat."),
    opponents: Optional[str] = typer.Option(None, "--opponents", help="Comma-separated opponent names; default: "
                                            "random,rule,minimax (3x3) or random,rule,mcts:10,mcts:100,mcts:300."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the test games."),
    out: Optional[str] = out_folder(None, "ladder.md, ladder.json and ladder.png (default: beside the checkpoint)."),
    baseline: bool = typer.Option(False, "--baseline", help="Also play the agent's look-ahead masks alone (random "
                                  "inside them) on the same games: what did learning add?"),
    search: Optional[int] = typer.Option(None, "--search", help="The robot picks game moves by MCTS guided by its "
                                         "Q-network with N simulations (as ncbot eval --search); default: greedy Q."),
    lookahead: Optional[str] = typer.Option(None, "--lookahead", help="Replace the checkpoint's masks: none | "
                                            "one_step (the paper's) | k1..k5 (forced-loss search of k plies)."),
    value: Optional[str] = typer.Option(None, "--value", help="With --search on Ultimate: a value network (value.pt "
                                        "from ncbot train-value) scores the search's leaves instead of random playouts."),
    workers: int = typer.Option(1, "--workers", help="Matches (opponent x seat) played in parallel processes; the "
                                "rows are the same for any number."),
    game: Optional[str] = typer.Option(None, "--game", help="The run's game class (my_pkg.games:Misere, "
                                       "path/to/file.py:Misere) for a run of your own game: ncbot imports a game's "
                                       "code only when you name it."),
    as_json: bool = json_option(),
    no_progress: bool = no_progress_option(),
) -> None:
    """Play a trained agent against a ladder of opponents from both seats; write a markdown table and a PNG."""
    from pathlib import Path

    if games < 1:
        raise ValueError(f"--games must be a positive number of games per opponent and seat, got {games}")
    if search is not None and search < 1:
        raise ValueError(f"--search must be a positive number of simulations, got {search}")
    if workers < 1:
        raise ValueError(f"--workers must be a positive number of processes, got {workers}")
    if lookahead is not None and lookahead not in LOOKAHEAD_CHOICES:
        raise ValueError(f"--lookahead must be one of {', '.join(LOOKAHEAD_CHOICES)}, got {lookahead!r}")
    check_value_option(value, search)
    if not Path(checkpoint).exists():
        raise FileNotFoundError(f"checkpoint {checkpoint!r} not found (expected a checkpoint.pt written by ncbot train)")
    if out is not None:
        check_writable_dir(out, "--out")
    from ncbot.pipelines.evaluate.ladder import run_ladder  # torch and the env load only now: errors above stay fast
    from ncbot.pipelines.game_option import name_game

    name_game(game, checkpoint)

    names = [name.strip() for name in opponents.split(",") if name.strip()] if opponents is not None else None
    if names is not None and not names:
        raise ValueError(f"--opponents must name at least one opponent (e.g. random,rule,minimax), got {opponents!r}")
    result = run_ladder(checkpoint, games=games, opponents=names, seed=seed, out_dir=out, baseline=baseline,
                        search=search, lookahead=lookahead, value=value, workers=workers, progress=not no_progress)
    written = [result["files"][kind] for kind in ("markdown", "json", "png")]
    if as_json:
        print_json({"rows": result["rows"], "goals": result["goals"], "written": written})
    else:
        typer.echo(result["markdown"])
    wrote(listing(written))


def match_command(
    first: str = typer.Argument(..., help="Opponent name moving first, e.g. random, rule, minimax, mcts:100, agent:CKPT."),
    second: str = typer.Argument(..., help="Opponent name moving second."),
    game: str = typer.Option("standard", "--game", help="standard | ultimate | a declared game (four, connect_four, a game YAML file) | a game class (path/to/file.py:Misere)."),
    free_move: str = typer.Option("anywhere", "--free-move", help="Ultimate rule: anywhere | open_subgrids."),
    games: int = typer.Option(100, "--games", max=MAX_GAMES, help="Number of games."),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="Seed of the match."),
    as_json: bool = json_option(),
    no_progress: bool = no_progress_option(),
) -> None:
    """Play two opponents against each other with the exact rules (no dialogue) and print W/D/L and timing."""
    if games < 1:
        raise ValueError(f"--games must be a positive number of games, got {games}")
    import torch

    from ncbot.envs.games import load_game
    from ncbot.envs.opponents import make_opponent
    from ncbot.envs.opponents.arena import play_match
    from ncbot.pipelines.agents import register_agent_opponent
    from ncbot.pipelines.progress import progress_bar

    torch.set_num_threads(1)
    register_agent_opponent()
    game = load_game(game, free_move).id
    players = [make_opponent(name, game=game, free_move=free_move, seed=seed + i) for i, name in enumerate((first, second))]
    result = play_match(players[0], players[1], games, seed=seed, progress=progress_bar)
    if as_json:
        print_json({"game": game, "games": games, "draws": result.draws, "first_score": result.first_score,
                    "first": {"player": first, "wins": result.first_wins, "seconds_per_game": result.first_seconds / games},
                    "second": {"player": second, "wins": result.second_wins,
                               "seconds_per_game": result.second_seconds / games}})
        return
    typer.echo("| first | second | games | first wins | draws | second wins | first score | s per game (first / second) |")
    typer.echo("|---|---|---|---|---|---|---|---|")
    typer.echo(f"| {first} | {second} | {games} | {result.first_wins} | {result.draws} | {result.second_wins} | "
               f"{result.first_score:.3f} | {result.first_seconds / games:.4f} / {result.second_seconds / games:.4f} |")


def register(app: typer.Typer) -> None:
    """Add this area's commands to the root app."""
    app.command("play")(play_command)
    app.command("ladder")(ladder_command)
    app.command("match")(match_command)
