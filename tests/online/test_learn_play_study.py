"""bench/studies/learn_play_from_play.py: each learning update's record (kept, which of the gate's checks refused it)
agrees with the learner's own per-game state, and a finished learning sequence is read back with the same records."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import torch

from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)
STUDY = Path(__file__).resolve().parents[2] / "bench" / "studies" / "learn_play_from_play.py"


def study_module():
    spec = importlib.util.spec_from_file_location("learn_play_from_play", STUDY)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def update(kept: bool | None, random_user: float = 1.0, person: float = 0.9, kept_person: float = 0.9) -> dict:
    return {"updated": kept is not None, "kept": kept, "gate_task_success": random_user, "start_task_success": 1.0,
            "person_task_success": person, "kept_person_task_success": kept_person}


def test_a_rolled_back_update_names_the_check_that_refused_it() -> None:
    rolled_back_by = study_module().rolled_back_by
    assert rolled_back_by(update(True)) is None and rolled_back_by(update(None)) is None
    assert rolled_back_by(update(False, random_user=0.99)) == "random user"
    assert rolled_back_by(update(False, person=0.8)) == "person model"
    assert rolled_back_by(update(False, random_user=0.99, person=0.8)) == "both"


def test_the_study_records_every_update_as_the_learner_did_and_reads_them_back(tmp_path: Path) -> None:
    train(load_config(write_tiny_config(tmp_path), ["collector.total_frames=256"]), tmp_path / "run")
    command = [sys.executable, str(STUDY), str(tmp_path / "run" / "checkpoint.pt"), "--person", "minimax",
               "--games", "3", "--seeds", "0", "--updates", "2", "--test-games", "10", "--out", str(tmp_path / "study")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    first = json.loads((tmp_path / "study" / "learn_play.json").read_text())
    learning = first["runs"][0]["learning"]
    state = json.loads((tmp_path / "study" / "seed0" / "learning" / "learning" / "state.json").read_text())
    plays = [game["play"] for game in state["per_game"]]
    assert learning["updates_kept"] == [play["game"] for play in plays if play["kept"]]
    assert [reason is None for reason in learning["rolled_back_by"]] == [bool(play["kept"]) for play in plays]
    assert learning["person_model_task_success"] == [play["kept_person_task_success"] for play in plays]
    assert first["summary"]["updates_kept_per_seed"] == [len(learning["updates_kept"])]
    assert sum(first["summary"]["rolled_back_by"].values()) == 3 - len(learning["updates_kept"])
    assert first["runs"][0]["frozen"]["updates_kept"] == [] and first["runs"][0]["frozen"]["rolled_back_by"] == []
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)  # the learning sequence is read back
    assert again.returncode == 0, again.stderr
    assert json.loads((tmp_path / "study" / "learn_play.json").read_text())["runs"][0]["learning"] == learning
