"""`ncbot ablate` + `ncbot table` on a tiny real grid: runs in parallel processes, finished runs are skipped,
the table has the paper's numbers beside ours and the curves PNG is written."""
from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
import yaml

from ncbot.pipelines.grid.plan import plan_runs
from ncbot.pipelines.grid.runner import Cluster, run_ablation
from ncbot.pipelines.reproduce.table import write_table
from tests.learning_helpers import write_tiny_config


def _grid(folder: Path) -> Path:
    base = write_tiny_config(folder, collector={"total_frames": 128}, eval={"games": 20, "periodic_games": 10})
    grid = {
        "runs_dir": str(folder / "runs"),
        "suites": {"fast": {"standard": {"config": base.name}}},
        "grid": {"suite": ["fast"], "game": ["standard"], "agent": ["dqn_variant", "proposed"], "temporal": [False, True]},
    }
    path = folder / "grid.yaml"
    path.write_text(yaml.safe_dump(grid))
    return path


def test_plan_covers_the_grid_and_drops_temporal_baselines(tmp_path: Path) -> None:
    names = [run.name for run in plan_runs(_grid(tmp_path), seeds=2)]
    assert names == [
        "fast/standard/dqn_variant-notemporal/seed0", "fast/standard/dqn_variant-notemporal/seed1",
        "fast/standard/proposed-notemporal/seed0", "fast/standard/proposed-notemporal/seed1",
        "fast/standard/proposed-temporal/seed0", "fast/standard/proposed-temporal/seed1",
    ]


def test_bad_grid_is_a_clear_error(tmp_path: Path) -> None:
    path = _grid(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["grid"]["agent"] = ["dqn_magic"]
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match="'agent.name' must be one of"):
        plan_runs(path, seeds=1)
    with pytest.raises(ValueError, match="backend"):
        run_ablation(path, cluster=Cluster(backend="k8s"))


def test_grid_runs_in_parallel_skips_finished_and_tabulates(tmp_path: Path) -> None:
    grid = _grid(tmp_path)
    summary = run_ablation(grid, seeds=1, cluster=Cluster(workers=2), only="proposed")
    assert (summary["done"], summary["failed"], summary["unfinished"]) == (2, 0, []), summary
    again = run_ablation(grid, seeds=1, cluster=Cluster(workers=2), only="proposed")
    assert (again["done"], again["skipped"]) == (0, 2)

    text = write_table(tmp_path / "runs", tmp_path / "table.md")
    rows = [line for line in text.splitlines() if line.startswith("| 3x3")]
    assert len(rows) == 2
    assert "Proposed + temporal" in text and "0.9980" in text  # the paper's task success beside ours
    assert (tmp_path / "curves_fast_standard.png").stat().st_size > 0



def test_sigterm_stops_the_grid_and_its_running_training(tmp_path: Path) -> None:
    """A stopped grid must not keep training: SIGTERM reaches the running `ncbot train` (resumable, exit 143) and no
    queued run starts (the thread pool would otherwise drain its queue on shutdown)."""
    import os
    import signal
    import subprocess
    import sys

    base = write_tiny_config(tmp_path, collector={"total_frames": 10_000_000}, eval={"games": 20, "periodic_games": 10})
    grid = {"runs_dir": str(tmp_path / "runs"), "suites": {"fast": {"standard": {"config": base.name}}},
            "grid": {"suite": ["fast"], "game": ["standard"], "agent": ["proposed"], "temporal": [False]}}
    (tmp_path / "grid.yaml").write_text(yaml.safe_dump(grid))
    grid_run = subprocess.Popen([sys.executable, "-m", "ncbot", "ablate", str(tmp_path / "grid.yaml"),
                                 "--seeds", "2", "--workers", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    first = tmp_path / "runs" / "fast" / "standard" / "proposed-notemporal" / "seed0"
    deadline = time.monotonic() + 120
    while not (first / "scalars").is_dir() and time.monotonic() < deadline:  # the training is under way
        time.sleep(0.2)
    assert (first / "scalars").is_dir(), "the first training never started"
    os.kill(grid_run.pid, signal.SIGTERM)
    _, err = grid_run.communicate(timeout=90)
    assert grid_run.returncode == 143, err
    log = (first / "train.log").read_text()
    assert "terminated (SIGTERM)" in log, log[-3000:]  # the child was stopped, not orphaned
    assert not (first.parent / "seed1").exists()  # the queued run never started


def test_status_says_where_every_run_stands_and_a_held_run_is_not_started_twice(tmp_path: Path) -> None:
    """Two `ncbot ablate` processes on one runs folder: a run the other one is training (its folder's lock held) is
    skipped and counted as held, not started a second time and not failed; `--status` names each run's state."""
    import json

    from ncbot.pipelines.grid.attempt import Outcome, run_attempt
    from ncbot.pipelines.grid.plan import PlannedRun
    from ncbot.pipelines.grid.status import grid_status
    from ncbot.pipelines.run_folder import RunLock
    from tests.learning_helpers import ncbot

    grid = _grid(tmp_path)
    runs = tmp_path / "runs" / "fast" / "standard"
    finished, stopped, held = (runs / "proposed-notemporal" / "seed0", runs / "proposed-temporal" / "seed0",
                               runs / "dqn_variant-notemporal" / "seed0")
    finished.mkdir(parents=True)
    (finished / "eval.json").write_text(json.dumps({"first": {"task_success": 0.99}, "second": {"task_success": 0.9}}))
    (stopped / "checkpoints").mkdir(parents=True)
    (stopped / "checkpoints" / "step-000050000.pt").write_bytes(b"")
    lock = RunLock(held)  # another ncbot train, as far as the folder can tell
    try:
        states = {status.name.split("/")[2]: (status.state, status.detail) for status in grid_status(grid, seeds=1)[0]}
        assert states["proposed-notemporal"] == ("finished", "task success 0.9900 robot first, 0.9000 robot second")
        assert states["proposed-temporal"] == ("stopped", "resumes from the checkpoint at 50,000 frames")
        assert states["dqn_variant-notemporal"][0] == "training now"
        assert f"pid {os.getpid()}" in states["dqn_variant-notemporal"][1]
        assert run_attempt(PlannedRun("held", held, tmp_path / "grid.yaml"), backend="local").kind == "held"
        assert run_attempt(PlannedRun("done", finished, tmp_path / "grid.yaml"), backend="local") == \
            Outcome("done", "finished", "finished by another process")
        assert not (held / "train.log").exists() and not (finished / "train.log").exists()  # nothing was started
        result = ncbot("ablate", str(grid), "--seeds", "1", "--status")
        assert result.returncode == 0, result.stderr
        assert result.stdout.strip().splitlines()[-2:] == [
            "3 runs: 1 training now, 1 finished, 1 stopped",
            "left: 2 runs, none with a finished seed of its cell to estimate from"]
    finally:
        lock.release()
    assert grid_status(grid, seeds=1)[0][0].state == "not started"  # the lock is gone with its holder, no checkpoint


def test_status_gives_a_running_run_its_pace_and_time_left(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The two newest checkpoints' frames and times give the rate; the run's config.yaml its total frames."""
    from ncbot.pipelines.grid.plan import PlannedRun
    from ncbot.pipelines.grid.status import run_state
    from ncbot.pipelines.run_folder import RunLock

    run_dir = tmp_path / "seed0"
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "config.yaml").write_text("collector:\n  total_frames: 400000\n")
    now = time.time()
    monkeypatch.setattr(time, "time", lambda: now)  # the clock stands still while the test reads the estimate
    for frames, age in ((100_000, 600.0), (150_000, 400.0)):  # 50,000 frames in 200 s, the newer 400 s ago
        path = run_dir / "checkpoints" / f"step-{frames:09d}.pt"
        path.write_bytes(b"")
        os.utime(path, (now - age, now - age))
    run = PlannedRun("seed0", run_dir, tmp_path / "grid.yaml")
    lock = RunLock(run_dir)
    try:
        os.utime(run_dir / ".lock", (now - 700, now - 700))  # the training started before both checkpoints
        where, detail = run_state(run)
        # 250,000 frames at 250 frames/s is 1,000 s from the newer checkpoint, 400 s of which have passed
        assert (where, detail.split(", ", 1)[1]) == \
            ("training now", "checkpoint at 150,000 frames, 250 frames/s, about 10:00 left of 400,000 frames")
        # resumed 500 s ago from the older checkpoint: its pace is from then (50,000 frames in 100 s), not the
        # earlier process's, whose stop before the resume would make the estimate hours long
        os.utime(run_dir / ".lock", (now - 500, now - 500))
        assert run_state(run)[1].endswith("checkpoint at 150,000 frames, 500 frames/s, about 1:40 left of 400,000 frames")
        os.utime(run_dir / ".lock", (now - 300, now - 300))  # resumed after both: nothing of its own yet
        assert run_state(run)[1].endswith("checkpoint at 150,000 frames")
        # checkpoints every 50,000 frames: 400 s after the newer one (200 s of frames at 500 frames/s) the run cannot
        # be past 200,000 frames, or it would have written that checkpoint: 200,000 frames left, 6:40, not 0:00
        (run_dir / "config.yaml").write_text("collector:\n  total_frames: 400000\ncheckpoint:\n  every_frames: 50000\n")
        os.utime(run_dir / ".lock", (now - 500, now - 500))
        assert run_state(run)[1].endswith("checkpoint at 150,000 frames, 500 frames/s, about 6:40 left of 400,000 frames")
        (run_dir / "config.yaml").write_text("collector:\n  total_frames: 400000\n")
        os.utime(run_dir / ".lock", (now - 300, now - 300))
        last = run_dir / "checkpoints" / "step-000400000.pt"
        last.write_bytes(b"")
        assert run_state(run)[1].endswith("every frame trained: the final evaluation")
        last.unlink()
        (run_dir / "config.yaml").write_text("collector: {}\n")  # no total: no estimate, still the checkpoint
        assert run_state(run)[1].endswith("checkpoint at 150,000 frames")
    finally:
        lock.release()


def test_status_sums_the_training_time_left_from_each_cells_finished_seeds(tmp_path: Path) -> None:
    """A run not started costs its cell's median finished seed, a stopped one the share of frames its checkpoint has
    left; a cell with no finished seed is counted apart, not guessed."""
    import json

    from ncbot.pipelines.grid.status import grid_status
    from tests.learning_helpers import ncbot

    grid = _grid(tmp_path)
    cell = tmp_path / "runs" / "fast" / "standard" / "proposed-temporal"
    for seed, seconds in ((0, 100.0), (1, 300.0), (2, 200.0)):  # median 200 s
        (cell / f"seed{seed}").mkdir(parents=True)
        (cell / f"seed{seed}" / "eval.json").write_text(json.dumps(
            {"train_wall_time_s": seconds, "first": {"task_success": 0.99}, "second": {"task_success": 0.9}}))
    stopped = cell / "seed3"
    (stopped / "checkpoints").mkdir(parents=True)
    (stopped / "config.yaml").write_text("collector:\n  total_frames: 400000\n")
    (stopped / "checkpoints" / "step-000100000.pt").write_bytes(b"")  # a quarter trained: 150 s left
    states, left, _ = grid_status(grid, seeds=5, only="proposed-temporal")
    assert [status.state for status in states] == ["finished"] * 3 + ["stopped", "not started"]
    assert (left.seconds, left.estimated, left.unknown) == (150.0 + 200.0, 2, 0)
    _, everything, _ = grid_status(grid, seeds=5)  # the other cells have no finished seed
    assert (everything.seconds, everything.estimated, everything.unknown) == (350.0, 2, 10)
    result = ncbot("ablate", str(grid), "--seeds", "5", "--only", "proposed-temporal", "--status", "--workers", "2")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == (
        "left: about 5:50 of training over 2 runs, about 2:55 at --workers 2 (each run at its own pace, else at the "
        "median of its cell's finished seeds)")
