"""`ncbot train --resume`: a run SIGKILLed after its first periodic checkpoint continues and finishes; missing or
corrupt checkpoints give one line and exit code 2."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ncbot.pipelines.checkpoint import (FORMAT, atomic_save, check_training_state, latest_training_state, load_checkpoint,
                                        periodic_checkpoints)
from ncbot.pipelines.run_folder import remove_stray_temp_files
from ncbot.pipelines.train.run import resolve_run
from tests.learning_helpers import ncbot, write_tiny_config


def _first_checkpoint_then_kill(config: Path, run: Path, timeout: float = 240) -> None:
    process = subprocess.Popen([sys.executable, "-m", "ncbot", "train", str(config), "--out", str(run)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    try:
        while not periodic_checkpoints(run):
            assert process.poll() is None, "training ended before its first periodic checkpoint"
            assert time.monotonic() < deadline, "no periodic checkpoint appeared in time"
            time.sleep(0.05)
    finally:
        os.kill(process.pid, signal.SIGKILL)
        process.wait()


def test_resume_after_sigkill_finishes_the_run(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path, collector={"total_frames": 20_480, "frames_per_batch": 64},
                               checkpoint={"every_frames": 128, "keep": 2}, train={"eval_every_frames": 2048})
    run = tmp_path / "run"
    _first_checkpoint_then_kill(config, run)
    assert not (run / "eval.json").exists(), "killed too late to test resuming"
    killed_at = load_checkpoint(periodic_checkpoints(run)[-1])
    assert killed_at["frames"] < 20_480 and killed_at["buffer"] is not None  # the replay buffer is saved

    result = ncbot("train", "--resume", str(run), "collector.total_frames=2048", "--no-progress")
    assert result.returncode == 0, result.stderr[-2000:]
    report = json.loads((run / "eval.json").read_text())
    assert report["frames"] == 2048
    assert report["updates"] > killed_at["updates"]
    assert report["train_cpu_time_s"] > killed_at["cpu_time"] > 0  # CPU time carries over the kill, like wall time
    assert load_checkpoint(run / "checkpoint.pt")["frames"] == 2048
    assert len(periodic_checkpoints(run)) <= 2
    assert not list(run.rglob("*.tmp"))


def test_missing_or_corrupt_checkpoint_is_one_line_exit_2(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="run folder .* not found"):
        resolve_run(None, [], out=None, seed=None, episodes=None, resume=str(tmp_path / "nowhere"), mcap=True)
    run = tmp_path / "run"
    run.mkdir()
    with pytest.raises(FileNotFoundError, match="config.yaml' not found"):
        resolve_run(None, [], out=None, seed=None, episodes=None, resume=str(run), mcap=True)
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text(write_tiny_config(tmp_path).read_text())
    with pytest.raises(FileNotFoundError, match="no periodic checkpoint"):
        latest_training_state(run)

    atomic_save({"format": "ncbot-dqn/1", "frames": 1}, run / "checkpoints" / "step-000000064.pt")
    data = (run / "checkpoints" / "step-000000064.pt").read_bytes()
    (run / "checkpoints" / "step-000000128.pt").write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="corrupt"):
        latest_training_state(run)
    result = ncbot("train", "--resume", str(run))  # the CLI turns it into one line and exit code 2
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    assert "corrupt" in result.stderr and "Traceback" not in result.stderr


def test_a_checkpoint_whose_cpu_time_is_not_a_number_is_refused_in_one_line() -> None:
    state = {"config": {}, "n_features": 73, "n_actions": 18, "qnet": {}, "learner": {}, "egreedy": {}, "history": [],
             "frames": 64, "updates": 1, "episodes": 1, "wall_time": 1.0, "cpu_time": "1.0"}
    with pytest.raises(ValueError, match="'cpu_time' is a str; expected a periodic checkpoint"):
        check_training_state(state, Path("step-000000064.pt"), config=None)


def test_every_run_removes_temp_files_left_by_a_kill_mid_write(tmp_path: Path) -> None:
    run = tmp_path / "run"
    atomic_save({"format": FORMAT, "learner": {}, "frames": 0}, run / "checkpoints" / "step-000000128.pt")
    stray = [run / "checkpoints" / ".step-000000256.pt.abc123.tmp", run / ".checkpoint.pt.def456.tmp"]
    for path in stray:
        path.write_bytes(b"half a checkpoint")
    keep = run / "notes.tmp"  # not one of ours: left alone
    keep.write_text("user file")
    assert latest_training_state(run)["frames"] == 0  # reading alone removes nothing (another run may be writing)
    assert all(path.exists() for path in stray)
    assert sorted(remove_stray_temp_files(run)) == sorted(stray)
    assert not any(path.exists() for path in stray) and keep.exists()


def test_a_sigterm_whose_exception_went_nowhere_still_stops_the_run(tmp_path: Path, monkeypatch) -> None:
    """The CLI's SIGTERM handler raises in whatever Python code runs; inside a finaliser that exception is only
    printed. The request it noted stops the training at its next batch, before the run would finish."""
    from ncbot.pipelines import errors
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.run import train

    config = load_config(write_tiny_config(tmp_path, collector={"total_frames": 2048}), [])
    monkeypatch.setattr(errors, "_termination_requested", True)  # the handler ran; its exception went nowhere
    with pytest.raises(errors.Terminated):
        train(config, tmp_path / "run")
    assert not (tmp_path / "run" / "eval.json").exists()


@pytest.mark.parametrize("network", ["mlp", "gru"])
def test_run_folders_of_the_previous_checkpoint_layout_resume_and_evaluate(tmp_path: Path, network: str) -> None:
    """A run folder written in the previous layout (tests/train/data/previous_layout: a recurrent objective's state
    then held no value-estimator gamma) resumes from its periodic checkpoint, and its final agent evaluates."""
    import shutil

    run = tmp_path / network
    shutil.copytree(Path(__file__).parent / "data" / "previous_layout" / network, run)
    result = ncbot("train", "--resume", str(run), "collector.total_frames=640", "--no-progress")
    assert result.returncode == 0, result.stderr
    assert "resuming from step-000000512.pt (512 frames)" in result.stderr
    assert load_checkpoint(run / "checkpoint.pt")["frames"] == 640
    shutil.copy(Path(__file__).parent / "data" / "previous_layout" / network / "checkpoint.pt", tmp_path / "old.pt")
    evaluated = ncbot("eval", str(tmp_path / "old.pt"), "--games", "10")
    assert evaluated.returncode == 0, evaluated.stderr
