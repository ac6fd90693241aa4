"""`--backend slurm`: the grid's runs as Slurm jobs through submitit, one array task per run.

Why submitit: it writes the sbatch script, pickles the call into the runs folder (RUNS/.submitit/, shared like the
runs), and implements Slurm's checkpointing protocol: shortly before a job's time limit, or when it is preempted,
Slurm signals it (USR2), submitit calls the job's `checkpoint` and requeues it. Here `checkpoint` stops the run's
`ncbot train` (SIGTERM: it exits resumable, its lock released) and requeues the same try, which resumes from the
run's last periodic checkpoint; every requeue is written in the run's tries (RUN/grid-attempts.json, outcome
"requeued"). A job that ends without a result (its node failed, the OOM killer, a job killed) is a try that died:
the grid's ledger submits it again, up to --retries times.

Resources come from each run (its `train.num_threads` as CPUs per task, a GPU when its `train.device` is CUDA):
runs that ask for the same go in one job array (at most --workers of its tasks at once); --partition, --time and
--sbatch KEY=VALUE go to every job. submitit's local executor runs the same jobs as local processes (the tests).
"""
from __future__ import annotations

import math
import re
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

from ncbot.pipelines.grid import attempts
from ncbot.pipelines.grid.attempt import Children, Outcome, run_attempt

# a job's wall-time limit without --time: about three times the longest paper-protocol run measured (Ultimate (100):
# 2,320 s of training with two runs sharing two cores, docs/reproduction.md), within most partitions' limits; a run
# past it is requeued and resumes from its checkpoint
DEFAULT_TIME = "2:00:00"
STOP_GRACE_S = 45.0  # within submitit's signal delay (90 s before the limit) for `ncbot train` to exit resumable
POLL_S = 2.0
_TIME = re.compile(r"^(?:(\d+)-)?(\d+):(\d{2}):(\d{2})$")


def time_minutes(text: str) -> int:
    """A Slurm time limit (MINUTES, HH:MM:SS or D-HH:MM:SS) in whole minutes; ValueError naming the forms."""
    text = text.strip()
    if text.isdigit() and int(text) > 0:
        return int(text)
    match = _TIME.match(text)
    if match is None or int(match.group(3)) >= 60 or int(match.group(4)) >= 60:
        raise ValueError(f"--time {text!r} is not a Slurm time limit; expected MINUTES, HH:MM:SS or D-HH:MM:SS "
                         "(e.g. 90, 2:00:00, 1-12:00:00)")
    days, hours, minutes, seconds = (int(part or 0) for part in match.groups())
    total = math.ceil(((days * 24 + hours) * 60 + minutes) + seconds / 60)
    if total <= 0:
        raise ValueError(f"--time {text!r} must be longer than zero")
    return total


def sbatch_options(pairs: tuple[str, ...]) -> dict[str, str]:
    """--sbatch KEY=VALUE options (e.g. mem=8G, account=myproj, qos=long) as sbatch's long options."""
    options = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key = key.strip().removeprefix("--")
        if not sep or not re.fullmatch(r"[a-z][a-z0-9-]*", key) or not value.strip():
            raise ValueError(f"--sbatch {pair!r} is not KEY=VALUE of an sbatch option (e.g. mem=8G, account=myproj)")
        options[key.replace("-", "_")] = value.strip()
    return options


def check_slurm_options(cluster: Any) -> None:
    """One-line ValueError for a bad --time or --sbatch, before anything is submitted."""
    time_minutes(cluster.time_limit or DEFAULT_TIME)
    sbatch_options(cluster.sbatch)
    if cluster.slurm_cluster not in ("slurm", "local"):
        raise ValueError(f"unknown submitit executor {cluster.slurm_cluster!r}; expected slurm or local")


class SlurmTry:
    """The job's callable: one try of one run (pipelines/grid/attempt.py); checkpointable, so Slurm's time limit
    and preemption requeue it (module doc)."""

    def __init__(self) -> None:
        self._children: Children | None = None

    def __call__(self, run: Any, try_number: int) -> Outcome:
        import submitit

        environment = submitit.JobEnvironment()
        self._children = Children()
        return run_attempt(run, backend="slurm", try_number=try_number, children=self._children,
                           node=f"job {environment.job_id} on {environment.hostname}")

    def checkpoint(self, run: Any, try_number: int) -> Any:
        """Preempted or at its time limit: stop the training (resumable) and requeue this try."""
        import submitit

        if self._children is not None:
            self._children.stop(grace_s=STOP_GRACE_S)
        why = "preempted or at its time limit: requeued by Slurm, resumes from its last checkpoint"
        attempts.end_attempt(run.run_dir, "requeued", why, try_number=try_number, backend="slurm")
        return submitit.helpers.DelayedSubmission(SlurmTry(), run, try_number)


def job_outcome(job: Any, run: Any) -> Outcome:
    """A finished job's `Outcome`: the try's own, or died (no result: node failure, killed, timed out too often)."""
    from submitit.core.utils import FailedJobError, UncompletedJobError

    try:
        return job.result()
    except FailedJobError as error:
        if "has not produced any output" in str(error) or "killed" in str(error).lower():
            return Outcome(run.name, "died", f"Slurm job {job.job_id} ended {job.state} without a result")
        lines = [line.strip() for line in str(error).splitlines() if line.strip() and not line.startswith("-")]
        error_line = next((line for line in reversed(lines) if "Error" in line), lines[-1] if lines else "")
        return Outcome(run.name, "failed", f"error in Slurm job {job.job_id}: {error_line[:200]}")
    except UncompletedJobError:
        if str(job.state).upper().startswith("CANCELLED"):
            return Outcome(run.name, "failed", f"Slurm job {job.job_id} was cancelled")
        return Outcome(run.name, "died", f"Slurm job {job.job_id} ended {job.state} without a result")


def _executor(ledger: Any, threads: int, gpus: int) -> Any:
    """A submitit executor for runs asking for ``threads`` CPUs and ``gpus`` GPUs, with the grid's job options."""
    import submitit

    cluster = ledger.cluster
    executor = submitit.AutoExecutor(folder=Path(ledger.runs_dir) / ".submitit" / "%j", cluster=cluster.slurm_cluster)
    parameters: dict[str, Any] = {"name": "ncbot-grid", "timeout_min": time_minutes(cluster.time_limit or DEFAULT_TIME),
                                  "cpus_per_task": threads, "gpus_per_node": gpus, "tasks_per_node": 1, "nodes": 1}
    if cluster.slurm_cluster == "slurm":
        parameters["slurm_array_parallelism"] = cluster.workers
        if cluster.partition:
            parameters["slurm_partition"] = cluster.partition
        if cluster.sbatch:
            parameters["slurm_additional_parameters"] = sbatch_options(cluster.sbatch)
    executor.update_parameters(**parameters)
    return executor


def run_on_slurm(todo: list[Any], ledger: Any) -> None:
    """Submit every planned run (one array per resource request), wait for the jobs and submit again each try that
    died while the ledger says so. Ctrl-C or SIGTERM cancels the grid's jobs (each run stays resumable)."""
    groups: dict[tuple[int, int], list[Any]] = defaultdict(list)
    for run in todo:
        _, threads, device = run.settings()
        gpus = math.ceil(ledger.cluster.gpus_per_run) if device.startswith("cuda") else 0
        groups[(threads, gpus)].append(run)
    executors = {key: _executor(ledger, *key) for key in groups}
    pending: dict[Any, tuple[Any, tuple[int, int]]] = {}
    try:
        for key, runs in groups.items():
            tries = [ledger.next_try(run) for run in runs]
            for job, run in zip(executors[key].map_array(SlurmTry(), runs, tries), runs):
                pending[job] = (run, key)
        while pending:
            time.sleep(POLL_S)
            for job in [job for job in pending if job.done()]:
                run, key = pending.pop(job)
                if ledger.settle(run, job_outcome(job, run)):
                    pending[executors[key].submit(SlurmTry(), run, ledger.next_try(run))] = (run, key)
    except BaseException:
        for job in pending:
            job.cancel(check=False)
        raise
