"""`ncbot ablate --status`: where every run of a grid stands, read from the runs folder alone, whatever the backend.

Why only the folder: a grid driven from a cluster's head or a Slurm login node is looked at from another machine
that mounts the same runs folder. Each run folder says whether the run finished (eval.json), trains now (its lock is
held; its checkpoints give its pace), stopped (a checkpoint to resume from) or failed, and how many tries it took
and why the earlier ones died (RUN/grid-attempts.json, pipelines/grid/attempts.py); RUNS/grid-driver.json says which
process drives the grid (pipelines/grid/runner.py), so a run that waits its turn reads "queued".
"""
from __future__ import annotations

import json
import statistics
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ncbot.pipelines.grid import attempts
from ncbot.pipelines.grid.plan import PlannedRun, grid_runs_dir, planned_runs


@dataclass(frozen=True)
class RunStatus:
    """One run's place in the grid."""

    name: str
    state: str  # finished | training now | queued | stopped | failed | not started
    detail: str
    tries: int  # tries recorded in its folder
    died: tuple[str, ...]  # why each try that died did (retried, or given up)


@dataclass(frozen=True)
class TimeLeft:
    """The grid's training time still to run, summed over its runs (``seconds_left``)."""

    seconds: float  # over the runs with an estimate
    estimated: int  # unfinished runs with an estimate
    unknown: int  # unfinished runs whose cell has no finished seed yet (and no pace of their own)


def driver(runs_dir: Path) -> dict[str, Any] | None:
    """RUNS/grid-driver.json with ``alive`` added (not ended, heartbeat fresh), or None where no grid ran."""
    from ncbot.pipelines.grid.runner import DRIVER_NAME

    path = Path(runs_dir) / DRIVER_NAME
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        age = time.time() - path.stat().st_mtime
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict):
        return None
    return {**record, "seen_s_ago": round(age, 1),
            "alive": record.get("ended") is None and age < attempts.STALE_AFTER_S}


def run_state(run: PlannedRun, *, queued: bool = False) -> tuple[str, str]:
    """(where the run stands, a detail): finished (robot-first / robot-second task success), training now (the pid
    holding its folder, its newest checkpoint, its pace), failed (the error of its last try), stopped (the checkpoint
    it resumes from), queued (a grid driving it is alive) or not started."""
    from ncbot.pipelines.checkpoint import periodic_checkpoints, periodic_frames
    from ncbot.pipelines.run_folder import lock_holder

    if run.finished:
        try:
            report = json.loads((run.run_dir / "eval.json").read_text(encoding="utf-8"))
            return "finished", (f"task success {report['first']['task_success']:.4f} robot first, "
                                f"{report['second']['task_success']:.4f} robot second")
        except (OSError, ValueError, KeyError, TypeError):
            return "finished", "eval.json unreadable"
    found = periodic_checkpoints(run.run_dir)  # oldest first
    at = f"checkpoint at {periodic_frames(found[-1]):,} frames" if found else "no checkpoint yet"
    holder = lock_holder(run.run_dir)
    if holder is not None:
        last = (attempts.read_attempts(run.run_dir) or [{}])[-1]
        where = f" on {last['node'] or last['host']}" if last.get("train_pid") == holder and last.get("host") else ""
        return "training now", f"pid {holder if holder > 0 else '?'}{where}, {at}{_pace(run, found)}"
    last = (attempts.read_attempts(run.run_dir) or [{}])[-1]
    if last.get("outcome") == "failed":
        return "failed", str(last.get("why", ""))
    if queued:
        return "queued", f"resumes from the {at}" if found else ""
    return ("stopped", f"resumes from the {at}") if found else ("not started", "")


def _pace(run: PlannedRun, found: list[Path]) -> str:
    """", N frames/s, about H:MM:SS left" from the checkpoints the training process wrote (`checkpoint_rate`) and the
    run's collector.total_frames (an estimate: evaluations and a games cap are not foreseen); "" where either is
    missing."""
    from ncbot.pipelines.checkpoint import periodic_frames
    from ncbot.pipelines.progress import duration

    total, every = run.frame_settings()
    if not found or total is None:
        return ""
    if periodic_frames(found[-1]) >= total:
        return ", every frame trained: the final evaluation"
    pace = _rate_and_left(run, found, total, every)
    if pace is None:
        return ""
    rate, left = pace
    return f", {rate:,.0f} frames/s, about {duration(left)} left of {total:,} frames"


def _rate_and_left(run: PlannedRun, found: list[Path], total: int, every: int | None) -> tuple[float, float] | None:
    """(frames/s of the process training the run now, seconds it has left), or None before it wrote 2 checkpoints.

    The time since the newest checkpoint counts as progress at that rate, but never past the next checkpoint
    (``every``: checkpoint.every_frames of its config), which would have been written: a run that slowed down or was
    paused is not estimated as done."""
    from ncbot.pipelines.checkpoint import checkpoint_rate, periodic_frames
    from ncbot.pipelines.run_folder import lock_taken_at

    rate = checkpoint_rate(found, since=lock_taken_at(run.run_dir))
    if rate is None:
        return None
    newest = periodic_frames(found[-1])
    left = (total - newest) / rate - (time.time() - found[-1].stat().st_mtime)
    if every is not None:
        left = max(left, (total - min(total, newest + every)) / rate)
    return rate, max(0.0, left)


def seconds_left(run: PlannedRun, typical: float | None) -> float | None:
    """Training time the run still needs: its own pace while it trains, else ``typical`` (a finished seed's of its
    cell) scaled by the frames its checkpoint has left; None where neither is known."""
    from ncbot.pipelines.checkpoint import periodic_checkpoints, periodic_frames
    from ncbot.pipelines.run_folder import lock_holder

    if run.finished:
        return 0.0
    found = periodic_checkpoints(run.run_dir)
    total, every = run.frame_settings() if found else (None, None)
    if found and total:
        done = min(1.0, periodic_frames(found[-1]) / total)
        pace = _rate_and_left(run, found, total, every) if lock_holder(run.run_dir) is not None else None
        if pace is not None:
            return pace[1]
        return None if typical is None else typical * (1.0 - done)
    return typical


def grid_time_left(runs: list[PlannedRun]) -> TimeLeft:
    """What is left of the grid, in training time: each unfinished run at its own pace, or at the median training
    time of its cell's finished seeds. Seeds of one cell cost about the same; a shared machine's load does not."""
    typical: dict[str, list[float]] = {}
    for run in runs:
        if (seconds := run.wall_time()) is not None:
            typical.setdefault(run.cell, []).append(seconds)
    medians = {cell: statistics.median(times) for cell, times in typical.items()}
    seconds, estimated, unknown = 0.0, 0, 0
    for run in runs:
        if run.finished:
            continue
        left = seconds_left(run, medians.get(run.cell))
        if left is None:
            unknown += 1
        else:
            seconds, estimated = seconds + left, estimated + 1
    return TimeLeft(seconds, estimated, unknown)


def grid_status(grid_path: str | Path, *, seeds: int = 3, out: str | Path | None = None, only: str | None = None,
                overrides: list[str] | None = None) -> tuple[list[RunStatus], TimeLeft, dict[str, Any] | None]:
    """Every run's `RunStatus`, the training time left and the grid's driver record; nothing starts."""
    runs = planned_runs(grid_path, seeds=seeds, out=out, only=only, overrides=overrides)
    record = driver(grid_runs_dir(grid_path, out))
    queued = bool(record and record["alive"])
    statuses = []
    for run in runs:
        tries = attempts.read_attempts(run.run_dir)
        died = tuple(str(entry.get("why", "")) for entry in tries if entry.get("outcome") in ("died", "requeued"))
        statuses.append(RunStatus(run.name, *run_state(run, queued=queued), len(tries), died))
    return statuses, grid_time_left(runs), record


def status_lines(statuses: list[RunStatus], left: TimeLeft, record: dict[str, Any] | None, workers: int) -> list[str]:
    """The text of `--status`: a line per run, the counts, the retried runs, the driver and the time left."""
    from ncbot.pipelines.progress import duration

    width = max(len(status.name) for status in statuses)
    lines = []
    for status in statuses:
        tried = f" [try {status.tries}; died before: {'; '.join(status.died)}]" if status.died else ""
        detail = f": {status.detail}" if status.detail else ""
        lines.append(f"{status.name:<{width}}  {status.state}{detail}{tried}")
    counts = Counter(status.state for status in statuses)
    retried = [status for status in statuses if status.died]
    died = sum(len(status.died) for status in retried)
    lines.append(f"{len(statuses)} runs: " + ", ".join(f"{n} {where}" for where, n in counts.items()) +
                 (f"; {len(retried)} retried ({died} {'try' if died == 1 else 'tries'} died)" if retried else ""))
    if record is not None:
        state = (f"running, seen {record['seen_s_ago']:.0f} s ago" if record["alive"] else
                 "ended" if record.get("ended") else f"silent for {record['seen_s_ago']:.0f} s (its process is gone)")
        lines.append(f"grid driver: pid {record.get('pid')} on {record.get('host')}, backend {record.get('backend')}, "
                     f"{record.get('workers')} workers, --retries {record.get('retries')}: {state}")
    if left.estimated:
        unknown = f"; {left.unknown} more with no finished seed of their cell to go by" if left.unknown else ""
        lines.append(f"left: about {duration(left.seconds)} of training over {left.estimated} runs, about "
                     f"{duration(left.seconds / workers)} at --workers {workers} (each run at its own pace, else at "
                     f"the median of its cell's finished seeds){unknown}")
    elif left.unknown:
        lines.append(f"left: {left.unknown} runs, none with a finished seed of its cell to estimate from")
    return lines


def status_json(statuses: list[RunStatus], left: TimeLeft, record: dict[str, Any] | None,
                workers: int) -> dict[str, Any]:
    """The `--status --json` object: the same facts as `status_lines`."""
    return {"runs": [{"run": s.name, "state": s.state, "detail": s.detail, "tries": s.tries, "died": list(s.died)}
                     for s in statuses],
            "counts": dict(Counter(s.state for s in statuses)),
            "retried": [s.name for s in statuses if s.died],
            "left": {"training_s": round(left.seconds, 1), "estimated_runs": left.estimated,
                     "unknown_runs": left.unknown, "wall_s_at_workers": round(left.seconds / workers, 1),
                     "workers": workers},
            "driver": record}
