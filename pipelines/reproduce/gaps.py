"""`python -m ncbot.pipelines.reproduce.gaps run | status | report`: the runs of "The remaining gaps"
(docs/reproduction.md) and their verdicts.

`run` trains every run of `gaps_plan.plan()` in order, one at a time, each as an `ncbot train` process (finished runs
skipped, a stopped one resumed from its last checkpoint with `--resume`), then the evaluations its tests read, each
an `ncbot eval` process whose output is kept in the run folder (done ones skipped). `status` says how far the queue is
without reading any result. `report` writes the verdicts (`ncbot.pipelines.reproduce.gaps_report`).

Why processes through the CLI: the queue runs for many hours on whatever code it was started with; calling the
commands users call keeps it independent of internal modules, and each run is its own crash domain.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.reproduce.gaps_plan import (
    ACTS_GAMES, ACTS_SEED, CHECKPOINT_GAMES, FINAL_EVAL_SEED_OFFSET, ActsEval, CheckpointEval, GapRun, plan,
)

NCBOT = (sys.executable, "-m", "ncbot")


def periodic(folder: Path) -> list[Path]:
    """The run's kept periodic checkpoints, oldest first."""
    return sorted((folder / "checkpoints").glob("step-*.pt"))


def checkpoint_path(folder: Path, frames: int | None) -> Path:
    return folder / "checkpoint.pt" if frames is None else folder / "checkpoints" / f"step-{frames:09d}.pt"


def train_command(run: GapRun, folder: Path) -> list[str]:
    if periodic(folder):
        return [*NCBOT, "train", "--resume", str(folder), "--no-progress"]
    return [*NCBOT, "train", str(run.config), *run.overrides, "--seed", str(run.seed), "--out", str(folder),
            "--no-progress", "--overwrite"]  # no checkpoint yet: start it again


def evaluation_jobs(run: GapRun, folder: Path) -> list[tuple[list[str], Path]]:
    """(command, output) of every evaluation of the run; the output is the JSON the command prints (acts: the
    metrics of the logged games, beside their MCAP log)."""
    jobs = []
    for evaluation in run.evaluations:
        if isinstance(evaluation, CheckpointEval):
            found = [checkpoint_path(folder, evaluation.frames)] if evaluation.frames else periodic(folder)
            seats = ("robot", "human") if evaluation.both_seats else ("robot",)
            for checkpoint in found:
                for first in seats:
                    seat = "first" if first == "robot" else "second"
                    out = folder / "checkpoint_evals" / f"{checkpoint.stem}-{seat}.json"
                    jobs.append(([*NCBOT, "eval", str(checkpoint), "--games", str(CHECKPOINT_GAMES), "--first", first,
                                  "--seed", str(run.seed + FINAL_EVAL_SEED_OFFSET), "--json", "--no-progress"], out))
        elif isinstance(evaluation, ActsEval):
            logs = folder / ("acts" if evaluation.frames is None else f"acts-step-{evaluation.frames:09d}")
            jobs.append(([*NCBOT, "eval", str(checkpoint_path(folder, evaluation.frames)), "--games", str(ACTS_GAMES),
                          "--first", "robot", "--seed", str(ACTS_SEED), "--out", str(logs), "--json", "--no-progress"],
                         logs / "metrics.json"))
    return jobs


def _log(message: str) -> None:
    print(f"{time.strftime('%Y-%m-%d %H:%M:%S')} {message}", flush=True)


def run_queue(runs: Path) -> int:
    """Train and evaluate every planned run not done yet; returns the number of failed steps (0: all done)."""
    queue, failures = plan(), 0
    for index, run in enumerate(queue, 1):
        folder = run.folder(runs)
        if not (folder / "eval.json").is_file():
            folder.mkdir(parents=True, exist_ok=True)
            _log(f"[{index}/{len(queue)}] {run.name}: training")
            started = time.monotonic()
            with open(folder / "train.log", "a") as log:
                code = subprocess.call(train_command(run, folder), stdout=log, stderr=subprocess.STDOUT)
            if code != 0:
                failures += 1
                _log(f"[{index}/{len(queue)}] {run.name}: training exited {code} (see {folder / 'train.log'})")
                continue
            _log(f"[{index}/{len(queue)}] {run.name}: trained in {time.monotonic() - started:.0f} s")
        for command, out in evaluation_jobs(run, folder):
            if out.is_file():
                continue
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                failures += 1
                _log(f"{run.name}: `{' '.join(command[1:])}` exited {done.returncode}: {done.stderr.strip()[-300:]}")
                continue
            out.parent.mkdir(parents=True, exist_ok=True)
            result = json.loads(done.stdout.strip().splitlines()[-1])
            atomic_write_text(json.dumps({"command": "ncbot " + " ".join(command[3:]), **result}, indent=2) + "\n", out)
        _log(f"[{index}/{len(queue)}] {run.name}: evaluations done")
    return failures


def queue_status(runs: Path) -> list[str]:
    """One line per planned run: trained or not, and how many of its evaluations are written (no result is read)."""
    lines = []
    for run in plan():
        folder = run.folder(runs)
        jobs = evaluation_jobs(run, folder)
        state = "trained" if (folder / "eval.json").is_file() else (
            f"checkpoint {periodic(folder)[-1].stem}" if periodic(folder) else "not started")
        lines.append(f"{run.name}: {state}; evaluations {sum(out.is_file() for _, out in jobs)}/{len(jobs)}")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ncbot.pipelines.reproduce.gaps", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("part", choices=("run", "status", "report"))
    parser.add_argument("--runs", default="runs/gaps", help="the queue's runs folder")
    parser.add_argument("--out", default="results/gaps", help="report: the folder for the verdicts")
    args = parser.parse_args(argv)
    runs = Path(args.runs)
    if args.part == "run":
        failures = run_queue(runs)
        _log(f"queue finished, {failures} failed step(s)" if failures else "queue finished")
        return 1 if failures else 0
    if args.part == "status":
        print("\n".join(queue_status(runs)))
        return 0
    from ncbot.pipelines.reproduce.gaps_report import write_gaps_report

    for path in write_gaps_report(runs, Path(args.out)):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
