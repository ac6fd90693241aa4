"""`--backend slurm` through submitit's local executor (the same jobs as on a cluster, run as local processes): a job
signalled as Slurm signals a preempted or timed-out job (USR2) stops its training, is requeued and resumes from its
checkpoint; a job SIGKILLed (its node lost) is submitted again; both are named in the summary and the grid finishes.

submitit is an optional extra (`pip install 'ncbot[slurm]'`): without it these tests are skipped, not failed.
"""
from __future__ import annotations

import json
import os
import signal
import threading
from pathlib import Path
from typing import Any

import pytest

from ncbot.pipelines.grid.attempts import read_attempts
from ncbot.pipelines.grid.plan import plan_runs
from ncbot.pipelines.grid.runner import Cluster, execute_runs
from tests.grid.test_retries import alive, grid, wait_for

pytest.importorskip("submitit", reason="submitit is an optional extra (pip install 'ncbot[slurm]'); not installed here")


def training_try(run_dir: Path) -> dict[str, Any] | None:
    """The run's running try once its `ncbot train` wrote a periodic checkpoint."""
    from ncbot.pipelines.checkpoint import periodic_checkpoints

    tries = read_attempts(run_dir)
    last = tries[-1] if tries else None
    if last and last.get("outcome") == "running" and last.get("train_pid") and periodic_checkpoints(run_dir):
        return last
    return None


def in_background(todo: list[Any], runs_dir: Path) -> tuple[threading.Thread, dict[str, Any]]:
    """The grid submitted to submitit's local executor from a thread; its summary lands in the dict."""
    result: dict[str, Any] = {}

    def drive() -> None:
        try:
            result["summary"] = execute_runs(todo, cluster=Cluster("slurm", workers=2, slurm_cluster="local"),
                                             runs_dir=runs_dir)
        except BaseException as error:  # noqa: BLE001 - re-raised by finish
            result["error"] = error

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    return thread, result


def finish(thread: threading.Thread, result: dict[str, Any]) -> dict[str, Any]:
    thread.join(timeout=300)
    assert not thread.is_alive(), "the grid did not finish"
    if "error" in result:
        raise result["error"]
    assert (result["summary"]["done"], result["summary"]["failed"]) == (1, 0), result["summary"]
    return result["summary"]


@pytest.mark.slow
def test_a_preempted_job_is_requeued_and_resumes_from_its_checkpoint(tmp_path: Path) -> None:
    (run,) = plan_runs(grid(tmp_path, total_frames=4096), seeds=1)
    thread, result = in_background([run], tmp_path / "runs")
    first = wait_for(lambda: training_try(run.run_dir), "the job's first checkpoint", timeout=180)
    os.kill(first["worker_pid"], signal.SIGUSR2)  # what Slurm sends before a time limit or on preemption
    summary = finish(thread, result)
    assert summary["retried"] == [{"run": run.name, "tries": 2, "why": [
        "preempted or at its time limit: requeued by Slurm, resumes from its last checkpoint"]}]
    requeued = read_attempts(run.run_dir)
    assert [entry["outcome"] for entry in requeued] == ["requeued", "finished"]
    assert requeued[1]["from_frames"] > 0 and requeued[1]["node"].startswith("job ")  # resumed from its checkpoint
    assert (tmp_path / "runs" / ".submitit").is_dir()  # submitit's files live in the shared runs folder
    assert json.loads((tmp_path / "runs" / "grid-driver.json").read_text())["backend"] == "slurm"


@pytest.mark.slow
def test_a_job_lost_with_its_node_is_submitted_again_and_its_training_dies_with_it(tmp_path: Path) -> None:
    (run,) = plan_runs(grid(tmp_path, total_frames=4096), seeds=1)
    thread, result = in_background([run], tmp_path / "runs")
    first = wait_for(lambda: training_try(run.run_dir), "the job's first checkpoint", timeout=180)
    os.kill(first["worker_pid"], signal.SIGKILL)  # the job's node gone
    wait_for(lambda: not alive(first["train_pid"]), "the lost job's ncbot train to die with it", timeout=30)
    summary = finish(thread, result)
    (entry,) = summary["retried"]
    assert entry["why"][0].startswith("Slurm job") and "without a result" in entry["why"][0], entry
    assert [attempt["outcome"] for attempt in read_attempts(run.run_dir)] == ["died", "finished"]
