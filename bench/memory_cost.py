"""CPU cost per training frame with and without `agent.memory` (docs/memory.md), on the run's own parts.

    python bench/memory_cost.py [--config pipelines/configs/default.yaml] [--rounds 3] [--batches 4]
                                [--memory none gru] [--reference-unroll] [override ...]

For each memory setting the training parts are built as `ncbot train` builds them (`ncbot.pipelines.train.build`), the
buffer is filled past the burn-in, then each round times, in CPU seconds of this process (`time.process_time`,
robust to a shared machine), `--batches` collected batches (collect + store) and `optim.updates_per_batch`
updates after each; the settings take turns and the median round is reported as CPU ms per frame.
`--reference-unroll` adds, for each recurrent setting, a twin whose loss unrolls its slices through TorchRL's
recurrent mode (`modules.networks.recurrent.unroll_in_recurrent_mode`, the same numbers) instead of on the tensors.
"""
from __future__ import annotations

import argparse
import logging
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree, not an installed copy


def _parts(config_path: str, overrides: list[str], memory: str):
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.build import assemble, check_run, frames_per_batch, make_collector

    config = load_config(config_path, [*overrides, f"agent.memory={memory}", "logger.mcap=false"])
    parts = assemble(config, check_run(config), config.train.seed)
    collector = make_collector(parts.env, parts.agent.explore, frames_per_batch(config), -1)
    return config, parts, iter(collector)


def _reference_parts(config_path: str, overrides: list[str], memory: str):
    """The parts of `memory` with the loss's unroll swapped for TorchRL's recurrent mode (same numbers, tested)."""
    from ncbot.modules.networks.recurrent import unroll_in_recurrent_mode

    config, parts, batches = _parts(config_path, overrides, memory)
    loss = parts.learner.objective
    loss._unroll = lambda observations, states: unroll_in_recurrent_mode(loss.value_network, observations, states)
    return config, parts, batches


def _store(config, parts, batch, frames: int) -> None:
    """What the training loop stores of a batch: its transitions, with the recurrent replay hook's keys."""
    from ncbot.pipelines.train.hooks import RecurrentReplay

    rows = parts.transitions(batch)
    for hook in parts.hooks:
        if isinstance(hook, RecurrentReplay):
            rows = hook.rows(batch, rows, frames)
    parts.buffer.extend(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="pipelines/configs/default.yaml")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--batches", type=int, default=4)
    parser.add_argument("--memory", nargs="+", default=["none", "gru"])
    parser.add_argument("--reference-unroll", action="store_true",
                        help="also time each recurrent setting with the loss unrolled in TorchRL's recurrent mode")
    parser.add_argument("overrides", nargs="*")
    args = parser.parse_args()
    logging.getLogger("torchrl").setLevel(logging.WARNING)
    torch.set_num_threads(1)
    torch.manual_seed(0)
    runs = {memory: _parts(args.config, args.overrides, memory) for memory in args.memory}
    if args.reference_unroll:
        for memory in [memory for memory in args.memory if memory != "none"]:
            runs[f"{memory}, recurrent-mode unroll"] = _reference_parts(args.config, args.overrides, memory)
    frames = {memory: 0 for memory in runs}
    for memory, (config, parts, batches) in runs.items():  # past the burn-in, with epsilon as early in training
        while len(parts.buffer) < max(config.collector.init_random_frames, 4 * config.buffer.batch_size):
            batch = next(batches)
            _store(config, parts, batch, frames[memory])
            frames[memory] += batch.numel()
    rounds: dict[str, list[tuple[float, float, int]]] = {memory: [] for memory in runs}
    for _ in range(args.rounds):
        for memory, (config, parts, batches) in runs.items():
            collect = learn = 0.0
            counted = 0
            for _ in range(args.batches):
                start = time.process_time()
                batch = next(batches)
                _store(config, parts, batch, frames[memory])
                middle = time.process_time()
                parts.learner.update_many(parts.buffer, config.optim.updates_per_batch)
                collect, learn = collect + middle - start, learn + time.process_time() - middle
                frames[memory] += batch.numel()
                counted += batch.numel()
            rounds[memory].append((collect, learn, counted))
    print("| agent.memory | collect + store, CPU ms/frame | updates, CPU ms/frame | total CPU ms/frame |")
    print("|---|---|---|---|")
    for memory, values in rounds.items():
        collect = statistics.median(c / n * 1e3 for c, _, n in values)
        learn = statistics.median(u / n * 1e3 for _, u, n in values)
        total = statistics.median((c + u) / n * 1e3 for c, u, n in values)
        print(f"| {memory} | {collect:.3f} | {learn:.3f} | {total:.3f} |")


if __name__ == "__main__":
    main()
