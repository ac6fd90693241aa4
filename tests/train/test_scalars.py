"""The run's scalars through TorchRL's loggers: train/ and eval/ records in the run folder, the curve from the same
records, a clear exit 2 for a backend that is not installed, and a piped `ncbot train` that prints lines, not redraws."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from ncbot.pipelines.plots import frames_label
from ncbot.pipelines.scalars import check_backend, eval_scalars, read_csv_scalars
from tests.learning_helpers import ncbot, write_tiny_config


def test_piped_train_logs_scalars_and_prints_progress_lines(tmp_path: Path) -> None:
    config = write_tiny_config(tmp_path, logger={"mcap": False, "progress": True})
    result = ncbot("train", str(config), "--out", str(tmp_path / "run"), "collector.total_frames=256",
                   "train.eval_every_frames=128")
    assert result.returncode == 0, result.stderr
    progress = [line for line in result.stderr.splitlines() if line.startswith("train standard proposed:")]
    assert 1 <= len(progress) <= 11 and "\r" not in result.stderr, result.stderr  # 4 batches: 25 %, 50 %, 75 %, 100 %
    assert "ETA" in progress[0] and "frame/s" in progress[0]

    scalars = read_csv_scalars(tmp_path / "run")
    history = json.loads((tmp_path / "run" / "eval.json").read_text())["history"]
    assert [step for step, _ in scalars["train/epsilon"]] == [64, 128, 192, 256]  # step = collected env frames
    for name in ("train/loss", "train/lr", "train/frames_per_s", "train/updates_per_s"):
        assert scalars[name] and all(value >= 0 for _, value in scalars[name]), name
    # every periodic evaluation, as eval.json's history records it (the learning-curve PNG draws these)
    for key in ("task_success", "win", "draw", "loss", "avg_length"):
        assert scalars[f"eval/{key}"] == [(h["frames"], pytest.approx(h[key])) for h in history], key


def test_backend_none_writes_no_scalars(tmp_path: Path) -> None:
    result = ncbot("train", str(write_tiny_config(tmp_path)), "--out", str(tmp_path / "run"),
                   "collector.total_frames=64", "logger.backend=none")
    assert result.returncode == 0, result.stderr
    assert not (tmp_path / "run" / "scalars").exists()


@pytest.mark.skipif(importlib.util.find_spec("tensorboard") is not None, reason="tensorboard is installed here")
def test_a_backend_that_is_not_installed_is_one_line_and_exit_2(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="'tensorboard' package is not installed"):
        check_backend("tensorboard")
    result = ncbot("train", str(write_tiny_config(tmp_path)), "--out", str(tmp_path / "run"),
                   "logger.backend=tensorboard")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "ncbot: error: config key 'logger.backend' is 'tensorboard' but the 'tensorboard' package is not installed "
        "(pip install tensorboard); use csv or none"]


def test_eval_scalars_and_frame_ticks() -> None:
    record = {"frames": 512, "task_success": 0.99, "win": 0.9, "draw": 0.09, "loss": 0.01, "avg_length": 8.5,
              "task_success_ci95": [0.9, 1.0], "wall_time": 3.0}
    assert eval_scalars(record) == {"eval/task_success": 0.99, "eval/win": 0.9, "eval/draw": 0.09, "eval/loss": 0.01,
                                    "eval/avg_length": 8.5}
    assert [frames_label(x) for x in (0, 500, 100_000, 250_000, 1_500_000)] == ["0", "500", "100K", "250K", "1.5M"]
