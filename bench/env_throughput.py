"""Env steps per second of the dialogue env vs torchrl's TicTacToeEnv (random masked actions, auto-reset).

Run: python bench/env_throughput.py [--seconds 2] [--rounds 3] [--batches 1 64 1024] [--png throughput.png]
One "env step" is one action of one game (a batch-1024 call counts 1024). Our envs build the full state
every step (features, act filter, look-ahead rewards of every action, winning actions). Every env goes
through the same public API: ``env.rand_action`` then ``env.step_and_maybe_reset``.

Why CPU time and rounds: on a shared machine the process is descheduled for a varying share of the wall
time, so rates per wall second swing 2x between runs. The table reports steps per second of this process's
CPU time (``time.process_time``, one torch thread), which other load barely changes, next to the wall-clock
rates; the envs are measured in interleaved rounds (TicTacToeEnv, 3x3, Ultimate, TicTacToeEnv, ...) and
each reports the median of its rounds. Run it on an idle machine for wall-clock numbers you quote.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import torch
from tensordict import TensorDict

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree's envs, not an installed copy
from ncbot.pipelines.progress import progress_bar  # noqa: E402


def steps_per_second(env, reset_td, seconds: float, label: str) -> tuple[float, float]:
    """Step ``env`` with random masked actions (auto-resetting finished games) for about ``seconds``.

    Returns (steps per CPU second of this process, steps per wall second)."""
    td = env.reset(reset_td)
    batch = td.batch_size[0]
    for _ in range(5):  # warm-up
        td = env.rand_action(td)
        _, td = env.step_and_maybe_reset(td)
    steps, start, cpu_start = 0, time.perf_counter(), time.process_time()
    with progress_bar(desc=label, unit="step", unit_scale=True, leave=False) as bar:
        while time.perf_counter() - start < seconds:
            td = env.rand_action(td)
            _, td = env.step_and_maybe_reset(td)
            steps += batch
            bar.update(batch)
    return steps / (time.process_time() - cpu_start), steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=2.0, help="measuring time per configuration and round")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds; each env reports its median round")
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 64, 1024])
    parser.add_argument("--png", default=None, help="also draw the figures as a bar chart into this PNG")
    args = parser.parse_args()
    torch.set_num_threads(1)
    from torchrl.envs.custom import TicTacToeEnv

    from ncbot.envs import make_env

    if args.rounds < 1 or args.seconds <= 0:
        parser.error("--rounds must be >= 1 and --seconds > 0")
    cpu_rows: list[tuple[int, float, float, float]] = []
    wall_rows: list[tuple[int, float, float, float]] = []
    for batch in args.batches:
        envs = [
            ("TicTacToeEnv", TicTacToeEnv(), TensorDict(batch_size=[batch])),
            ("standard", make_env("standard", batch_size=(batch,)), None),
            ("ultimate", make_env("ultimate", batch_size=(batch,)), None),
        ]
        rates: list[list[tuple[float, float]]] = [[] for _ in envs]
        for round_ in range(args.rounds):
            for i, (name, env, reset_td) in enumerate(envs):
                rates[i].append(steps_per_second(env, reset_td, args.seconds, f"{name} B={batch} round {round_ + 1}/{args.rounds}"))
        cpu_rows.append((batch, *(statistics.median(r[0] for r in env_rates) for env_rates in rates)))
        wall_rows.append((batch, *(statistics.median(r[1] for r in env_rates) for env_rates in rates)))
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, load average {os.getloadavg()[0]:.1f}; "
          f"env steps/s, median of {args.rounds} interleaved rounds (higher is better)")
    for title, rows in (("per CPU second of this process", cpu_rows), ("per wall-clock second", wall_rows)):
        print(title)
        print(f"{'batch':>6} {'TicTacToeEnv':>14} {'ncbot 3x3':>12} {'ncbot ultimate':>15} {'3x3/TTT':>8} {'ult/TTT':>8}")
        for batch, ref, std, ult in rows:
            print(f"{batch:>6} {ref:>14,.0f} {std:>12,.0f} {ult:>15,.0f} {std / ref:>8.2f} {ult / ref:>8.2f}")
    if args.png:
        draw(cpu_rows, args.png)


def draw(rows: list[tuple[int, float, float, float]], path: str) -> None:
    """Grouped bars of steps/s per batch size (log scale), written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    labels = ["TicTacToeEnv", "ncbot 3x3", "ncbot ultimate"]
    for i, label in enumerate(labels):
        ax.bar([k + (i - 1) * 0.27 for k in range(len(rows))], [row[1 + i] for row in rows], width=0.27, label=label)
    ax.set_xticks(range(len(rows)), [f"batch {row[0]}" for row in rows])
    ax.set_yscale("log")
    ax.set_ylabel("env steps / CPU second")
    ax.set_title("Env throughput (random masked actions, 1 thread)")
    ax.legend()
    fig.tight_layout()
    from ncbot.fileio import atomic_path

    with atomic_path(path) as temp:
        fig.savefig(temp, dpi=120, format="png")
    plt.close(fig)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
