"""`ncbot ablate` / `ncbot reproduce`'s runner: the planned runs on a backend (local, ray, slurm), lost tries retried.

Every backend runs tries of runs (pipelines/grid/attempt.py) and reports each one's `Outcome` to one `Ledger`, which
decides: a try that died (its `ncbot train`, its worker or its node killed, a Slurm job preempted past its requeues)
is tried again, from the run's last periodic checkpoint, up to ``retries`` more times; a try that failed on ncbot's
own error (a bad config, a bug: the same on a retry) is not. The ledger also keeps the grid's progress on stderr
(runs done / running / failed / retried, with an ETA) and its driver record (RUNS/grid-driver.json) for `--status`
(pipelines/grid/status.py). The exit code of the commands is 0 only when every planned run finished.
"""
from __future__ import annotations

import json
import os
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ncbot.pipelines.grid import attempts
from ncbot.pipelines.grid.attempt import Outcome

BACKENDS = ("local", "ray", "slurm")
# Why 3: a lost node or a preempted worker is rare, and each try resumes from the run's last periodic checkpoint, so a
# retry costs at most one checkpoint interval; a run killed four times in a row is killing itself (e.g. the OOM
# killer: its replay buffer is larger than the node's memory), and more tries would only waste the cluster's time.
# It is also Ray's own default for a task's retries.
DEFAULT_RETRIES = 3
DRIVER_NAME = "grid-driver.json"


@dataclass(frozen=True)
class Cluster:
    """Where and how the grid's runs execute (the commands' --backend, --workers, --retries and their options)."""

    backend: str = "local"
    workers: int = 2
    retries: int = DEFAULT_RETRIES
    address: str | None = None  # ray: a running head's HOST:PORT; None starts a local instance
    gpus_per_run: float = 1.0  # ray / slurm: GPUs of a CUDA run
    partition: str | None = None  # slurm
    time_limit: str | None = None  # slurm: a job's wall-time limit, [D-]HH:MM:SS or minutes
    sbatch: tuple[str, ...] = ()  # slurm: extra KEY=VALUE sbatch options
    slurm_cluster: str = "slurm"  # slurm: submitit's executor ("local" runs the jobs as local processes: tests)

    def check(self) -> None:
        """One-line ValueError for a backend, worker count, retry limit or option that cannot run."""
        from ncbot.pipelines.extras import require

        if self.backend not in BACKENDS:
            raise ValueError(f"unknown backend {self.backend!r}; expected one of {', '.join(BACKENDS)}")
        if self.address is not None and self.backend != "ray":
            raise ValueError(f"--address {self.address} needs --backend ray (it is the Ray cluster's HOST:PORT)")
        slurm_options = [name for name, value in (("--partition", self.partition), ("--time", self.time_limit),
                                                  ("--sbatch", self.sbatch)) if value]
        if slurm_options and self.backend != "slurm":
            raise ValueError(f"{slurm_options[0]} needs --backend slurm (it is a Slurm job option)")
        if not 0 < self.workers <= 4096:
            raise ValueError(f"--workers must be a positive number of parallel runs (at most 4096), got {self.workers}")
        if not 0 <= self.retries <= 100:
            raise ValueError(f"--retries must be 0 to 100 tries again per run, got {self.retries}")
        if self.backend == "ray":
            require("ray", "ray", what="--backend ray")
        if self.backend == "slurm":
            from ncbot.pipelines.grid.slurm_backend import check_slurm_options

            require("slurm", "submitit", what="--backend slurm")
            check_slurm_options(self)


@dataclass
class Ledger:
    """Every try's outcome for one grid: retries, what failed, the progress line and the driver record."""

    todo: list[Any]
    cluster: Cluster
    runs_dir: Path
    desc: str = "ablate"
    tries: dict[str, int] = field(default_factory=dict)
    retried: dict[str, list[str]] = field(default_factory=dict)  # run -> why each earlier try died
    finished: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)  # run -> why (its last try)
    held: list[str] = field(default_factory=list)
    running: int = 0

    def __post_init__(self) -> None:
        from ncbot.pipelines.progress import progress_bar

        self._lock = threading.Lock()
        self._started = time.time()
        self.bar = progress_bar(total=len(self.todo), unit="run", desc=self.desc)
        self._stop_beat = threading.Event()
        self._beat = threading.Thread(target=self._beat_driver, daemon=True)
        self._write_driver(ended=None)
        self._beat.start()

    def next_try(self, run: Any) -> int:
        """The number of the try that starts now (1, then 2, ... for each retry); counts it as running."""
        with self._lock:
            self.tries[run.name] = self.tries.get(run.name, 0) + 1
            self.running += 1
            self._show()
            return self.tries[run.name]

    def settle(self, run: Any, outcome: Outcome) -> bool:
        """Record how the run's current try ended; True when the backend should try it again."""
        with self._lock:
            self.running -= 1
            number = self.tries.get(run.name, 1)
            again = outcome.kind == "died" and number <= self.cluster.retries
            self._record_end(run, outcome, number)
            if outcome.kind == "died":
                self.retried.setdefault(run.name, []).append(outcome.why)
                if not again:
                    self.failed[run.name] = (f"{outcome.why}; gave up after {number} tries "
                                             f"(--retries {self.cluster.retries})")
            elif outcome.kind in ("failed", "stopped"):
                self.failed[run.name] = outcome.why
            elif outcome.kind == "held":
                self.held.append(run.name)
            else:
                self.finished.append(run.name)
            if not again:
                self.bar.update(1)
            self._show()
            return again

    def _record_end(self, run: Any, outcome: Outcome, number: int) -> None:
        """The try's end in RUN/grid-attempts.json: always for a try that died or failed (a task lost with its node
        never wrote its start), for one that finished only where it recorded its start (not one that found the run
        finished by another process)."""
        last = (attempts.read_attempts(run.run_dir) or [{}])[-1]
        started_here = last.get("try") == number and last.get("outcome") == "running"
        if outcome.kind in ("died", "failed") or (outcome.kind in ("finished", "stopped") and started_here):
            attempts.end_attempt(run.run_dir, outcome.kind, outcome.why, try_number=number,
                                 backend=self.cluster.backend)

    def _show(self) -> None:
        parts = [f"{self.running} running"]
        if self.failed:
            parts.append(f"{len(self.failed)} failed")
        if self.retried:
            parts.append(f"{sum(len(whys) for whys in self.retried.values())} retried")
        self.bar.set_postfix_str(", ".join(parts))

    def close(self) -> None:
        self._stop_beat.set()
        self._write_driver(ended=time.time())
        self.bar.close()

    def _write_driver(self, ended: float | None) -> None:
        """RUNS/grid-driver.json: which process drives the grid, on which backend, whether it still runs."""
        from ncbot.fileio import atomic_write_text

        record = {"host": socket.gethostname(), "pid": os.getpid(), "backend": self.cluster.backend,
                  "workers": self.cluster.workers, "retries": self.cluster.retries, "runs": len(self.todo),
                  "started": self._started, "ended": ended}
        try:
            self.runs_dir.mkdir(parents=True, exist_ok=True)
            atomic_write_text(json.dumps(record) + "\n", self.runs_dir / DRIVER_NAME)
        except OSError:
            pass  # the record is for --status; a runs folder briefly away must not stop the grid

    def _beat_driver(self) -> None:
        while not self._stop_beat.wait(attempts.HEARTBEAT_S):
            attempts.touch(self.runs_dir / DRIVER_NAME)

    def summary(self) -> dict[str, Any]:
        """The grid's counts and the runs that failed or were retried, with why (a Slurm requeue, done by Slurm and
        submitit inside the job, is read back from the run's tries)."""
        retried = {name: list(whys) for name, whys in self.retried.items()}
        tries = dict(self.tries)
        for run in self.todo:
            for entry in attempts.read_attempts(run.run_dir):
                if entry.get("outcome") == "requeued" and (entry.get("ended") or 0) >= self._started:
                    retried.setdefault(run.name, []).append(str(entry.get("why", "")))
                    tries[run.name] = tries.get(run.name, 1) + 1
        return {"done": len(self.finished), "held": len(self.held), "failed": len(self.failed),
                "failed_runs": sorted(self.failed), "failures": dict(sorted(self.failed.items())),
                "held_runs": sorted(self.held),
                "retried": [{"run": name, "tries": tries.get(name, 1), "why": whys}
                            for name, whys in sorted(retried.items())],
                "runs_dir": str(self.runs_dir)}


def execute_runs(todo: list[Any], *, cluster: Cluster, runs_dir: str | Path | None = None,
                 desc: str = "ablate") -> dict[str, Any]:
    """Run the planned runs on ``cluster``'s backend, ``workers`` at a time, retrying tries that died; returns the
    ledger's summary. Ray and Slurm need every run under ``runs_dir``, the folder every node shares."""
    cluster.check()
    root = Path(runs_dir or (todo[0].run_dir.parent if todo else ".")).resolve()
    if cluster.backend != "local":
        todo = [type(run)(run.name, run.run_dir.resolve(), run.config.resolve(), list(run.overrides)) for run in todo]
        outside = [run.name for run in todo if root not in run.run_dir.parents]
        if outside:
            raise ValueError(f"run {outside[0]} is not under the runs folder {root} that the {cluster.backend} "
                             "nodes share")
    ledger = Ledger(todo, cluster, root, desc)
    try:
        if not todo:
            pass
        elif cluster.backend == "local":
            from ncbot.pipelines.grid.local_backend import run_local

            run_local(todo, ledger)
        elif cluster.backend == "ray":
            from ncbot.pipelines.grid.ray_backend import run_on_ray

            run_on_ray(todo, ledger)
        else:
            from ncbot.pipelines.grid.slurm_backend import run_on_slurm

            run_on_slurm(todo, ledger)
    finally:
        ledger.close()
    return ledger.summary()


def run_ablation(grid_path: str | Path, *, seeds: int = 3, cluster: Cluster | None = None,
                 out: str | Path | None = None, only: str | None = None,
                 overrides: list[str] | None = None) -> dict[str, Any]:
    """Run every unfinished cell of the grid (``planned_runs``: ``only`` keeps the runs whose name holds the text,
    ``overrides`` apply to every run); returns the summary, with ``skipped`` (finished before) and ``unfinished``
    (planned runs without eval.json at the end: the exit code is 0 only when there are none)."""
    from ncbot.pipelines.grid.plan import grid_runs_dir, planned_runs

    cluster = cluster or Cluster()
    cluster.check()
    planned = planned_runs(grid_path, seeds=seeds, out=out, only=only, overrides=overrides)
    todo = [run for run in planned if not run.finished]
    summary = execute_runs(todo, cluster=cluster, runs_dir=grid_runs_dir(grid_path, out))
    return {**summary, "runs_dir": str(grid_runs_dir(grid_path, out)), "skipped": len(planned) - len(todo),
            "planned": len(planned), "unfinished": sorted(run.name for run in planned if not run.finished)}
