"""A game given as code, trained from an empty folder by its import path: misère Noughts & Crosses
(docs/examples/misere.py) learns the hard first seat on a short budget (0.894 at 153,600 frames; 0.958 at the
default's 614,400, docs/games.md) and the easy second seat, and its run folder names the class without ever
importing it by itself (an evaluation asks for the path again, in one line)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

MISERE = f"{Path(__file__).resolve().parents[2] / 'docs' / 'examples' / 'misere.py'}:Misere"
# the default recipe, its lost game priced at -50 (docs/games.md "Training it": under -20 the return-optimal robot who
# opens misère risks a loss for likelier wins), on a short budget
RECIPE = ["loss.loss_reward=-50", "collector.total_frames=153600", "train.eval_every_frames=153600",
          "checkpoint.every_frames=153600", "eval.games=1000", "eval.periodic_games=100", "logger.mcap=false"]


def _ncbot(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True, timeout=600, cwd=cwd)


@pytest.mark.slow
def test_the_misere_plugin_trains_from_an_empty_folder_by_its_import_path(tmp_path: Path) -> None:
    trained = _ncbot("train", "default", "--seed", "0", f"env.game={MISERE}", *RECIPE, "--out", "run", "--no-progress",
                     cwd=tmp_path)
    assert trained.returncode == 0, trained.stderr[-2000:]
    report = json.loads((tmp_path / "run" / "eval.json").read_text())
    # above the uniform choice inside the look-ahead masks in both seats (0.585 [0.554, 0.615] and 0.968 [0.955, 0.977],
    # docs/games.md): the run learnt, not only its masks
    assert report["first"]["task_success"] >= 0.85 and report["second"]["task_success"] >= 0.985, report

    refused = _ncbot("eval", "run", "--games", "10", cwd=tmp_path)  # the run folder alone never imports the class
    assert refused.returncode == 2
    (line,) = refused.stderr.strip().splitlines()
    assert line == (f"ncbot: error: game {MISERE} is code ncbot imports only when you name it: pass --game {MISERE} "
                    f"(or env.game={MISERE}) to the command; in Python, ncbot.envs.games.load_game('{MISERE}')")
    named = _ncbot("eval", "run", "--games", "100", "--game", MISERE, "--json", "--no-progress", cwd=tmp_path)
    assert named.returncode == 0, named.stderr[-2000:]
    assert json.loads(named.stdout)["games"] == 100
    other = _ncbot("eval", "run", "--games", "10", "--game", "four", cwd=tmp_path)
    assert other.returncode == 2 and f"does not match the checkpoint, which plays {MISERE}" in other.stderr
