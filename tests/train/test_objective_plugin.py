"""A user's objective by import path, from an empty folder (docs/examples/double_dqn.py, docs/learning.md "Write your
own objective"): it trains to task success >= 0.95 from both seats; an objective the run cannot use is one line,
exit code 2, and the run folder is left untouched."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.learning_helpers import ncbot

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "double_dqn.py"


@pytest.mark.slow
def test_the_documented_double_dqn_objective_trains_from_an_empty_folder(tmp_path: Path) -> None:
    """The default config's run, shortened to 32 batches (seed 0: task success 1.000 / 0.978 robot first / second,
    500 games each; ~14 CPU s of training)."""
    result = ncbot("train", "default", "--out", "run", "--no-progress", "logger.mcap=false",
                   f"loss.objective={EXAMPLE}:MaskedDoubleDQNLoss", "collector.total_frames=32768",
                   "collector.annealing_frames=16384", "eval.games=500", "eval.periodic_games=100", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "Warning" not in result.stderr, result.stderr  # e.g. TorchRL's "no target network updater"
    report = json.loads((tmp_path / "run" / "eval.json").read_text())
    assert report["first"]["task_success"] >= 0.95 and report["second"]["task_success"] >= 0.95
    config = (tmp_path / "run" / "config.yaml").read_text()
    assert f"objective: {EXAMPLE}:MaskedDoubleDQNLoss" in config  # the run folder names the class it learnt with


def test_an_objective_the_run_cannot_use_is_one_line_and_writes_nothing(tmp_path: Path) -> None:
    broken = tmp_path / "mine.py"
    broken.write_text("import torch\nclass MineLoss(torch.nn.Module):\n    pass\n")
    shaped = tmp_path / "shaped.py"
    shaped.write_text("from ncbot.modules.objectives.competitive_dqn import CompetitiveDQNLoss\n"
                      "class ShapedLoss(CompetitiveDQNLoss):\n    @property\n    def in_keys(self):\n"
                      "        return [*super().in_keys, ('next', 'shaped_reward')]\n")
    for objective, message in [(f"{broken}:MineLoss", "is not a TorchRL LossModule"),
                               (f"{tmp_path / 'absent.py'}:MineLoss", "not found"),
                               ("recurrent_dqn", "replays sequences and needs a recurrent network"),
                               (f"{shaped}:ShapedLoss", "reads ('next', 'shaped_reward'), which the replayed rows")]:
        result = ncbot("train", "default", "--out", str(tmp_path / "run"), f"loss.objective={objective}")
        assert result.returncode == 2, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("ncbot: error: ") and message in lines[0], result.stderr
        assert not any((tmp_path / "run" / name).exists() for name in ("run.json", "config.yaml", "checkpoints"))
