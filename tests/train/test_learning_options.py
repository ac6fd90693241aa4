"""`schedule.lr_end`: the learning rate decays linearly over the training frames, and a tiny real run ends with the
optimiser at (or next to) lr_end; bad values stop with one line naming the key."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from ncbot.pipelines.checkpoint import latest_training_state
from ncbot.pipelines.config import load_config
from ncbot.modules.learner import scheduled_lr
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)
CONFIGS = Path(__file__).resolve().parents[2] / "pipelines" / "configs"


def _lr(config, frames: int) -> float:
    return scheduled_lr(frames, config.optim.lr, config.schedule.lr_end, config.collector.total_frames)


def test_schedule_is_linear_from_lr_to_lr_end_and_constant_without_it() -> None:
    config = load_config(CONFIGS / "default.yaml", ["optim.lr=0.001", "schedule.lr_end=0.0001",
                                                    "collector.total_frames=1000"])
    assert _lr(config, 0) == pytest.approx(0.001)
    assert _lr(config, 500) == pytest.approx(0.00055)
    assert _lr(config, 1000) == pytest.approx(0.0001)
    assert _lr(config, 5000) == pytest.approx(0.0001)  # past the end: stays at lr_end
    constant = load_config(CONFIGS / "default.yaml", ["optim.lr=0.001", "schedule.lr_end=null"])
    assert _lr(constant, 10**6) == pytest.approx(0.001)


@pytest.mark.parametrize("value", ["0", "-0.1", "0.5"])
def test_lr_end_must_be_positive_and_not_above_lr(value: str) -> None:
    with pytest.raises(ValueError, match="schedule.lr_end"):
        load_config(CONFIGS / "default.yaml", ["optim.lr=0.001", f"schedule.lr_end={value}"])


def test_a_real_run_ends_with_the_decayed_learning_rate(tmp_path: Path) -> None:
    config = load_config(write_tiny_config(tmp_path), ["optim.lr=0.001", "schedule.lr_end=0.0002"])
    train(config, tmp_path / "run")
    state = torch.load(tmp_path / "run" / "checkpoint.pt", weights_only=True)
    assert state["frames"] == config.collector.total_frames
    last = latest_training_state(tmp_path / "run")
    lrs = [group["lr"] for group in last["learner"]["optimizer"]["param_groups"]]
    assert lrs == pytest.approx([_lr(config, last["frames"])] * len(lrs))
    assert lrs == pytest.approx([0.0002] * len(lrs))  # the last periodic checkpoint is at the end of training


def _transitions(before: list[int], after: list[int], mask_ok: list[bool]) -> "TensorDict":
    from tensordict import TensorDict

    n = len(before)
    mask = torch.ones(n, 18, dtype=torch.bool)
    mask[:, 0] = torch.tensor(mask_ok)
    return TensorDict({
        "outcome": torch.tensor(before).unsqueeze(-1), "action": torch.zeros(n, dtype=torch.long), "action_mask": mask,
        ("next", "outcome"): torch.tensor(after).unsqueeze(-1), ("next", "reward"): torch.zeros(n, 1),
    }, batch_size=[n])


def test_loss_reward_prices_only_lost_games() -> None:
    from ncbot.modules.replay.rewards import OUTCOME_DRAW, OUTCOME_HUMAN_WON, OUTCOME_NONE, OUTCOME_ROBOT_WON, learning_rewards

    none, won, lost, draw = OUTCOME_NONE, OUTCOME_ROBOT_WON, OUTCOME_HUMAN_WON, OUTCOME_DRAW
    batch = _transitions([none, none, none, none, lost, none], [won, lost, draw, none, lost, none],
                         [True, True, True, True, True, False])
    result = learning_rewards(batch, "outcome", loss_reward=-20.0)
    rewards = result.get(("next", "learning_reward")).flatten()
    # win, loss (re-priced), draw, game goes on, already over, act outside the mask (keeps -5)
    assert rewards.tolist() == [5.0, -20.0, 1.0, 0.0, 0.0, -5.0]
    assert (result.get(("next", "reward")) == 0).all()  # the env's reward keeps its meaning
    paper = learning_rewards(batch, "paper").get(("next", "learning_reward"))
    assert torch.equal(paper, batch.get(("next", "reward")))


def test_loss_reward_must_be_negative() -> None:
    with pytest.raises(ValueError, match="loss.loss_reward"):
        load_config(CONFIGS / "default.yaml", ["loss.loss_reward=1"])
