"""Faults a run meets in the wild: a read-only or full disk, SIGINT/SIGTERM/SIGKILL while it writes, a
second run into the same folder, a damaged newest checkpoint, a kill before the first checkpoint. Each must end
in one line (exit 2, 130 or 143) and `--resume` must then finish the run with nothing of another run mixed in.

The disks are real tmpfs mounts (root in a container may mount; the tests skip, saying why, where it cannot).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from ncbot.pipelines.checkpoint import FORMAT, atomic_save, load_checkpoint, periodic_checkpoints
from tests.learning_helpers import ncbot, write_tiny_config
from tests.cli.test_reliability_fuzz import _valid_agent, assert_refused

LONG = {"collector": {"total_frames": 20_480, "frames_per_batch": 64}, "checkpoint": {"every_frames": 128, "keep": 2},
        "train": {"eval_every_frames": 4096}, "logger": {"mcap": True, "progress": False}}


@contextmanager
def tmpfs(folder: Path, size: str, read_only: bool = False):
    """A small tmpfs at `folder` (read-only after `prepare` when asked); skips when mounting is not allowed."""
    folder.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root / CAP_SYS_ADMIN): {done.stderr.strip()}")
    try:
        if read_only:
            subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def start_training(config: Path, run: Path, *extra: str) -> subprocess.Popen:
    """`ncbot train` in a child whose Ctrl-C is live even when this suite runs as a background job (a shell starts
    those with SIGINT ignored, which the child would inherit and Python would then never turn into KeyboardInterrupt)."""
    return subprocess.Popen([sys.executable, "-m", "ncbot", "train", str(config), "--out", str(run), *extra],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_for(condition, process: subprocess.Popen, what: str, timeout: float = 240) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert process.poll() is None, f"training ended before {what}: {process.stderr.read()[-1500:]}"
        assert time.monotonic() < deadline, f"no {what} in time"
        time.sleep(0.02)


def train_episodes_in_log(run: Path) -> int:
    from ncbot.logs.reader import read_episodes

    return sum(1 for path in sorted(run.glob("episodes-*.mcap"))
               for episode in read_episodes(path) if episode["phase"] == "train")


# ------------------------------------------------------------------------------------------------- disks
def test_read_only_outputs_are_one_line_for_every_writing_command(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path)
    atomic_save(_valid_agent(), tmp_path / "run" / "checkpoint.pt")
    with tmpfs(tmp_path / "ro", "1m", read_only=True) as ro:
        cases = [
            ["train", str(config), "--out", str(ro / "run")],
            ["eval", str(tmp_path / "run" / "checkpoint.pt"), "--games", "1", "--out", str(ro / "log")],
            ["ladder", str(tmp_path / "run" / "checkpoint.pt"), "--games", "1", "--out", str(ro / "ladder")],
            ["play", "--out", str(ro / "play")],
            ["logs", "curve", str(tmp_path), "-o", str(ro / "curve.png")],
            ["logs", "to-rerun", str(tmp_path), "-o", str(ro / "x.rrd")],
            ["vision", "generate", "cells", "--out", str(ro / "cells")],
            ["vision", "train", "--out", str(ro / "w.pt")],
            ["vision", "eval", "--what", "cells", "--out", str(ro / "vision")],
            ["table", str(tmp_path), "--out", str(ro / "table.md")],
            ["robot", "urdf", "-o", str(ro / "pepper.urdf")],
            ["robot", "play", "--out", str(ro / "robot")],
            ["robot", "render", "-o", str(ro / "mouth.png")],
            ["ablate", str(config), "--out", str(ro / "runs")],
        ]
        for args in cases:
            line = assert_refused(tmp_path, *args)
            assert "read-only" in line, (args, line)


def test_a_disk_too_small_is_refused_before_any_write(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path)
    with tmpfs(tmp_path / "small", "512k") as small:
        line = assert_refused(tmp_path, "train", str(config), "--out", str(small / "run"))
        assert "MiB free" in line and not (small / "run").exists()


def test_a_disk_that_fills_during_training_is_one_line_and_resume_finishes(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path, collector={"total_frames": 2048, "frames_per_batch": 64},
                          checkpoint={"every_frames": 128, "keep": 3}, logger={"mcap": True, "progress": False})
    with tmpfs(tmp_path / "full", "3m") as full:
        run = full / "run"
        done = ncbot("train", str(config), "--out", str(run))
        assert done.returncode == 2, done.stderr[-2000:]
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and "no space left" in lines[0] and "Traceback" not in done.stderr
        assert not list(run.rglob("*.tmp")), "a temp file of the failed write was left behind"
        for path in periodic_checkpoints(run):
            assert load_checkpoint(path)["frames"] > 0  # never a partial checkpoint under its final name
        subprocess.run(["mount", "-o", "remount,size=64m", str(full)], check=True)
        resumed = ncbot("train", "--resume", str(run), "--no-progress")
        assert resumed.returncode == 0, resumed.stderr[-2000:]
        report = json.loads((run / "eval.json").read_text())
        assert report["frames"] == 2048 and train_episodes_in_log(run) == report["episodes"]


# ------------------------------------------------------------------------------------------------- signals
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGKILL, -9)])
def test_a_signal_during_training_then_resume_finishes_with_a_consistent_log(tmp_path: Path, signum: int, code: int) -> None:
    config = write_tiny_config(tmp_path, **LONG)
    run = tmp_path / "run"
    old_umask = os.umask(0o022)
    try:
        process = start_training(config, run)
        wait_for(lambda: len(periodic_checkpoints(run)) >= 2, process, "second periodic checkpoint")
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)
        assert process.returncode == code, err[-2000:]
        if signum != signal.SIGKILL:
            lines = err.strip().splitlines()
            assert len(lines) == 1 and "--resume" in lines[0] and "Traceback" not in err, err[-2000:]
            assert not list(run.rglob("*.tmp")), "an interrupted write left its temp file"
        killed_at = load_checkpoint(periodic_checkpoints(run)[-1])["frames"]
        resumed = ncbot("train", "--resume", str(run), "collector.total_frames=2048", "--no-progress")
    finally:
        os.umask(old_umask)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert f"resuming from step-{killed_at:09d}.pt" in resumed.stderr
    report = json.loads((run / "eval.json").read_text())
    assert report["frames"] == 2048
    assert train_episodes_in_log(run) == report["episodes"], "the log keeps episodes the counters do not count"
    assert not list(run.rglob("*.tmp"))
    for name in ("checkpoint.pt", "eval.json", "config.yaml", "learning_curve.png", "run.json"):
        assert (run / name).stat().st_mode & 0o777 == 0o644, name


def test_a_kill_before_the_first_checkpoint_then_resume_starts_the_run_again(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path, **LONG)
    run = tmp_path / "run"
    process = start_training(config, run)
    wait_for(lambda: (run / "config.yaml").exists(), process, "config.yaml")
    process.kill()
    process.wait()
    for path in periodic_checkpoints(run):  # in case it got that far: back to "killed during the first write"
        path.unlink()
    (run / "checkpoints").mkdir(exist_ok=True)
    (run / "checkpoints" / ".step-000000128.pt.0badf00d.tmp").write_bytes(b"half a checkpoint")
    resumed = ncbot("train", "--resume", str(run), "collector.total_frames=512", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert "starting this run again" in resumed.stderr
    report = json.loads((run / "eval.json").read_text())
    assert report["frames"] == 512 and train_episodes_in_log(run) == report["episodes"]
    assert not list(run.rglob("*.tmp"))


def test_a_damaged_newest_checkpoint_falls_back_to_the_older_one(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path, **LONG)
    run = tmp_path / "run"
    process = start_training(config, run)
    wait_for(lambda: len(periodic_checkpoints(run)) >= 2, process, "second periodic checkpoint")
    process.kill()
    process.wait()
    older, newest = periodic_checkpoints(run)[-2:]
    newest.write_bytes(newest.read_bytes()[:1000])
    resumed = ncbot("train", "--resume", str(run), "collector.total_frames=1024", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert f"skipped {newest.name}" in resumed.stderr and f"resuming from {older.name}" in resumed.stderr
    report = json.loads((run / "eval.json").read_text())
    assert report["frames"] == 1024 and train_episodes_in_log(run) == report["episodes"]


# ------------------------------------------------------------------------------------------------- run identity
def test_a_second_run_into_a_busy_folder_is_refused_and_a_dead_runs_lock_is_taken_over(tmp_path: Path) -> None:
    # the first run must outlive two CLI start-ups on a loaded machine (LONG's 20K frames did not, once): it is
    # killed below anyway
    config = write_tiny_config(tmp_path, **{**LONG, "collector": {"total_frames": 10_000_000, "frames_per_batch": 64}})
    run = tmp_path / "run"
    process = start_training(config, run)
    try:
        wait_for(lambda: len(periodic_checkpoints(run)) >= 1, process, "first periodic checkpoint")
        for args in (["train", str(config), "--out", str(run), "--overwrite"], ["train", "--resume", str(run)]):
            done = ncbot(*args)
            assert done.returncode == 2 and f"in use by another ncbot train (pid {process.pid})" in done.stderr, done.stderr
            assert len(done.stderr.strip().splitlines()) == 1
    finally:
        process.kill()
        process.wait()
    resumed = ncbot("train", "--resume", str(run), "collector.total_frames=512", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr[-2000:]


def test_a_new_run_into_a_folder_of_another_run_is_refused_unless_overwrite(tmp_path: Path) -> None:
    run = tmp_path / "run"
    first = ncbot("train", str(write_tiny_config(tmp_path, checkpoint={"every_frames": 128, "keep": 10})), "--out", str(run))
    assert first.returncode == 0, first.stderr[-2000:]
    old_steps = {p.name for p in periodic_checkpoints(run)}
    old_id = json.loads((run / "run.json").read_text())["run_id"]
    config = write_tiny_config(tmp_path, train={"seed": 9, "eval_every_frames": 256}, collector={"total_frames": 256})
    refused = ncbot("train", str(config), "--out", str(run))
    assert refused.returncode == 2 and "holds another run" in refused.stderr
    assert {p.name for p in periodic_checkpoints(run)} == old_steps  # untouched
    replaced = ncbot("train", str(config), "--out", str(run), "--overwrite")
    assert replaced.returncode == 0, replaced.stderr[-2000:]
    new_id = json.loads((run / "run.json").read_text())["run_id"]
    assert new_id != old_id
    assert all(load_checkpoint(p)["run_id"] == new_id for p in periodic_checkpoints(run))
    assert load_checkpoint(run / "checkpoint.pt")["config"]["train"]["seed"] == 9


def test_a_checkpoint_of_another_run_is_never_resumed(tmp_path: Path) -> None:
    run = tmp_path / "run"
    first = ncbot("train", str(write_tiny_config(tmp_path)), "--out", str(run))
    assert first.returncode == 0, first.stderr[-2000:]
    newest = periodic_checkpoints(run)[-1]
    foreign = load_checkpoint(newest)
    foreign["run_id"] = "someone-else"
    atomic_save(foreign, newest.with_name("step-000009999.pt"))
    resumed = ncbot("train", "--resume", str(run), "collector.total_frames=768", "--no-progress")
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert "skipped step-000009999.pt" in resumed.stderr and "belongs to another run" in resumed.stderr
    assert f"resuming from {newest.name}" in resumed.stderr


def test_a_resume_whose_overrides_do_not_fit_the_checkpoint_is_one_line(tmp_path: Path) -> None:
    run = tmp_path / "run"
    assert ncbot("train", str(write_tiny_config(tmp_path)), "--out", str(run)).returncode == 0
    done = ncbot("train", "--resume", str(run), "agent.hidden=[8]")
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "do not match agent.hidden=[8]" in done.stderr and "Traceback" not in done.stderr


def test_a_failed_start_writes_nothing(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path)
    for args in (["optim.lr=-1"], ["--seed", "-1"], ["env.batch_size=100000000000"], ["agent.hidden=[1000000000]"]):
        assert_refused(tmp_path, "train", str(config), *args, "--out", str(tmp_path / "run"))
    assert not (tmp_path / "run").exists()
    legacy = tmp_path / "legacy"
    atomic_save({"format": FORMAT}, legacy / "checkpoint.pt")
    assert "has no 'config'" in assert_refused(tmp_path, "eval", str(legacy), "--games", "1")
