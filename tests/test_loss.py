"""CompetitiveDQNLoss targets on hand-made transitions: terminal, masked max over available actions, double DQN."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn

from modules.loss import CompetitiveDQNLoss, make_target_updater
from modules.qnet import make_qnet

torch.set_num_threads(1)
N_ACTIONS = 4


class TableQ(nn.Module):
    """Q(s, .) read from a learnable table indexed by a one-hot observation: exact, hand-checkable values."""

    def __init__(self, table: torch.Tensor) -> None:
        super().__init__()
        self.table = nn.Parameter(table.clone())

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        return observation @ self.table


def one_hot_states(indices: list[int], n_states: int = 3) -> torch.Tensor:
    return torch.nn.functional.one_hot(torch.tensor(indices), n_states).float()


def transitions(*, reward, terminated, next_mask, state=(0, 0), next_state=(1, 1), action=None) -> TensorDict:
    batch = len(reward)
    action = action if action is not None else (0,) * batch
    next_mask = torch.tensor(next_mask)
    return TensorDict(
        {
            "observation": one_hot_states(list(state)),
            "action_mask": torch.ones(batch, N_ACTIONS, dtype=torch.bool),
            "action": torch.tensor(action),
            "next": {
                "observation": one_hot_states(list(next_state)),
                "action_mask": next_mask,
                "reward": torch.tensor(reward, dtype=torch.float32).unsqueeze(-1),
                "terminated": torch.tensor(terminated).unsqueeze(-1),
                "done": torch.tensor(terminated).unsqueeze(-1),
                "truncated": torch.zeros(batch, 1, dtype=torch.bool),
            },
        },
        batch_size=[batch],
    )


def table_loss(table: torch.Tensor, *, double_dqn: bool = False, gamma: float = 0.5) -> CompetitiveDQNLoss:
    qnet = TensorDictModule(TableQ(table), in_keys=["observation"], out_keys=["action_value"])
    loss = CompetitiveDQNLoss(qnet, loss_function="l2", double_dqn=double_dqn)
    loss.make_value_estimator(gamma=gamma)
    return loss


TABLE = torch.tensor(
    [
        [1.0, 2.0, 3.0, 4.0],  # s0
        [10.0, 50.0, -3.0, 7.0],  # s1: the best action overall is 1, masked out below
        [0.0, 0.0, 0.0, 0.0],
    ]
)


def test_terminal_target_is_reward_alone() -> None:
    loss = table_loss(TABLE)
    td = transitions(reward=[5.0, -5.0], terminated=[True, True], next_mask=[[True] * 4, [True] * 4])
    out = loss(td)
    # y = r; Q(s0, a0) = 1 -> squared errors (5-1)^2 and (-5-1)^2
    assert out["loss"].item() == pytest.approx(((5 - 1) ** 2 + (-5 - 1) ** 2) / 2)
    assert out["target_mean"].item() == pytest.approx(0.0)


def test_bootstrap_maximises_only_over_available_next_actions() -> None:
    loss = table_loss(TABLE, gamma=0.5)
    td = transitions(
        reward=[1.0, 1.0],
        terminated=[False, False],
        next_mask=[[True, False, True, True], [False, False, True, False]],
    )
    out = loss(td)
    # row 0: max over {10, -3, 7} = 10 (not the masked 50) -> y = 1 + 0.5 * 10 = 6
    # row 1: only action 2 -> y = 1 + 0.5 * -3 = -0.5
    expected_targets = torch.tensor([6.0, -0.5])
    assert out["target_mean"].item() == pytest.approx(expected_targets.mean().item())
    assert out["loss"].item() == pytest.approx(((expected_targets - 1.0) ** 2).mean().item())
    # td_error written for prioritised replay
    assert torch.allclose(td["td_error"].squeeze(-1), (expected_targets - 1.0).abs())


def test_loss_is_on_q_of_the_taken_action() -> None:
    loss = table_loss(TABLE)
    td = transitions(reward=[0.0], terminated=[True], next_mask=[[True] * 4], state=(0,), next_state=(1,), action=(3,))
    assert loss(td)["loss"].item() == pytest.approx(16.0)  # (0 - Q(s0, a3)=4)^2


def test_target_uses_target_network_until_hard_update() -> None:
    loss = table_loss(TABLE, gamma=1.0)
    updater = make_target_updater(loss, "hard", period=2)
    td = transitions(reward=[0.0], terminated=[False], next_mask=[[True] * 4], state=(0,), next_state=(1,))
    with torch.no_grad():
        loss.value_network_params["module", "0", "module", "table"].data.zero_()
    assert loss(td.clone())["target_mean"].item() == pytest.approx(50.0)  # target still holds the old table
    updater.step()
    assert loss(td.clone())["target_mean"].item() == pytest.approx(50.0)  # period 2: not yet
    updater.step()
    assert loss(td.clone())["target_mean"].item() == pytest.approx(0.0)


def test_double_dqn_online_picks_target_scores() -> None:
    loss = table_loss(TABLE, gamma=1.0, double_dqn=True)
    online = TABLE.clone()
    online[1] = torch.tensor([0.0, 100.0, 9.0, 1.0])  # online prefers a1 (masked) then a2
    with torch.no_grad():
        loss.value_network_params["module", "0", "module", "table"].data.copy_(online)
    td = transitions(
        reward=[0.0], terminated=[False], next_mask=[[True, False, True, True]], state=(0,), next_state=(1,)
    )
    # online argmax over available {0, 2, 3} = a2; the target network scores it Q_target(s1, a2) = -3
    assert loss(td)["target_mean"].item() == pytest.approx(-3.0)
    plain = table_loss(TABLE, gamma=1.0)
    assert plain(td.clone())["target_mean"].item() == pytest.approx(10.0)


def test_gradient_flows_only_through_online_network_and_soft_update_moves_target() -> None:
    torch.manual_seed(0)
    qnet = make_qnet(3, N_ACTIONS, [8])
    loss = CompetitiveDQNLoss(qnet, loss_function="huber")
    loss.make_value_estimator(gamma=0.7)
    updater = make_target_updater(loss, "soft", tau=0.5)
    td = transitions(reward=[1.0, 0.0], terminated=[False, True], next_mask=[[True] * 4, [True] * 4])
    before = [p.clone() for p in loss.target_value_network_params.values(True, True)]
    out = loss(td)
    out["loss"].backward()
    grads = [p.grad for p in loss.value_network_params.values(True, True)]
    assert all(g is not None and torch.isfinite(g).all() for g in grads)
    with torch.no_grad():
        for p in loss.value_network_params.values(True, True):
            p.add_(1.0)
    updater.step()
    after = list(loss.target_value_network_params.values(True, True))
    assert all(not torch.allclose(a, b) for a, b in zip(after, before))


def test_bad_target_updater_settings_are_clear_errors() -> None:
    loss = table_loss(TABLE)
    with pytest.raises(ValueError, match="target_period"):
        make_target_updater(loss, "hard", period=0)
    with pytest.raises(ValueError, match="'hard' or 'soft'"):
        make_target_updater(loss, "polyak")


def test_unknown_loss_function_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="loss_function"):
        CompetitiveDQNLoss(make_qnet(3, N_ACTIONS, [4]), loss_function="l3")
