"""`ncbot ladder`: how good is a trained agent against more than a random player?

The agent plays its full dialogues in the real env, greedy with its own look-ahead masks, while the simulated
user's game moves come from each opponent of the ladder (``ncbot.envs.opponents``), from both seats. Scores count a
win 1 and a draw 0.5. The project's goals are checked and printed with the table: on 3x3 never lose to
``minimax`` or ``random``; on Ultimate score at least 0.5 against ``mcts:100``, 0.75 against
``mcts:1000``, 0.5 against ``mcts:10000`` and against OpenSpiel's ``openspiel-mcts:1000`` when played.
Each score carries a 95 % Wilson interval (draws as half points, so approximate), and a goal is "met" or "missed"
only when that interval lies on one side of the target; otherwise the games played do not decide it. With
``--search`` the robot's CPU seconds per searched move are measured per row and checked against the
robot's 0.2 s budget.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.evaluate.games import wilson_interval

SOLVED_LADDER = ["random", "rule", "minimax"]  # a game with an exact solver (Game.solver): perfect play on top
SEARCH_LADDER = ["random", "rule", "mcts:10", "mcts:100"]  # a game too large to solve: search of growing budget
LONGER_LADDERS = {"ultimate": SEARCH_LADDER + ["mcts:300"]}  # games whose agents outgrow mcts:100 (by game id)
OPENERS = ("robot", "human")  # each match is played robot-first and human-first
# score targets by game id: Ultimate's, mcts:100 and strong search (openspiel-mcts needs free_move open_subgrids)
SCORE_GOALS = {"ultimate": {"mcts:100": 0.5, "mcts:1000": 0.75, "mcts:10000": 0.5, "openspiel-mcts:1000": 0.5}}
SEARCH_SECONDS_PER_MOVE = 0.2  # the robot's decision budget with search, one core


def run_ladder(checkpoint: str, *, games: int = 200, opponents: list[str] | None = None, seed: int = 0,
               out_dir: str | None = None, progress: bool = True, baseline: bool = False,
               search: int | None = None, lookahead: str | None = None, value: str | None = None,
               workers: int = 1) -> dict[str, Any]:
    """Play every (opponent, seat) pair; write ladder.md / ladder.json / ladder.png; return rows, goals and paths.

    ``baseline`` also plays the agent's look-ahead masks alone (random choice inside them) on the same games,
    so the table shows what learning added beyond the masks. ``search`` / ``lookahead``: how the robot decides
    (``load_robot``; ``value``: a value network scores the search's leaves); the table header says which.
    ``workers`` > 1 plays the matches in that many processes (200 games against ``mcts:10000`` take ~25 min per
    seat): every match re-seeds the robot's own chance from its match seed, so the rows are the same for any
    number of workers.
    """
    import torch

    from ncbot.envs.opponents import make_opponent

    if games < 1:
        raise ValueError(f"--games must be a positive number of games per opponent and seat, got {games}")
    if workers < 1:
        raise ValueError(f"--workers must be a positive number of processes, got {workers}")
    torch.set_num_threads(1)
    robot_spec = (checkpoint, search, lookahead, seed, value, baseline)
    config, robot, choosers = load_ladder_robot(*robot_spec)
    game = config.env.game
    names = list(opponents) if opponents else default_ladder(game)
    for name in names:  # fail fast, with the registry's message, before any game is played
        make_opponent(name, game=game, free_move=config.env.free_move)
    pairs = [(name, first, who) for name in names for first in OPENERS for who in choosers]
    # the agent and the baseline meet the same games: one match seed per (opponent, seat)
    matches = [(name, first, who, seed + 1000 * (index // len(choosers)))
               for index, (name, first, who) in enumerate(pairs)]
    bar = None
    if progress:
        from ncbot.pipelines.progress import progress_bar

        bar = progress_bar(total=len(matches), desc="ladder", unit="match")
    rows: list[dict[str, Any]] = [{} for _ in matches]
    if workers > 1 and len(matches) > 1:
        import multiprocessing

        # a multiprocessing Pool, not a ProcessPoolExecutor: on Ctrl-C or SIGTERM the executor's exit waits for
        # the running matches (25 min each against mcts:10000); Pool.terminate stops the workers at once
        from ncbot.envs.games import named_games

        # only this ladder's game is named again in a worker: another class named earlier in this process may no
        # longer import, and a Pool whose initializer raises starts new workers forever
        named = tuple(name for name in named_games() if name == game)
        pool = multiprocessing.get_context("spawn").Pool(min(workers, len(matches)), initializer=_load_worker_robot,
                                                         initargs=(named, *robot_spec))
        try:
            tasks = [(index, *match, games) for index, match in enumerate(matches)]
            for index, row in pool.imap_unordered(_play_worker_match, tasks):
                rows[index] = row
                if bar is not None:
                    name, first, who, _ = matches[index]
                    bar.set_postfix_str(f"done: {who} vs {name} ({first} first)")
                    bar.update(1)
            pool.close()
        except BaseException:
            pool.terminate()
            raise
        finally:
            pool.join()
    else:
        for index, (name, first, who, match_seed) in enumerate(matches):
            if bar is not None:
                bar.set_postfix_str(f"{who} vs {name} ({first} first)")
            rows[index] = play_ladder_match(config, choosers[who], who, name, first, match_seed, games)
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    goals = check_goals(game, rows)
    out = Path(out_dir) if out_dir else _default_out(checkpoint)
    markdown = ladder_markdown(checkpoint, game, config.agent.name, rows, goals, robot=robot)
    summary = {"checkpoint": str(checkpoint), "game": game, "agent": config.agent.name, "robot": robot,
               "search": search or 0, "value": value, "lookahead": config.lookahead, "seed": seed, "rows": rows, "goals": goals}
    files = {
        "markdown": atomic_write_text(markdown, out / "ladder.md"),
        "json": atomic_write_text(json.dumps(summary, indent=2), out / "ladder.json"),
        "png": draw_ladder(rows, out / "ladder.png", title=f"{config.agent.name} on {game} ({robot}): score vs opponents"),
    }
    return {"rows": rows, "goals": goals, "markdown": markdown, "files": {k: str(v) for k, v in files.items()}}


def load_ladder_robot(checkpoint: str, search: int | None, lookahead: str | None, seed: int, value: str | None,
                      baseline: bool) -> tuple[Any, str, dict[str, Any]]:
    """(config, description of how the robot decides, {"agent": policy[, "look-ahead only": masks alone]})."""
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy
    from ncbot.pipelines.agents import load_robot, register_agent_opponent

    register_agent_opponent()
    config, policy, robot = load_robot(checkpoint, search=search, lookahead=lookahead, seed=seed, value=value)
    choosers = {"agent": policy}
    if baseline:
        choosers["look-ahead only"] = LookaheadOnlyPolicy(seed, config.lookahead, config.agent.all_negative)
    return config, robot, choosers


def play_ladder_match(config, chooser, who: str, opponent: str, first: str, match_seed: int,
                      games: int) -> dict[str, Any]:
    """One ladder row: ``games`` games of ``chooser`` against ``opponent``, ``first`` (robot | human) opening; the
    row's "seat" is the robot's (``run_env.robot_seat``).

    The chooser's own random stream (the search's per-move seeds, the baseline's choice) restarts from
    ``match_seed``, so a match's games do not depend on which matches ran before it in the same process."""
    from ncbot.pipelines.evaluate.games import evaluate_agent
    from ncbot.pipelines.run_env import robot_seat

    generator = getattr(chooser, "generator", None)
    if generator is not None:
        generator.manual_seed(match_seed)
    searched = (getattr(chooser, "decisions", 0), getattr(chooser, "cpu_seconds", 0.0))
    result = evaluate_agent(config, chooser, games=games, first=first, seed=match_seed, opponent=opponent)
    row = {
        "policy": who, "opponent": opponent, "seat": robot_seat(first), "games": result.games, "win": result.win, "draw": result.draw,
        "loss": result.loss, "score": result.win + 0.5 * result.draw, "task_success": result.task_success,
        "task_success_ci95": result.task_success_ci95, "avg_length": result.avg_length,
    }
    if hasattr(chooser, "decisions"):  # the guided search counts its moves and their CPU over every match
        moves = chooser.decisions - searched[0]  # named as ncbot eval --json names them
        row["search_decisions"] = moves
        row["search_cpu_s_per_decision"] = (chooser.cpu_seconds - searched[1]) / max(moves, 1)
    return row


_WORKER_ROBOT: tuple[Any, dict[str, Any]] | None = None  # (config, choosers) of a ladder worker process


def _load_worker_robot(named: tuple[str, ...], *robot_spec: Any) -> None:
    """Process-pool initializer: each worker loads the robot once, single-threaded like the parent, and names the
    game classes the user named in the parent (a spawned process starts with none)."""
    import signal

    import torch

    from ncbot.envs.games import load_game

    for game in named:
        load_game(game)

    global _WORKER_ROBOT
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group: the parent stops the workers
    torch.set_num_threads(1)
    config, _, choosers = load_ladder_robot(*robot_spec)
    _WORKER_ROBOT = (config, choosers)


def _play_worker_match(task: tuple) -> tuple[int, dict[str, Any]]:
    """(index, row) of one match, ``task`` = (index, opponent, first, who, match seed, games)."""
    assert _WORKER_ROBOT is not None, "ladder worker used before its initializer ran"
    index, opponent, first, who, match_seed, games = task
    config, choosers = _WORKER_ROBOT
    return index, play_ladder_match(config, choosers[who], who, opponent, first, match_seed, games)


def default_ladder(game: str) -> list[str]:
    """The opponents a ladder of ``game`` climbs by default: perfect play where the game has an exact solver, else
    search of growing budget."""
    from ncbot.envs.games import make_game

    if game in LONGER_LADDERS:
        return list(LONGER_LADDERS[game])
    return list(SOLVED_LADDER if make_game(game).solver() is not None else SEARCH_LADDER)


def check_goals(game: str, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The goals that this ladder covers: each with its value, and "met" / "missed" / "undecided".

    ``met`` is the point estimate's verdict (kept for scripts); ``verdict`` says whether the games played decide
    it: the score's 95 % Wilson interval wholly at or above the target (met) or below it (missed). A game with an
    exact solver: never lose to random or minimax; a game with score targets (``SCORE_GOALS``): those."""
    from ncbot.envs.games import make_game

    by_opponent: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        if row.get("policy", "agent") == "agent":
            by_opponent.setdefault(row["opponent"], []).append(row)
    goals = []
    if make_game(game).solver() is not None:
        for name in ("random", "minimax"):
            if name in by_opponent:
                losses = sum(round(r["loss"] * r["games"]) for r in by_opponent[name])
                goals.append({"goal": f"never loses to {name}", "met": losses == 0, "value": f"{losses} losses",
                              "verdict": "met" if losses == 0 else "missed"})
    for name, target in SCORE_GOALS.get(game, {}).items():
        if name in by_opponent:
            matches = by_opponent[name]
            played = sum(r["games"] for r in matches)
            points = sum(r["score"] * r["games"] for r in matches)
            low, high = wilson_interval(points, played)
            verdict = "met" if low >= target else "missed" if high < target else "undecided"
            goals.append({"goal": f"score >= {target} against {name}", "met": points / played >= target,
                          "value": f"{points / played:.3f} [{low:.3f}, {high:.3f}] over {played} games",
                          "verdict": verdict})
    searched = [r for r in rows if "search_cpu_s_per_decision" in r]
    if searched:
        worst = max(r["search_cpu_s_per_decision"] for r in searched)
        goals.append({"goal": f"<= {SEARCH_SECONDS_PER_MOVE} CPU s per searched move (one core)",
                      "met": worst <= SEARCH_SECONDS_PER_MOVE, "value": f"{worst:.3f} s in the slowest match",
                      "verdict": "met" if worst <= SEARCH_SECONDS_PER_MOVE else "missed"})
    return goals


def ladder_markdown(checkpoint: str, game: str, agent: str, rows: list[dict[str, Any]], goals: list[dict[str, Any]],
                    robot: str = "greedy Q, the checkpoint's masks") -> str:
    lines = [f"# Ladder: {agent} ({game}) from `{checkpoint}`", "", f"Robot decides by: {robot}.", "",
             "| robot policy | opponent | robot seat | games | win | draw | loss | score | task success (95% CI) | actions/game | CPU s/searched move |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        low, high = r["task_success_ci95"]
        cpu = f"{r['search_cpu_s_per_decision']:.3f}" if "search_cpu_s_per_decision" in r else "-"
        lines.append(f"| {r.get('policy', 'agent')} | {r['opponent']} | {r['seat']} | {r['games']} | {r['win']:.3f} | {r['draw']:.3f} | {r['loss']:.3f} | "
                     f"{r['score']:.3f} | {r['task_success']:.3f} ({low:.3f}-{high:.3f}) | {r['avg_length']:.1f} | {cpu} |")
    if goals:
        lines += ["", "Goals (a score goal is decided when its 95 % interval lies on one side of the target):"]
        lines += [f"- {g.get('verdict', 'met' if g['met'] else 'missed')}: {g['goal']} ({g['value']})" for g in goals]
    return "\n".join(lines) + "\n"


def draw_ladder(rows: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Stacked win/draw/loss bars per opponent and seat (what a reader checks first: where does it lose?)."""
    from ncbot.pipelines.plots import pyplot, save_figure

    plt = pyplot()

    labels = [f"{'' if r.get('policy', 'agent') == 'agent' else 'masks only: '}{r['opponent']}\n"
              f"{'robot first' if r['seat'] == 'first' else 'robot second'}" for r in rows]
    x = range(len(rows))
    fig, ax = plt.subplots(figsize=(max(7.0, 1.3 * len(rows) + 2.0), 4.0))
    wins = [r["win"] for r in rows]
    draws = [r["draw"] for r in rows]
    losses = [r["loss"] for r in rows]
    hatches = [None if r.get("policy", "agent") == "agent" else "//" for r in rows]  # baseline rows hatched
    for heights, bottom, colour, label in ((wins, None, "#2a9d8f", "win"), (draws, wins, "#e9c46a", "draw"),
                                           (losses, [w + d for w, d in zip(wins, draws)], "#e76f51", "loss")):
        for patch, hatch in zip(ax.bar(x, heights, bottom=bottom, color=colour, label=label), hatches):
            patch.set_hatch(hatch)
    ax.plot(list(x), [r["score"] for r in rows], "ko", label="score (win 1, draw 0.5)")
    ax.set_xticks(list(x), labels, fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("fraction of games")
    ax.set_title(title)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    return path


def _default_out(checkpoint: str) -> Path:
    path = Path(checkpoint)
    return path if path.is_dir() else path.parent
