"""MCTS speed and strength: simulations/s, seconds per 100-simulation game vs random, win rates vs random.

Run by hand (figures go to docs/opponents.md):

    python bench/mcts_speed.py                 # both games, 100 games per strength row
    python bench/mcts_speed.py --games 300 --budgets 10 100 300

The goal: enough simulations per second that a 100-simulation game against random plays in under
0.2 s. "needed sims/s" below is that requirement for the measured number of MCTS decisions per game.
Timings on a shared machine are noisy; run twice and keep the better figure when others are busy.
"""
from __future__ import annotations

import argparse
import random
import time

import torch

from ncbot.envs.opponents import make_opponent
from ncbot.envs.opponents.arena import play_match
from ncbot.envs.games import make_game
from ncbot.envs.opponents.bitboards import DRAW, ONGOING
from ncbot.envs.opponents.mcts import uct_search

SETTINGS = [("standard", "anywhere"), ("ultimate", "anywhere"), ("ultimate", "open_subgrids")]


def engine_game(game: str, free_move: str, simulations: int, mcts_side: int, seed: int) -> tuple[int, int, float, float]:
    """One game MCTS vs uniform random on the bitboards: (MCTS points 2/1/0, decisions, wall s, CPU s)."""
    engine = make_game(game, free_move).search_engine()
    rng = random.Random(seed)
    pos = engine.from_board([0] * engine.n_cells, 1)
    decisions = 0
    began, began_cpu = time.perf_counter(), time.process_time()
    while engine.result(pos) == ONGOING:
        moves = engine.moves(pos)
        if engine.turn(pos) == mcts_side:
            move, _ = uct_search(engine, pos, moves, simulations, rng)
            decisions += 1
        else:
            move = moves[int(rng.random() * len(moves))]
        pos = engine.play(pos, move)
    seconds, cpu_seconds = time.perf_counter() - began, time.process_time() - began_cpu
    result = engine.result(pos)
    points = 1 if result == DRAW else 2 if result == mcts_side else 0
    return points, decisions, seconds, cpu_seconds


def simulations_per_second(game: str, free_move: str, simulations: int = 2000, seed: int = 0) -> tuple[float, float]:
    """UCT iterations per wall second and per CPU second from the empty board (the longest playouts)."""
    engine = make_game(game, free_move).search_engine()
    pos = engine.from_board([0] * engine.n_cells, 1)
    began, began_cpu = time.perf_counter(), time.process_time()
    uct_search(engine, pos, engine.moves(pos), simulations, random.Random(seed))
    return simulations / (time.perf_counter() - began), simulations / (time.process_time() - began_cpu)


def batched_select_ms(game: str, free_move: str, name: str, batch: int = 1024, repeats: int = 20) -> float:
    """Milliseconds per ``select`` call on ``batch`` random unfinished positions (the env's per-step cost)."""
    rules = make_game(game, free_move)
    rng = random.Random(0)
    states = []
    while len(states) < batch:
        s = rules.new()
        stop = rng.randrange(rules.n_cells)
        while rules.outcome(s) is None and s.n_marks < stop:
            s = rules.play(s, rng.choice(rules.legal(s)))
        if rules.outcome(s) is None and rules.mark_to_move(s) == 1:
            states.append(s)
    boards = torch.tensor([s.board for s in states], dtype=torch.int8)
    last_move = torch.tensor([s.last_move for s in states])
    legal = torch.zeros(batch, rules.n_cells, dtype=torch.bool)
    for row, s in enumerate(states):
        legal[row, rules.legal(s)] = True
    owners = torch.tensor([s.subgrids for s in states], dtype=torch.int8) if game == "ultimate" else None
    opponent = make_opponent(name, game=game, free_move=free_move)
    generator = torch.Generator().manual_seed(0)
    opponent.select(boards, last_move, legal, 1, generator, owners=owners)
    began = time.perf_counter()
    for _ in range(repeats):
        opponent.select(boards, last_move, legal, 1, generator, owners=owners)
    return (time.perf_counter() - began) / repeats * 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", type=int, default=100, help="games per seat for the strength rows")
    parser.add_argument("--timing-games", type=int, default=40, help="games per seat for the 100-sim timing")
    parser.add_argument("--budgets", type=int, nargs="+", default=[10, 100, 300])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)

    print("## speed (plain Python bitboards, one core; wall time is noisy on a shared machine, CPU time much less so)")
    print("| game | rule | sims/s from empty board (wall / CPU) | s per 100-sim game vs random, MCTS first / second "
          "(wall) | same in CPU s | MCTS decisions per game | sims/s needed for 0.2 s |")
    print("|---|---|---|---|---|---|---|")
    for game, free_move in SETTINGS:
        rate, cpu_rate = simulations_per_second(game, free_move, seed=args.seed)
        wall, cpu = [], []
        decisions = 0
        for side in (0, 1):
            runs = [engine_game(game, free_move, 100, side, args.seed + i) for i in range(args.timing_games)]
            wall.append(sum(run[2] for run in runs) / len(runs))
            cpu.append(sum(run[3] for run in runs) / len(runs))
            decisions += sum(run[1] for run in runs)
        mean_decisions = decisions / (2 * args.timing_games)
        rule = free_move if game == "ultimate" else "-"
        print(f"| {game} | {rule} | {rate:,.0f} / {cpu_rate:,.0f} | {wall[0]:.3f} / {wall[1]:.3f} | "
              f"{cpu[0]:.3f} / {cpu[1]:.3f} | {mean_decisions:.1f} | {mean_decisions * 100 / 0.2:,.0f} |", flush=True)

    print()
    print("## batched opponents: ms per select on 1,024 random positions")
    print("| game | rule | random | rule | minimax |")
    print("|---|---|---|---|---|")
    for game, free_move in SETTINGS:
        names = ["random", "rule"] + (["minimax"] if game == "standard" else [])
        cost = [f"{batched_select_ms(game, free_move, name):.2f}" for name in names] + ([] if game == "standard" else ["-"])
        rule = free_move if game == "ultimate" else "-"
        print(f"| {game} | {rule} | " + " | ".join(cost) + " |")

    print()
    print(f"## strength vs random ({args.games} games per seat; score = win 1, draw 0.5)")
    print("| game | rule | opponent | first: W/D/L | score | second: W/D/L | score | s per game |")
    print("|---|---|---|---|---|---|---|---|")
    for game, free_move in SETTINGS:
        names = [f"mcts:{n}" for n in args.budgets]
        for name in names:
            player = make_opponent(name, game=game, free_move=free_move, seed=args.seed)
            rnd = make_opponent("random", game=game, free_move=free_move, seed=args.seed + 1)
            first = play_match(player, rnd, args.games, seed=args.seed)
            second = play_match(rnd, player, args.games, seed=args.seed + 1)
            per_game = (first.first_seconds + second.second_seconds) / (2 * args.games)
            rule = free_move if game == "ultimate" else "-"
            print(f"| {game} | {rule} | {name} | {first.first_wins}/{first.draws}/{first.second_wins} | {first.first_score:.3f} | "
                  f"{second.second_wins}/{second.draws}/{second.first_wins} | {second.second_score:.3f} | {per_game:.3f} |",
                  flush=True)


if __name__ == "__main__":
    main()
