"""A grid survives its runs' deaths on the local backend: a SIGKILLed `ncbot train` is tried again from its last
checkpoint and named in the summary; a SIGKILLed grid takes its `ncbot train` along (no orphan holds the folder); a
lock whose holder on another machine stopped its heartbeat is broken; a run that fails on its own error is not
retried and the exit code says the grid is unfinished. Real processes, tiny budgets."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import pytest
import yaml

from ncbot.pipelines.checkpoint import periodic_checkpoints
from ncbot.pipelines.grid.attempt import Outcome, exit_outcome
from ncbot.pipelines.grid.attempts import read_attempts
from tests.learning_helpers import write_tiny_config

RUN = Path("fast/standard/proposed-notemporal/seed0")


def grid(folder: Path, total_frames: int = 8192) -> Path:
    """A one-run grid (two with --seeds 2) whose runs checkpoint every 256 frames."""
    base = write_tiny_config(folder, collector={"total_frames": total_frames}, train={"eval_every_frames": 4096},
                             checkpoint={"every_frames": 256, "keep": 2})
    path = folder / "grid.yaml"
    path.write_text(yaml.safe_dump({"runs_dir": str(folder / "runs"), "suites": {"fast": {"standard": {"config": base.name}}},
                                    "grid": {"suite": ["fast"], "game": ["standard"], "agent": ["proposed"],
                                             "temporal": [False]}}))
    return path


def wait_for(condition: Callable[[], object], what: str, timeout: float = 120) -> object:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def training_pid(run_dir: Path) -> int | None:
    """The pid of the `ncbot train` of the run's current try, once it wrote a periodic checkpoint."""
    tries = read_attempts(run_dir)
    if tries and tries[-1].get("outcome") == "running" and tries[-1].get("train_pid") and periodic_checkpoints(run_dir):
        return tries[-1]["train_pid"]
    return None


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}").is_dir() and "Z" not in Path(f"/proc/{pid}/stat").read_text().split(")")[-1][:3]


def ablate(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "ncbot", "ablate", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def test_exit_codes_of_ncbot_train_read_as_outcomes(tmp_path: Path) -> None:
    (tmp_path / "train.log").write_text("...\nncbot: error: run folder 'x' is in use by another ncbot train (pid 7)\n")
    assert exit_outcome("r", -9, tmp_path) == Outcome("r", "died", "ncbot train killed by SIGKILL")
    assert exit_outcome("r", 143, tmp_path) == Outcome("r", "died", "ncbot train killed by SIGTERM")
    assert exit_outcome("r", 2, tmp_path).kind == "held"
    (tmp_path / "train.log").write_text("ncbot: error: checkpoint 'x' is corrupt\n")
    assert exit_outcome("r", 2, tmp_path) == Outcome("r", "failed", "ncbot train exited 2: ncbot: error: checkpoint 'x' is corrupt")
    assert exit_outcome("r", 0, tmp_path) == Outcome("r", "failed", "ncbot train exited 0 without writing eval.json")


@pytest.mark.slow
def test_a_sigkilled_training_is_retried_from_its_checkpoint_and_named_in_the_summary(tmp_path: Path) -> None:
    run_dir = tmp_path / "runs" / RUN
    process = ablate(str(grid(tmp_path)), "--seeds", "1", "--workers", "1", "--json")
    os.kill(wait_for(lambda: training_pid(run_dir), "the first checkpoint"), signal.SIGKILL)
    out, err = process.communicate(timeout=240)
    assert process.returncode == 0, err[-3000:]
    summary = json.loads(out)
    assert (summary["done"], summary["failed"], summary["unfinished"]) == (1, 0, [])
    assert summary["retried"] == [{"run": str(RUN), "tries": 2, "why": ["ncbot train killed by SIGKILL"]}]
    first, second = read_attempts(run_dir)
    assert (first["outcome"], second["outcome"], second["try"]) == ("died", "finished", 2)
    assert second["from_frames"] > 0  # resumed from the checkpoint, not started again
    assert "retried" in err and "1 retried" in err  # the progress on stderr counts it


@pytest.mark.slow
def test_a_killed_grid_takes_its_training_along_and_the_next_grid_resumes_the_run(tmp_path: Path) -> None:
    run_dir = tmp_path / "runs" / RUN
    path = grid(tmp_path, total_frames=40_960)
    process = ablate(str(path), "--seeds", "1", "--workers", "1")
    child = wait_for(lambda: training_pid(run_dir), "the first checkpoint")
    os.kill(process.pid, signal.SIGKILL)  # the grid's process dies as a worker would, without a word
    process.communicate(timeout=60)
    wait_for(lambda: not alive(child), "the orphaned ncbot train to die with its parent", timeout=30)
    from ncbot.pipelines.run_folder import lock_holder

    # nothing holds the folder once the training's process has exited (the kernel drops its flock on exit, which a
    # loaded machine may finish a moment after the pid stops answering): the next grid can take it
    wait_for(lambda: lock_holder(run_dir) is None, "the run folder's lock to be free", timeout=30)
    again = ablate(str(path), "--seeds", "1", "--workers", "1", "collector.total_frames=2048", "--json")
    out, err = again.communicate(timeout=240)
    assert again.returncode == 0, err[-3000:]
    assert json.loads(out)["done"] == 1
    assert read_attempts(run_dir)[-1]["from_frames"] > 0


@pytest.mark.slow
def test_a_lock_whose_holder_stopped_its_heartbeat_on_another_machine_is_broken(tmp_path: Path) -> None:
    """The folder's lock is held (as a lock server keeps a lost node's), but the try that holds it wrote its last
    heartbeat long ago from another machine: a retry moves the lock aside and trains; while the heartbeat is fresh
    the run is held by its holder."""
    from ncbot.pipelines.grid.attempt import run_attempt
    from ncbot.pipelines.grid.attempts import ATTEMPTS_NAME
    from ncbot.pipelines.grid.plan import plan_runs

    (run,) = plan_runs(grid(tmp_path, total_frames=1024), seeds=1)
    run.run_dir.mkdir(parents=True)
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from pathlib import Path; "
                               "from ncbot.pipelines.run_folder import RunLock; RunLock(Path(sys.argv[1])); "
                               "print('locked', flush=True); time.sleep(600)", str(run.run_dir)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        record = {"try": 1, "backend": "ray", "host": "node-b", "boot": "node-b/0", "node": "node-b",
                  "train_pid": holder.pid, "started": time.time() - 900, "outcome": "running", "ended": None}
        (run.run_dir / ATTEMPTS_NAME).write_text(json.dumps({"attempts": [record]}))
        outcome = run_attempt(run, backend="local", try_number=1)  # a first try does not wait for the lock
        assert outcome.kind == "held", outcome  # its heartbeat is fresh (the file was just written): not stale
        os.utime(run.run_dir / ATTEMPTS_NAME, (time.time() - 900, time.time() - 900))
        assert run_attempt(run, backend="local", try_number=2) == Outcome(run.name, "finished")
        assert list(run.run_dir.glob(".lock.stale-*")) and "lock was stale" in (run.run_dir / "train.log").read_text()
    finally:
        holder.kill()
        holder.wait()


def test_a_run_that_fails_on_its_own_error_is_not_retried_and_the_grid_exits_1(tmp_path: Path) -> None:
    run_dir = tmp_path / "runs" / RUN
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "checkpoints" / "step-000000256.pt").write_bytes(b"not a checkpoint")
    process = ablate(str(grid(tmp_path)), "--seeds", "1", "--workers", "1", "--retries", "3")
    out, err = process.communicate(timeout=240)
    assert process.returncode == 1, err[-2000:]
    assert "0 runs finished, 0 skipped (already done), 1 failed, 0 retried" in out
    assert f"failed {RUN}: ncbot train exited 2: ncbot: error:" in out
    assert [entry["outcome"] for entry in read_attempts(run_dir)] == ["failed"]  # one try only
