"""CompetitiveDQNLoss targets on hand-made transitions: terminal, masked max over available actions, double DQN."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn

from ncbot.modules.networks.qnet import make_qnet
from ncbot.modules.objectives.common import make_target_updater
from ncbot.modules.objectives.competitive_dqn import CompetitiveDQNLoss

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


# --- the keys training wires, bf16, and the Learner's update -----------------------------------------------------

def mlp_transitions(batch: int, n_features: int = 6, seed: int = 0) -> TensorDict:
    """Transitions as prepare_transitions stores them: learning reward and bootstrap mask under their own keys."""
    generator = torch.Generator().manual_seed(seed)
    next_mask = torch.rand(batch, N_ACTIONS, generator=generator) < 0.5
    next_mask[:, 0] = True
    terminated = torch.rand(batch, 1, generator=generator) < 0.3
    return TensorDict({
        "observation": torch.rand(batch, n_features, generator=generator),
        "action": torch.randint(0, N_ACTIONS, (batch,), generator=generator),
        "next": {"observation": torch.rand(batch, n_features, generator=generator), "bootstrap_mask": next_mask,
                 "learning_reward": torch.randn(batch, 1, generator=generator), "terminated": terminated,
                 "done": terminated.clone(), "truncated": torch.zeros(batch, 1, dtype=torch.bool)},
    }, batch_size=[batch])


def mlp_loss(precision: str = "fp32", double_dqn: bool = False) -> CompetitiveDQNLoss:
    """The loss as training builds it: keys wired to the transitions' (`LOSS_KEYS`), TD(0) estimator."""
    from ncbot.modules.networks.qnet import seeded_init
    from ncbot.modules.replay.transitions import LOSS_KEYS

    qnet = make_qnet(6, N_ACTIONS, [16, 16])
    seeded_init(qnet, 0)
    loss = CompetitiveDQNLoss(qnet, double_dqn=double_dqn, precision=precision)
    loss.set_keys(**LOSS_KEYS)
    loss.make_value_estimator(gamma=0.9)
    return loss


def _expected_target(loss: CompetitiveDQNLoss, td: TensorDict, gamma: float = 0.9) -> torch.Tensor:
    """y written out by hand: the target network's Q (functional_call on the target weights), masked max."""
    names = [name for name, _ in loss.value_network[0].module.named_parameters()]
    target = {name: loss.target_value_network_params.get(("module", "0", "module", *name.split(".")))
              for name in names}
    next_q = torch.func.functional_call(loss.value_network[0].module, target, (td["next", "observation"],))
    best = next_q.masked_fill(~td["next", "bootstrap_mask"], torch.finfo(next_q.dtype).min).max(-1).values
    return td["next", "learning_reward"].squeeze(-1) + gamma * (~td["next", "terminated"].squeeze(-1)) * best


def test_set_keys_wires_the_learning_reward_and_the_bootstrap_mask() -> None:
    """Training reads ("next", "learning_reward") and maximises over ("next", "bootstrap_mask"); the env's
    ("next", "reward") and ("next", "action_mask"), present with other values, are not read."""
    loss = mlp_loss()
    td = mlp_transitions(64)
    td["next", "reward"] = torch.full((64, 1), 100.0)
    td["next", "action_mask"] = torch.ones(64, N_ACTIONS, dtype=torch.bool)
    out = loss(td)
    expected = _expected_target(loss, td)
    assert out["target_mean"].item() == pytest.approx(expected.mean().item(), abs=1e-5)
    with torch.no_grad():
        q = loss.value_network[0](td.select("observation"))["action_value"]
    predicted = q.gather(-1, td["action"].unsqueeze(-1)).squeeze(-1)
    assert torch.allclose(td["td_error"].squeeze(-1), (predicted - expected).abs(), atol=1e-5)


def test_steps_to_next_obs_discounts_the_bootstrap_by_gamma_to_the_window_length() -> None:
    """n-step transitions (TorchRL's MultiStepTransform writes `steps_to_next_obs`) bootstrap with gamma^k."""
    loss = mlp_loss()
    td = mlp_transitions(32)
    td["next", "terminated"] = torch.zeros(32, 1, dtype=torch.bool)
    one_step = loss(td.clone())["target_mean"]
    td["steps_to_next_obs"] = torch.full((32,), 3, dtype=torch.long)
    bootstrap = (_expected_target(loss, td) - td["next", "learning_reward"].squeeze(-1)) / 0.9
    three_steps = (td["next", "learning_reward"].squeeze(-1) + 0.9 ** 3 * bootstrap).mean()
    assert loss(td)["target_mean"].item() == pytest.approx(three_steps.item(), abs=1e-5)
    assert one_step.item() != pytest.approx(three_steps.item(), abs=1e-3)


def test_bf16_runs_the_products_in_bfloat16_with_float32_weights_and_gradients() -> None:
    exact, fast = mlp_loss("fp32"), mlp_loss("bf16")
    td = mlp_transitions(256)
    out_exact, out_fast = exact(td.clone()), fast(td.clone())
    assert out_fast["loss"].dtype == torch.float32
    assert out_fast["q_mean"].item() != out_exact["q_mean"].item()  # really computed in bfloat16 ...
    assert out_fast["q_mean"].item() == pytest.approx(out_exact["q_mean"].item(), rel=0.02, abs=0.02)  # ... roughly
    assert out_fast["loss"].item() == pytest.approx(out_exact["loss"].item(), rel=0.02)
    out_fast["loss"].backward()
    for p in fast.value_network_params.values(True, True):
        assert p.dtype == torch.float32 and p.grad is not None and p.grad.dtype == torch.float32
    assert all(p.grad is None for p in fast.target_value_network_params.values(True, True))


def test_unknown_precision_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="precision 'fp16'.*'fp32', 'bf16'"):
        CompetitiveDQNLoss(make_qnet(3, N_ACTIONS, [4]), precision="fp16")


def _filled_buffer(size: int = 300, batch: int = 48):
    from ncbot.modules.replay.buffer import make_replay_buffer

    buffer = make_replay_buffer(size, batch)
    for seed in range(3):  # 3 x 128 rows into 300 slots: the ring wraps
        buffer.extend(mlp_transitions(128, seed=seed))
    return buffer


def _learner(batch_size: int | None = None, **loss_settings):
    from ncbot.modules.learner import Learner
    from ncbot.modules.networks.qnet import seeded_init
    from ncbot.pipelines.config import RunConfig
    from ncbot.pipelines.train.build import make_objective

    config = RunConfig()
    if batch_size is not None:
        config.buffer.batch_size = batch_size
    for key, value in loss_settings.items():
        setattr(config.loss, key, value)
    qnet = make_qnet(6, N_ACTIONS, [16, 16])
    seeded_init(qnet, 0)
    objective, _ = make_objective(config, qnet)
    return Learner.build(objective, optim=config.optim, loss=config.loss)


@pytest.mark.parametrize("target_update", ["hard", "soft"])
def test_learner_update_is_the_torchrl_update_written_out(target_update: str) -> None:
    """Learner.update = objective(td), backward, clip, Adam, target updater: the same weights, update after update,
    as those calls written out here (and the target follows the updater)."""
    learner, reference = _learner(target_period=3, target_update=target_update), \
        _learner(target_period=3, target_update=target_update)
    buffer = _filled_buffer(batch=64)
    for step in range(8):
        batch = buffer.sample()
        learner.update(batch.clone())
        loss = reference.objective(batch.clone())["loss"]
        reference.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(reference.objective.parameters(), reference.max_grad_norm, foreach=True)
        reference.optimizer.step()
        reference.target_updater.step()
        for a, b in zip(learner.objective.parameters(), reference.objective.parameters()):
            assert torch.equal(a, b), f"update {step}"
    targets = list(learner.objective.target_value_network_params.values(True, True))
    online = list(learner.objective.value_network_params.values(True, True))
    assert not all(torch.equal(a, b) for a, b in zip(targets, online))  # 8 updates: not a copy after the 8th (hard)


@pytest.mark.parametrize("batch", [2, 64])
def test_update_many_draws_once_and_steps_exactly_like_one_draw_per_update(batch: int) -> None:
    """One sampling call of count x batch rows split in order = count calls of batch rows: same rows, same weights
    bit for bit."""
    once, each = _learner(target_period=3, batch_size=batch), _learner(target_period=3, batch_size=batch)
    once_buffer, each_buffer = _filled_buffer(batch=batch), _filled_buffer(batch=batch)
    torch.manual_seed(5)
    losses = once.update_many(once_buffer, 7)
    torch.manual_seed(5)
    expected = [each.update(each_buffer.sample()) for _ in range(7)]
    assert len(losses) == 7 and all(torch.equal(a, b) for a, b in zip(losses, expected))
    for a, b in zip(once.objective.parameters(), each.objective.parameters()):
        assert torch.equal(a, b)
    assert once.update_many(once_buffer, 0) == []


@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_the_estimator_runs_the_target_network_on_the_target_parameters(precision: str) -> None:
    """TorchRL's TD(0) estimator runs the target network (the value network bound to the target parameters) on the
    next states: its target is the hand-written one (target weights, masked max) and the one TorchRL's swap of the
    target parameters into the value network gives, bit for bit, through hard updates and with masks that hide the
    best action; the target network adds no parameter and no state_dict key."""
    from torchrl.envs.utils import step_mdp

    learner, buffer = _learner(target_period=3), _filled_buffer(batch=8)
    loss = learner.objective
    loss.precision = precision  # (optim.precision in a config)
    for _ in range(5):
        learner.update(buffer.sample())
        batch = buffer.sample()
        assert not batch.get(("next", "bootstrap_mask")).all()  # some next actions masked out
        with torch.no_grad(), loss._matmul_precision():
            estimated = loss.value_estimator.value_estimate(batch.clone())
            with loss.target_value_network_params.to_module(loss.value_network):
                swapped = loss.value_network(step_mdp(batch, keep_other=False))["bootstrap_value"]
            expected = _expected_target(loss, batch, gamma=0.7)
        assert torch.equal(estimated, loss.value_estimator.value_estimate(batch.clone(), next_value=swapped))
        assert torch.allclose(estimated.squeeze(-1), expected, atol=0.05 if precision == "bf16" else 1e-6)
    online = list(learner.objective.parameters())
    assert len(online) == 6 and all(p.requires_grad for p in online)
    assert not any("target" in name for name, _ in learner.objective.named_parameters())
    assert all(key.startswith(("value_network_params.", "target_value_network_params.", "_value_estimator.gamma"))
               for key in learner.objective.state_dict())


def test_the_target_network_follows_the_target_parameters_when_the_loss_moves() -> None:
    """Moving the loss (`.double()`, `.to(device)`) gives the target parameters new tensors: the target network
    runs on them from the next forward on, and its targets stay the hand-written ones."""
    loss = mlp_loss()
    td = mlp_transitions(16)
    with torch.no_grad():
        for weight in loss.target_value_network_params.values(True, True):
            weight.add_(0.5)  # targets that differ from the online network's
    loss.double()
    batch = td.apply(lambda x: x.double() if x.is_floating_point() else x)
    out = loss(batch)
    expected = _expected_target(loss, batch)
    assert out["target_mean"].dtype == torch.float64
    assert out["target_mean"].item() == pytest.approx(expected.mean().item(), abs=1e-9)
