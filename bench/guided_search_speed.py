"""Q-guided search speed: CPU seconds per decision at several budgets, and how many simulations fit in 0.2 s.

Run by hand (figures go to docs/ultimate.md, "A faster search"):

    python bench/guided_search_speed.py CHECKPOINT --value VALUE.pt
    python bench/guided_search_speed.py CHECKPOINT --value VALUE.pt --budgets 1600 4000 --positions 12
    python bench/guided_search_speed.py PLAIN.pt THREATS.pt --budgets 100 400   # Q-value leaves, two agents in one run

The robot has 0.2 CPU s per move on one core; the stronger the search within that budget, the better
it plays against ``mcts:10000``. Positions come from seeded random openings of 4 to 40 moves (Ultimate), the same
for every row. The "torch reads" row reads both networks through ``nn.Module`` instead of the search's numpy
reader (``ncbot.modules.networks.qnet.MLPReader``): the two rows' ratio is the reader's gain on this machine, measured in one run.
Several checkpoints are timed on the same positions in one run (e.g. an agent without and one with the env's threat
planes, whose search builds the planes at every expansion): their rows' ratio is what the planes cost.
"""
from __future__ import annotations

import argparse
import random
import time

import torch

from ncbot.envs.opponents.bitboards import ONGOING
from ncbot.pipelines.agents import load_agent, guided_search

BUDGET_SECONDS = 0.2


def positions(engine, count: int, seed: int) -> list[tuple]:
    """``count`` unfinished positions after seeded random openings of 4..40 moves."""
    rng, found = random.Random(seed), []
    while len(found) < count:
        pos = engine.from_board([0] * 81, 1)
        for _ in range(rng.randint(4, 40)):
            pos = engine.play(pos, rng.choice(engine.moves(pos)))
            if engine.result(pos) != ONGOING:
                break
        if engine.result(pos) == ONGOING:
            found.append(pos)
    return found


def cpu_per_search(search, boards: list[tuple]) -> float:
    """Mean process CPU seconds of one search over ``boards`` (the root masks included, as the robot runs it)."""
    started = time.process_time()
    for index, pos in enumerate(boards):
        search.search(pos, search.engine.moves(pos), random.Random(index))
    return (time.process_time() - started) / len(boards)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", nargs="+", help="Ultimate checkpoint.pt files written by ncbot train")
    parser.add_argument("--value", help="value.pt written by ncbot train-value (same free-move rule); default: "
                                        "the search's own leaves (Q-value + random playout)")
    parser.add_argument("--budgets", type=int, nargs="+", default=[1600, 3200, 4000, 4800])
    parser.add_argument("--positions", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    rows, boards = [], None
    for number, checkpoint in enumerate(args.checkpoints):
        config, greedy = load_agent(checkpoint)
        name = f"#{number} " if len(args.checkpoints) > 1 else ""
        numpy_reads = guided_search(config, greedy, args.budgets[0], value=args.value)
        boards = boards or positions(numpy_reads.engine, args.positions, args.seed)
        rows += [(f"{name}numpy", numpy_reads, budget) for budget in args.budgets]
        if number == 0:
            torch_reads = guided_search(config, greedy, args.budgets[0], value=args.value)
            torch_reads._reader = None  # the nn.Module path every reader falls back to
            if args.value is not None:
                torch_reads.evaluator._reader = None
            rows.insert(1, ("torch", torch_reads, args.budgets[0]))
        if len(args.checkpoints) > 1:
            print(f"#{number}: {checkpoint} ({numpy_reads.features.n_features} features)")
    print(f"{'reads':<16} {'simulations':>11} {'CPU s/decision':>15} {'sims/CPU s':>11} {'fits 0.2 s':>10}")
    for reads, search, budget in rows:
        search.simulations = budget
        seconds = cpu_per_search(search, boards)
        print(f"{reads + ' reads':<16} {budget:>11} {seconds:>15.3f} {budget / seconds:>11.0f} "
              f"{'yes' if seconds <= BUDGET_SECONDS else 'no':>10}", flush=True)


if __name__ == "__main__":
    main()
