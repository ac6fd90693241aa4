"""A game the project has never seen, declared in a temporary file, trained end to end by `ncbot train` with the
default recipe on a short budget: the robot beats the random user from the first seat and never plays outside its
action mask. (The full-budget runs of the shipped games are recorded in results/games.md.)"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ncbot.envs import make_env
from ncbot.pipelines.agents import load_agent

SHORT = ["collector.total_frames=8192", "train.eval_every_frames=8192", "eval.games=1000", "eval.periodic_games=100",
         "checkpoint.every_frames=8192"]


@pytest.mark.slow
def test_an_unseen_declared_game_trains_end_to_end(tmp_path: Path) -> None:
    game = tmp_path / "five_four.yaml"
    game.write_text("name: five_four\nrows: 5\ncols: 4\nk: 3\ngravity: true\n")
    run = tmp_path / "run"
    result = subprocess.run([sys.executable, "-m", "ncbot", "train", "default", "--seed", "0", f"env.game={game}", *SHORT,
                             "--out", str(run)], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    report = json.loads((run / "eval.json").read_text())
    assert report["first"]["games"] == 1000
    assert report["first"]["task_success"] >= 0.95, report["first"]

    config, policy = load_agent(run)
    assert config.env.game == str(game.resolve())
    env = make_env(config.env.game, batch_size=(64,), seed=5, first="alternate")
    td, outside = env.reset(), 0
    for _ in range(100):
        td = policy(td)
        outside += int((~td["action_mask"].gather(1, td["action"].unsqueeze(1))).sum())
        td = env.step_and_maybe_reset(td)[1]
    assert outside == 0


def test_a_bad_declaration_is_one_line_and_exit_2(tmp_path: Path) -> None:
    game = tmp_path / "wide.yaml"
    game.write_text("name: wide\nrows: 3\ncols: 12\nk: 3\n")
    result = subprocess.run([sys.executable, "-m", "ncbot", "train", "default", f"env.game={game}", "--out",
                             str(tmp_path / "run")], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert "cols must be an integer 3..9; got 12" in result.stderr
