"""The vision data budget: N cells split as the paper's 109 : 201, nested seeded draws, the shipped recipe's update
count, `ncbot vision train --budget N` / `--weights`, and `ncbot reproduce vision` at a toy budget."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import torch
from typer.testing import CliRunner

from ncbot.pipelines.reproduce.grid import BUDGETS, Budget
from ncbot.pipelines.reproduce.vision import VISION_BUDGETS, VisionBudget
from ncbot.vision import budget as vb
from ncbot.vision.classifier import DEFAULT_WEIGHTS
from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.cells import make_cells

TINY = Budget(name="tiny", seeds=1, rows=("standard",), max_games={"standard": 4}, eval_games=20,
              eval_every_frames={"standard": 64}, game_points=(2, 4), label="TINY BUDGET (test)")
TOY = VisionBudget("tiny", (6, 9), 1, 20, 2, 1, "TOY VISION BUDGET (test)", updates=8)


def _vision(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", "vision", *args], capture_output=True, text=True, cwd=cwd)


def test_split_follows_the_paper_and_draws_are_nested(monkeypatch) -> None:
    monkeypatch.setattr(vb, "PHOTO_POOL", (3, 1))  # 108 photo cells are plenty here (the default pool: 540)
    assert vb.split(310) == vb.Split(109, 101, 100)  # the paper's 109 clean + 201 noisy
    assert [vb.split(n).images for n in (10, 25, 1000)] == [10, 25, 1000] and vb.split(10).clean == 4
    small, small_labels, _ = vb.training_set(6, seed=3)
    large, large_labels, parts = vb.training_set(9, seed=3)
    assert parts == vb.Split(3, 3, 3) and set(large_labels.tolist()) == {0, 1, 2}
    # clean (first 2 of 3), generated noisy (first 2 of 3) and photo cells (first 2 of 3) of N = 6 are N = 9's
    for mine, theirs in ((slice(0, 2), slice(0, 2)), (slice(2, 4), slice(3, 5)), (slice(4, 6), slice(6, 8))):
        assert np.array_equal(small[mine], large[theirs]) and np.array_equal(small_labels[mine], large_labels[theirs])
    other, _, _ = vb.training_set(6, seed=4)
    assert not np.array_equal(small, other)


def test_every_budget_makes_the_shipped_runs_updates_on_its_clean_and_noisy_cells() -> None:
    meta = torch.load(DEFAULT_WEIGHTS, map_location="cpu", weights_only=True)["meta"]
    # the shipped run's updates over its cells without the harsh ones (the kinds a budget draws): 8,764
    shipped = meta["train_epochs"] * math.ceil((meta["n_training_cells"] - meta["n_harsh_cells"]) / meta["train_batch_size"])
    assert vb.BUDGET_UPDATES == shipped == 8_764 and meta["n_training_cells"] == vb.SHIPPED_CELLS
    for n in (10, 64, 310, 1000):
        config = vb.train_config(n)
        made = config.epochs * math.ceil(n / config.batch_size)
        assert shipped <= made < shipped + math.ceil(n / 64) and (config.batch_size, config.lr) == (64, 3e-3)


def test_train_budget_cli_and_weights_option(tmp_path: Path) -> None:
    weights = tmp_path / "w.pt"
    out = _vision("train", "--budget", "6", "--updates", "8", "--seed", "1", "--out", str(weights))
    assert out.returncode == 0, out.stderr
    meta = torch.load(weights, map_location="cpu", weights_only=True)["meta"]
    assert (meta["budget_images"], meta["clean"], meta["budget_seed"], meta["updates"]) == (6, 2, 1, 8)
    import cv2

    cells, _ = make_cells(1, TEST_SEED + 602)
    cell = tmp_path / "cell.png"
    cv2.imwrite(str(cell), cells[0])
    used = _vision("classify", str(cell), "--weights", str(weights), "--json")
    assert used.returncode == 0 and json.loads(used.stdout)["images"][0]["label"] in ("nought", "cross", "nothing")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    for command in (("classify", str(cell)), ("read", str(cell), "--grid", "3")):
        wrong = _vision(*command, "--weights", str(bad))
        assert wrong.returncode == 2 and "Traceback" not in wrong.stderr, wrong.stderr
        assert len(wrong.stderr.strip().splitlines()) == 1 and f"classifier weights {bad}" in wrong.stderr
    from ncbot.vision.classifier import DEFAULT_WEIGHTS

    shipped = Path(DEFAULT_WEIGHTS).read_bytes()
    no_out = _vision("train", "--budget", "6", "--no-progress", cwd=tmp_path)  # the default --out: under runs/, never the package
    assert no_out.returncode == 0, no_out.stderr[-2000:]
    assert (tmp_path / "runs" / "vision" / "cell_cnn.pt").is_file() and Path(DEFAULT_WEIGHTS).read_bytes() == shipped
    assert no_out.stderr.strip().splitlines()[-1].startswith("wrote runs/vision/cell_cnn.pt")


def test_reproduce_vision_toy_budget_writes_reports_and_resumes(tmp_path: Path, monkeypatch) -> None:
    from ncbot.pipelines.cli.app import app

    monkeypatch.setitem(BUDGETS, "tiny", TINY)
    monkeypatch.setattr(vb, "PHOTO_POOL", (3, 1))
    monkeypatch.setitem(VISION_BUDGETS, "tiny", TOY)
    out, runs = tmp_path / "results", tmp_path / "runs"
    args = ["reproduce", "vision", "--budget", "tiny", "--out", str(out), "--runs", str(runs), "--workers", "1", "--json"]
    first = CliRunner().invoke(app, args)
    assert first.exit_code == 0, first.output
    data = json.loads(first.stdout.strip().splitlines()[-1])
    assert data["label"] == TOY.label and [r["images"] for r in data["vision"]] == [6, 9]
    for r in data["vision"]:
        assert {"images", "cell_accuracy", "board_accuracy", "clean", "noisy", "seeds"} <= set(r)
        assert 0 <= r["cell_accuracy"] <= 1 and r["board_accuracy"] in (0.0, 0.5, 1.0) and r["clean"] + r["noisy"] == r["images"]
    text = (out / "vision_experiments.md").read_text()
    assert TOY.label in text and "Made by `ncbot " in text  # the command line that made it
    for paper in ("99.9 %", "74.0 %", "98.4 %", "95.1 / 4.9 / 0.0"):  # the paper's three numbers and its nought row
        assert paper in text
    assert (out / "vision_experiments.png").stat().st_size > 0 and (out / "data_budget_vision.png").stat().st_size > 0
    assert not (runs / "tiny" / "grid.yaml").exists()  # the vision part trains no RL agents
    results = sorted((runs / "tiny" / "vision").glob("n*_seed0/result.json"))
    stamps = [p.stat().st_mtime_ns for p in results]
    again = CliRunner().invoke(app, args)
    assert again.exit_code == 0 and [p.stat().st_mtime_ns for p in results] == stamps  # finished points skipped
    # `budget` reads the same points back into data_budget.md's vision section and its --json "vision" list
    from ncbot.pipelines.reproduce.budget import write_budget_report

    report = write_budget_report(TINY, runs_dir=runs / "tiny", out=out, command="ncbot reproduce budget --budget tiny")
    assert [r["cell_accuracy"] for r in report["vision"]] == [r["cell_accuracy"] for r in data["vision"]]
    section = (out / "data_budget.md").read_text().split("## Vision: labelled cell images")[1].split("## Dialogues")[0]
    assert TOY.label in section and "| 6 | 2 + 4 (2 + 2) | 1 |" in section and "shipped weights" in section
    assert str(out / "data_budget_vision.png") in report["figures"]
    assert [p.stat().st_mtime_ns for p in results] == stamps
    # a report of a run still under way: finished points only, nothing trained, labelled PARTIAL
    import shutil

    from ncbot.pipelines.reproduce.vision import write_vision_report

    shutil.rmtree(runs / "tiny" / "vision" / "n00009_seed0")
    partial = write_vision_report(TINY, runs_dir=runs / "tiny", out=out, command="x", partial="stopped for a test.")
    assert [r["images"] for r in partial["vision"]] == [6] and not (runs / "tiny" / "vision" / "n00009_seed0").exists()
    assert (out / "vision_experiments.md").read_text().count("PARTIAL (1 of 2 points finished): stopped for a test.") == 2
