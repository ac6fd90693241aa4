"""Look-ahead masks (A, A_hat, fallback) and the greedy / epsilon-greedy policies on hand-made TensorDicts."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.data import Categorical

from ncbot.modules.policies.masks import AGENT_LOOKAHEAD, LookaheadMasks, lookahead_rule, one_step_lookahead, variant_lookahead
from ncbot.modules.policies.policy import make_policies

torch.set_num_threads(1)
N = 5


def row(values: list[int]) -> torch.Tensor:
    return torch.tensor([values], dtype=torch.bool)


def rewards(values: list[float]) -> torch.Tensor:
    return torch.tensor([values], dtype=torch.float32)


def test_proposed_forces_winning_actions_and_drops_negative_ones() -> None:
    available = row([1, 1, 1, 1, 0])
    reward = rewards([0, 5, -5, 5, 5])  # a4 would win but is unavailable
    winning = row([0, 1, 0, 1, 1])
    explore, greedy = one_step_lookahead(available, reward, winning)
    assert explore.tolist() == [[False, True, False, True, False]]  # A = winning & available
    assert greedy.tolist() == [[False, True, False, True, False]]


def test_proposed_without_wins_excludes_a_hat_from_greedy_only() -> None:
    available = row([1, 1, 1, 0, 1])
    reward = rewards([0, -5, 1, 0, -5])
    winning = row([0, 0, 0, 0, 0])
    explore, greedy = one_step_lookahead(available, reward, winning)
    assert explore.tolist() == available.tolist()  # A = available
    assert greedy.tolist() == [[True, False, True, False, False]]  # A minus A_hat


def test_proposed_falls_back_to_a_when_every_action_is_negative() -> None:
    available = row([0, 1, 1, 0, 0])
    reward = rewards([0, -5, -5, 0, 0])
    explore, greedy = one_step_lookahead(available, reward, row([0] * N))
    assert greedy.tolist() == available.tolist()


def test_variant_skips_only_the_actions_tied_for_the_lowest_negative_reward() -> None:
    available = row([1, 1, 1, 1, 1])
    reward = rewards([-5, -1, 0, -5, 5])
    explore, greedy = variant_lookahead(available, reward, row([0, 0, 0, 0, 1]))
    assert explore.tolist() == available.tolist()  # no win-forcing, exploration unchanged
    assert greedy.tolist() == [[False, True, True, False, True]]
    # lowest reward not negative: nothing is skipped
    _, greedy = variant_lookahead(available, rewards([0, 1, 0, 5, 1]), row([0] * N))
    assert greedy.tolist() == available.tolist()
    # all available tied at the lowest negative: fall back to available
    _, greedy = variant_lookahead(row([1, 1, 0, 0, 0]), rewards([-5, -5, 5, 5, 5]), row([0] * N))
    assert greedy.tolist() == [[True, True, False, False, False]]


def test_original_uses_available_actions_for_both() -> None:
    available = row([1, 0, 1, 1, 0])
    explore, greedy = lookahead_rule("none")(available, rewards([-5, 0, 5, 0, 0]), row([0, 0, 1, 0, 0]))
    assert explore.tolist() == greedy.tolist() == available.tolist()


def test_unknown_lookahead_names_the_choices() -> None:
    with pytest.raises(ValueError, match="one_step"):
        LookaheadMasks("two_step_magic")
    assert set(AGENT_LOOKAHEAD) == {"dqn_original", "dqn_variant", "proposed", "uniform"}
    assert AGENT_LOOKAHEAD["uniform"] == AGENT_LOOKAHEAD["proposed"]  # no learning inside Proposed's masks


class FixedQ(nn.Module):
    def __init__(self, q: list[float]) -> None:
        super().__init__()
        self.q = nn.Parameter(torch.tensor(q))

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        return self.q.expand(observation.shape[0], -1)


def batch(available, reward, winning, size: int = 1) -> TensorDict:
    return TensorDict(
        {
            "observation": torch.zeros(size, 3),
            "action_mask": row(available).expand(size, -1).clone(),
            "lookahead_reward": rewards(reward).expand(size, -1).clone(),
            "winning_actions": row(winning).expand(size, -1).clone(),
        },
        batch_size=[size],
    )


def policies(q: list[float], lookahead: str, eps: float = 1.0):
    qnet = TensorDictModule(FixedQ(q), in_keys=["observation"], out_keys=["action_value"])
    return make_policies(qnet, Categorical(N), lookahead, eps_init=eps, eps_end=eps, annealing_frames=1)


def test_greedy_policy_takes_best_q_outside_a_hat_and_keeps_raw_q_values() -> None:
    q = [9.0, 8.0, 1.0, 7.0, 0.0]
    td = batch([1, 1, 1, 1, 1], [-5, 0, 0, 0, -5], [0, 0, 0, 0, 0])
    out = policies(q, "one_step").greedy(td)
    assert out["action"].item() == 1  # a0 has the best Q but is in A_hat
    assert out["action_value"].tolist() == [q]  # raw Q-values untouched for the logger
    assert out["chosen_action_value"].item() == 8.0
    # DQN-Original would take a0 regardless of its -5 one-step reward
    assert policies(q, "none").greedy(batch([1, 1, 1, 1, 1], [-5, 0, 0, 0, -5], [0] * 5))["action"].item() == 0


def test_epsilon_greedy_samples_uniformly_inside_a() -> None:
    torch.manual_seed(0)
    td = batch([1, 1, 1, 1, 0], [0, 5, 0, 5, 5], [0, 1, 0, 1, 1], size=4000)
    actions = policies([0.0] * N, "one_step", eps=1.0).explore(td)["action"]
    counts = torch.bincount(actions, minlength=N)
    assert counts[[0, 2, 4]].sum() == 0  # only the available winning actions a1, a3
    assert abs(counts[1].item() - counts[3].item()) < 300
    # DQN-Original explores over every available action
    actions = policies([0.0] * N, "none", eps=1.0).explore(td)["action"]
    assert set(torch.unique(actions).tolist()) == {0, 1, 2, 3}


def test_epsilon_anneals_with_frames() -> None:
    qnet = TensorDictModule(FixedQ([0.0] * N), in_keys=["observation"], out_keys=["action_value"])
    agent = make_policies(qnet, Categorical(N), "one_step", eps_init=1.0, eps_end=0.1, annealing_frames=100)
    agent.egreedy.step(50)
    assert agent.egreedy.eps.item() == pytest.approx(0.55)
    agent.egreedy.step(100)
    assert agent.egreedy.eps.item() == pytest.approx(0.1)
