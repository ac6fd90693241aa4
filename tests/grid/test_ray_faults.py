"""`--backend ray` loses workers and nodes and still finishes the grid: a real two-node Ray cluster on this machine
(`ray.cluster_utils.Cluster`) whose second node is removed while it trains a run; a SIGKILLed Ray worker (its
`ncbot train` dies with it) and a SIGKILLed `ncbot train`. Each lost try is retried from the shared runs folder and
named in the summary. Tiny budgets, one CPU a node; no timing is asserted.

Ray is an optional extra (`pip install 'ncbot[ray]'`): without it these tests are skipped, not failed.
"""
from __future__ import annotations

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

ray = pytest.importorskip("ray", reason="ray is an optional extra (pip install 'ncbot[ray]'); not installed here")


def in_background(todo: list[Any], runs_dir: Path, workers: int) -> tuple[threading.Thread, dict[str, Any]]:
    """The grid driven from a thread of the test (connected to the cluster already); its summary lands in the dict."""
    result: dict[str, Any] = {}

    def drive() -> None:
        try:
            result["summary"] = execute_runs(todo, cluster=Cluster("ray", workers=workers, retries=2), runs_dir=runs_dir)
        except BaseException as error:  # noqa: BLE001 - re-raised by the test
            result["error"] = error

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    return thread, result


def current_try(run_dir: Path, node: str | None = None) -> dict[str, Any] | None:
    """The run's running try once its `ncbot train` started (on ``node``, a node id's first 12 characters)."""
    tries = read_attempts(run_dir)
    last = tries[-1] if tries else None
    if last and last.get("outcome") == "running" and last.get("train_pid") and node in (None, last.get("node")):
        return last
    return None


def finish(thread: threading.Thread, result: dict[str, Any]) -> dict[str, Any]:
    thread.join(timeout=300)
    assert not thread.is_alive(), "the grid did not finish"
    if "error" in result:
        raise result["error"]
    return result["summary"]


@pytest.mark.slow
def test_a_node_removed_mid_grid_loses_its_run_to_the_other_node_and_the_grid_completes(tmp_path: Path) -> None:
    from ray.cluster_utils import Cluster as RayCluster

    todo = plan_runs(grid(tmp_path, total_frames=4096), seeds=2)
    runs_dir = (tmp_path / "runs").resolve()
    nodes = RayCluster()
    try:
        nodes.add_node(num_cpus=1, include_dashboard=False)
        second = nodes.add_node(num_cpus=1)
        ray.init(address=nodes.address, log_to_driver=False)
        thread, result = in_background(todo, runs_dir, workers=2)
        lost = wait_for(lambda: next(((run, t) for run in todo if (t := current_try(run.run_dir, second.node_id[:12]))),
                                     None), "a run training on the second node")
        run, try_there = lost
        nodes.remove_node(second, allow_graceful=False)
        summary = finish(thread, result)
    finally:
        ray.shutdown()
        nodes.shutdown()
    assert (summary["done"], summary["failed"]) == (2, 0), summary
    assert [entry["run"] for entry in summary["retried"]] == [run.name], summary["retried"]
    assert "Ray" in summary["retried"][0]["why"][0]
    tries = read_attempts(run.run_dir.resolve())
    assert [t["outcome"] for t in tries] == ["died", "finished"] and tries[1]["node"] != try_there["node"]
    wait_for(lambda: not alive(try_there["train_pid"]), "the lost node's ncbot train to be gone", timeout=30)
    assert all(run.finished for run in todo)


@pytest.mark.slow
def test_a_sigkilled_ray_worker_and_a_sigkilled_training_are_both_retried(tmp_path: Path) -> None:
    todo = plan_runs(grid(tmp_path, total_frames=4096), seeds=2)
    runs_dir = (tmp_path / "runs").resolve()
    worker_run, training_run = todo
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        thread, result = in_background(todo, runs_dir, workers=2)
        on_worker = wait_for(lambda: current_try(worker_run.run_dir), "the first run's training")
        in_training = wait_for(lambda: current_try(training_run.run_dir), "the second run's training")
        os.kill(on_worker["worker_pid"], signal.SIGKILL)  # the Ray worker: its ncbot train must go with it
        os.kill(in_training["train_pid"], signal.SIGKILL)
        wait_for(lambda: not alive(on_worker["train_pid"]), "the killed worker's ncbot train to die", timeout=30)
        summary = finish(thread, result)
    finally:
        ray.shutdown()
    assert (summary["done"], summary["failed"]) == (2, 0), summary
    why = {entry["run"]: entry["why"] for entry in summary["retried"]}
    assert why[training_run.name] == ["ncbot train killed by SIGKILL"]
    assert why[worker_run.name][0].startswith("its Ray worker died"), why
    assert all(run.finished for run in todo)
