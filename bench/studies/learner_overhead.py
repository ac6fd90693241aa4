"""CPU per training frame of the paper-faithful runs (batch 2, one update per env step), old tree against this one.

    python bench/studies/learner_overhead.py --old /tmp/base [--frames 5000] [--rounds 3]
        [--configs pipelines/configs/paper/standard_proposed_temporal.yaml pipelines/configs/paper/ultimate100_proposed_temporal.yaml]

Why: at the paper's batch of 2 an update is almost all fixed cost (TensorDict plumbing, replay sampling, optimiser,
collector), so `reproduce --budget full` pays ~12 CPU hours mostly for overhead. This bench prices that overhead as
a run pays it: each round runs `ncbot.pipelines.train.run.train` of each config once in a fresh subprocess per tree (old,
new, alternately, so a burst of load on this shared machine hits both alike) and times, in CPU seconds of that
process (`time.process_time`), the training loop after the burn-in (`collector.init_random_frames`), minus the
periodic evaluations inside it. It patches only the timing hooks (the Collector's iterator and `evaluate_agent`),
so an old tree needs no change. Prints CPU ms per frame for each tree, the median over rounds, and new / old.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[2]
CONFIGS = ["pipelines/configs/paper/standard_proposed_temporal.yaml",
           "pipelines/configs/paper/ultimate100_proposed_temporal.yaml"]

# Runs inside the subprocess, with the measured tree first on sys.path.
CHILD = r"""
import json, sys, time
import importlib
import torchrl.collectors
from ncbot.pipelines.config import load_config
try:  # the tree's layout: pipelines/train/ and pipelines/evaluate/ packages, or the flat modules of older trees
    from ncbot.pipelines.train.run import train
    evaluation = importlib.import_module("ncbot.pipelines.evaluate.games")
except ImportError:
    from ncbot.pipelines.train import train
    evaluation = importlib.import_module("ncbot.pipelines.evaluate")

config_path, frames, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
config = load_config(config_path, [f"collector.total_frames={frames}", "train.max_games=null", "eval.games=10",
                                   "eval.periodic_games=10", "logger.mcap=false", "logger.progress=false",
                                   "checkpoint.every_frames=10000000"])
eval_cpu = [0.0]
real_eval = evaluation.evaluate_agent

def timed_eval(*args, **kwargs):
    start = time.process_time()
    try:
        return real_eval(*args, **kwargs)
    finally:
        eval_cpu[0] += time.process_time() - start

evaluation.evaluate_agent = timed_eval
marks = []  # (frames collected, CPU s, eval CPU s) at every batch handed to the loop
real_iter = torchrl.collectors.Collector.__iter__

def timed_iter(self):
    seen = 0
    for batch in real_iter(self):
        marks.append((seen, time.process_time(), eval_cpu[0]))
        seen += batch.numel()
        yield batch

torchrl.collectors.Collector.__iter__ = timed_iter
real_shutdown = torchrl.collectors.Collector.shutdown

def timed_shutdown(self, *args, **kwargs):
    marks.append((frames, time.process_time(), eval_cpu[0]))
    return real_shutdown(self, *args, **kwargs)

torchrl.collectors.Collector.shutdown = timed_shutdown
train(config, out)
start = next(m for m in marks if m[0] >= config.collector.init_random_frames)
end = marks[-1]
cpu = (end[1] - start[1]) - (end[2] - start[2])
print(json.dumps({"frames": end[0] - start[0], "cpu_s": cpu}))
"""


def run_once(tree: Path, config: str, frames: int) -> float:
    """CPU ms per training frame after the burn-in, for one tree and config, in a fresh process."""
    with tempfile.TemporaryDirectory(prefix="ncbot-overhead-") as out:
        env = {**os.environ, "PYTHONPATH": str(tree)}
        result = subprocess.run([sys.executable, "-c", CHILD, str(tree / config), str(frames), out + "/run"],
                                cwd=tree, env=env, capture_output=True, text=True, check=False)
        if result.returncode != 0:
            sys.exit(f"run failed in {tree} ({config}):\n{result.stderr[-2000:]}")
        figures = json.loads(result.stdout.strip().splitlines()[-1])
    return 1000.0 * figures["cpu_s"] / figures["frames"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--old", required=True, help="a checkout of the base commit (e.g. git worktree or git archive)")
    parser.add_argument("--frames", type=int, default=5000, help="frames per run (the first 1000 are the burn-in)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--configs", nargs="+", default=CONFIGS)
    args = parser.parse_args()
    old = Path(args.old).resolve()
    if not any((old / "pipelines" / name).exists() for name in ("config.py", "config")):
        sys.exit(f"--old {args.old!r} is not an ncbot tree (no pipelines/config); expected a checkout of the base commit")
    print(f"load average at start: {os.getloadavg()[0]:.1f}; frames per run {args.frames}; rounds {args.rounds}")
    for config in args.configs:
        times: dict[str, list[float]] = {"old": [], "new": []}
        for round_ in range(args.rounds):
            for name, tree in (("old", old), ("new", HERE)) if round_ % 2 == 0 else (("new", HERE), ("old", old)):
                times[name].append(run_once(tree, config, args.frames))
            print(f"  {Path(config).stem} round {round_ + 1}: old {times['old'][-1]:.3f} ms/frame, "
                  f"new {times['new'][-1]:.3f} ms/frame", flush=True)
        old_ms, new_ms = statistics.median(times["old"]), statistics.median(times["new"])
        print(f"{Path(config).stem}: old {old_ms:.3f} CPU ms/frame, new {new_ms:.3f}, new/old {new_ms / old_ms:.3f} "
              f"(median of {args.rounds})")
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
