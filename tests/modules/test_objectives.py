"""Objectives chosen by name (`loss.objective`): the built-ins, a user's class by import path, and one line for an
objective that does not import, is no TorchRL loss, lacks what the loop calls, or reads keys the replay lacks."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch
from torchrl.objectives import ValueEstimators

from ncbot.modules.networks.qnet import make_qnet
from ncbot.modules.objectives.competitive_dqn import CompetitiveDQNLoss
from ncbot.modules.objectives.names import default_objective, objective_name
from ncbot.modules.objectives.recurrent_dqn import RecurrentDQNLoss
from ncbot.modules.objectives.registry import build_objective, check_objective_keys, objective_class
from ncbot.modules.replay.transitions import BUFFER_KEYS, LOSS_KEYS

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "double_dqn.py"
KEYS = {**LOSS_KEYS, "priority": "td_error"}


def test_built_in_names_and_the_default_for_each_network() -> None:
    assert objective_class("competitive_dqn") is CompetitiveDQNLoss
    assert objective_class("recurrent_dqn") is RecurrentDQNLoss
    assert default_objective("none") == "competitive_dqn" and default_objective("gru") == "recurrent_dqn"
    assert CompetitiveDQNLoss.replays == "transitions" and RecurrentDQNLoss.replays == "sequences"


def test_a_users_class_loads_by_file_path_and_by_module_path(tmp_path: Path, monkeypatch) -> None:
    spec = f"{EXAMPLE}:MaskedDoubleDQNLoss"
    cls = objective_class(spec)
    assert cls.__name__ == "MaskedDoubleDQNLoss"
    monkeypatch.chdir(EXAMPLE.parent)
    assert objective_name("double_dqn.py:MaskedDoubleDQNLoss") == spec  # a config keeps the absolute path
    (tmp_path / "my_objectives.py").write_text(EXAMPLE.read_text())
    monkeypatch.syspath_prepend(str(tmp_path))
    assert objective_class("my_objectives:MaskedDoubleDQNLoss").__name__ == "MaskedDoubleDQNLoss"


def test_the_users_objective_is_built_wired_and_steps_like_the_built_in(tmp_path: Path) -> None:
    """Built as a run builds it: keys wired to the transitions', TD(0) estimator with the run's gamma, target
    parameters; its forward reads only what the replay stores and writes the priority."""
    cls = objective_class(f"{EXAMPLE}:MaskedDoubleDQNLoss")
    objective = build_objective(cls, "example", make_qnet(6, 4, [8]), {}, keys=KEYS, gamma=0.7)
    check_objective_keys(objective, "example", [*BUFFER_KEYS], prioritized=True)
    assert objective.tensor_keys.reward == "learning_reward" and objective.tensor_keys.bootstrap_mask == "bootstrap_mask"
    assert float(objective.value_estimator.gamma) == pytest.approx(0.7)
    from tests.modules.test_loss import mlp_transitions

    batch = mlp_transitions(8)  # the keys the replay buffer stores
    out = objective(batch)
    assert torch.isfinite(out["loss"]) and batch.get("td_error").shape == (8, 1)


def _write(tmp_path: Path, text: str) -> str:
    path = tmp_path / "objective.py"
    path.write_text(text)
    return f"{path}:BrokenLoss"


@pytest.mark.parametrize("text,message", [
    ("import not_a_module_anywhere\n", "does not import: ModuleNotFoundError"),
    ("def broken(:\n", "does not import: SyntaxError"),
    ("x = 1\n", "defines no 'BrokenLoss'"),
    ("class BrokenLoss:\n    pass\n", "is not a TorchRL LossModule"),
    ("from torchrl.objectives import LossModule\nclass BrokenLoss(LossModule):\n    def forward(self, td):\n"
     "        return td\n", "lacks make_value_estimator()"),
    ("from torchrl.objectives import LossModule\nclass BrokenLoss(LossModule):\n    def make_value_estimator(self, "
     "*a, **k):\n        pass\n", "lacks forward()"),
])
def test_an_objective_that_cannot_serve_is_one_line_naming_why(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message) as error:
        objective_class(_write(tmp_path, text))
    assert "\n" not in str(error.value)


def test_missing_file_and_bad_names_are_one_line() -> None:
    with pytest.raises(ValueError, match="not found"):
        objective_class("/nowhere/objective.py:XLoss")
    with pytest.raises(ValueError, match="competitive_dqn, recurrent_dqn or an import path"):
        objective_name("dqn")


def test_an_objective_reading_keys_the_replay_lacks_is_refused() -> None:
    objective = build_objective(CompetitiveDQNLoss, "competitive_dqn", make_qnet(6, 4, [8]), {}, keys=KEYS, gamma=0.7)
    objective.set_keys(reward="shaped_reward")  # a key no transition holds
    with pytest.raises(ValueError, match="reads \\('next', 'shaped_reward'\\), which the replayed rows do not hold"):
        check_objective_keys(objective, "competitive_dqn", BUFFER_KEYS, prioritized=False)


def test_a_transition_objective_refuses_sequence_estimators_in_one_line() -> None:
    with pytest.raises(ValueError, match="objective competitive_dqn .*TD\\(1\\) and TD\\(lambda\\) need whole "
                                         "sequences") as error:
        build_objective(CompetitiveDQNLoss, "competitive_dqn", make_qnet(6, 4, [8]), {}, keys=KEYS,
                        value_estimator="td_lambda", gamma=0.7, lmbda=0.9)
    assert "\n" not in str(error.value)
    loss = CompetitiveDQNLoss(make_qnet(6, 4, [8]))
    loss.make_value_estimator(ValueEstimators.TD0, gamma=0.5)
    assert loss.value_type is ValueEstimators.TD0


def test_the_documented_double_dqn_is_the_built_in_double_dqn_bit_for_bit() -> None:
    """docs/examples/double_dqn.py, written on TorchRL's public API alone, steps exactly like competitive_dqn with
    loss.double_dqn: the same losses, TD errors and weights through target updates."""
    from ncbot.modules.learner import Learner
    from ncbot.modules.networks.qnet import seeded_init
    from ncbot.pipelines.config import RunConfig
    from tests.modules.test_loss import _filled_buffer

    config = RunConfig()
    config.loss.double_dqn, config.loss.target_period = True, 3
    learners = []
    for cls, options in [(objective_class(f"{EXAMPLE}:MaskedDoubleDQNLoss"), {}),
                         (CompetitiveDQNLoss, {"double_dqn": True})]:
        qnet = make_qnet(6, 4, [16, 16])
        seeded_init(qnet, 0)
        objective = build_objective(cls, cls.__name__, qnet, options, keys=KEYS, gamma=0.7)
        learners.append(Learner.build(objective, optim=config.optim, loss=config.loss))
    buffer = _filled_buffer(batch=16)
    for _ in range(6):
        batch = buffer.sample()
        plugin, built_in = (learner.update(batch.clone()) for learner in learners)
        assert torch.equal(plugin, built_in)
    for a, b in zip(*(learner.objective.parameters() for learner in learners)):
        assert torch.equal(a, b)
