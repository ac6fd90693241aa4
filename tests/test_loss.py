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


# --- speed paths: the same numbers as the plain TorchRL calls, and bf16 as an opt-in ---------------------------------

def mlp_transitions(batch: int, n_features: int = 6, seed: int = 0) -> TensorDict:
    generator = torch.Generator().manual_seed(seed)
    next_mask = torch.rand(batch, N_ACTIONS, generator=generator) < 0.5
    next_mask[:, 0] = True
    terminated = torch.rand(batch, 1, generator=generator) < 0.3
    return TensorDict({
        "observation": torch.rand(batch, n_features, generator=generator),
        "action": torch.randint(0, N_ACTIONS, (batch,), generator=generator),
        "next": {"observation": torch.rand(batch, n_features, generator=generator), "action_mask": next_mask,
                 "reward": torch.randn(batch, 1, generator=generator), "terminated": terminated,
                 "done": terminated.clone()},
    }, batch_size=[batch])


def mlp_loss(precision: str = "fp32", double_dqn: bool = False) -> CompetitiveDQNLoss:
    from modules.qnet import seeded_init

    qnet = make_qnet(6, N_ACTIONS, [16, 16])
    seeded_init(qnet, 0)
    loss = CompetitiveDQNLoss(qnet, double_dqn=double_dqn, precision=precision)
    loss.make_value_estimator(gamma=0.9)
    return loss


@pytest.mark.parametrize("double_dqn", [False, True])
def test_plain_tensor_loss_is_the_tensordict_loss_bit_for_bit(double_dqn: bool) -> None:
    loss = mlp_loss(double_dqn=double_dqn)
    td = mlp_transitions(64)
    via_tensordict = loss(td.clone())["loss"]
    via_tensors, predicted, target = loss.td_loss(*loss.td_loss_inputs(td))
    assert torch.equal(via_tensors, via_tensordict)
    # and the target is TorchRL's own TD(0) estimate from the same next value
    next_value = loss.bootstrap_value(td["next", "observation"], td["next", "action_mask"])
    expected = loss.value_estimator.value_estimate(td.clone(), next_value=next_value).squeeze(-1)
    assert torch.equal(target, expected)


def test_target_pass_by_layers_equals_functional_call_and_follows_hard_updates() -> None:
    loss = mlp_loss()
    updater = make_target_updater(loss, "hard", period=1)
    observation = mlp_transitions(32)["observation"]
    target_params = loss.target_value_network_params
    with torch.no_grad():
        for p in loss.value_network_params.values(True, True):
            p.add_(0.1)
    swapped = {name: target_params.get(("module", "0", "module", *name.split("."))) for name in loss._qnet_param_names}
    reference = torch.func.functional_call(loss._qnet_tensor_module, swapped, (observation,))
    by_layers = loss._q_values(observation, target_params)
    assert torch.equal(by_layers, reference)
    online = loss._q_values(observation, loss.value_network_params)
    assert not torch.allclose(by_layers, online)  # the target still holds the old weights
    updater.step()
    assert torch.equal(loss._q_values(observation, target_params), online)


def test_bf16_runs_the_products_in_bfloat16_with_float32_weights_and_gradients() -> None:
    exact, fast = mlp_loss("fp32"), mlp_loss("bf16")
    td = mlp_transitions(256)
    loss_exact, predicted_exact, _ = exact.td_loss(*exact.td_loss_inputs(td))
    loss_fast, predicted_fast, _ = fast.td_loss(*fast.td_loss_inputs(td))
    assert predicted_fast.dtype == torch.float32 and loss_fast.dtype == torch.float32
    assert not torch.equal(predicted_fast, predicted_exact)  # really computed in bfloat16 ...
    assert torch.allclose(predicted_fast, predicted_exact, rtol=0.02, atol=0.02)  # ... to bfloat16 accuracy
    assert loss_fast.item() == pytest.approx(loss_exact.item(), rel=0.02)
    loss_fast.backward()
    for p in fast.value_network_params.values(True, True):
        assert p.dtype == torch.float32 and p.grad is not None and p.grad.dtype == torch.float32
    assert all(p.grad is None for p in fast.target_value_network_params.values(True, True))


def test_unknown_precision_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="precision 'fp16'.*'fp32', 'bf16'"):
        CompetitiveDQNLoss(make_qnet(3, N_ACTIONS, [4]), precision="fp16")


def _filled_buffers(size: int = 300, batch: int = 48):
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

    from pipelines.learner import make_replay_buffer

    fast = make_replay_buffer(size, batch)
    plain = TensorDictReplayBuffer(storage=LazyTensorStorage(size), batch_size=batch)
    for seed in range(3):  # 3 x 128 rows into 300 slots: the ring wraps
        rows = mlp_transitions(128, seed=seed)
        fast.extend(rows.clone())
        plain.extend(rows.clone())
    return fast, plain


def _without_stamps(batch: TensorDict) -> TensorDict:
    from pipelines.learner import WRITE_STAMP_KEY

    return batch.exclude(WRITE_STAMP_KEY)


def test_gather_storage_samples_the_same_batches_as_lazy_tensor_storage() -> None:
    fast, plain = _filled_buffers()
    for _ in range(3):
        torch.manual_seed(7)
        ours = fast.sample()
        torch.manual_seed(7)
        theirs = plain.sample()
        assert set(_without_stamps(ours).keys(True, True)) == set(theirs.keys(True, True))
        assert (_without_stamps(ours) == theirs).all()
    assert (fast[10:20] == plain[10:20]).all()  # slices and other reads go through TorchRL unchanged


def test_gather_storage_stamps_each_write_so_rewritten_slots_are_told_apart() -> None:
    from pipelines.learner import WRITE_STAMP_KEY

    fast, _ = _filled_buffers(size=300)  # writes of 128 rows: slots 0-127, 128-255, 256-299 + 0-83 (wrapped)
    stamps = fast.storage._write_stamps
    assert len(set(stamps[:84].tolist())) == 1 and len(set(stamps[84:128].tolist())) == 1
    assert stamps[0] != stamps[100] and stamps[0] != stamps[200]
    batch = fast.sample()
    assert torch.equal(batch[WRITE_STAMP_KEY], stamps[batch["index"]])


def test_gather_storage_state_round_trips_for_resume() -> None:
    from pipelines.learner import make_replay_buffer

    fast, _ = _filled_buffers()
    restored = make_replay_buffer(300, 48)
    restored.load_state_dict(fast.state_dict())
    assert len(restored) == len(fast)
    torch.manual_seed(3)
    ours = fast.sample()
    torch.manual_seed(3)
    assert (_without_stamps(restored.sample()) == _without_stamps(ours)).all()


def _learner(batch_size: int | None = None, **loss_settings):
    from modules.qnet import seeded_init
    from pipelines.config import RunConfig
    from pipelines.learner import Learner

    config = RunConfig()
    if batch_size is not None:
        config.buffer.batch_size = batch_size
    for key, value in loss_settings.items():
        setattr(config.loss, key, value)
    qnet = make_qnet(6, N_ACTIONS, [16, 16])
    seeded_init(qnet, 0)
    return Learner.from_config(qnet, config)


def _plain_torchrl_update(learner, batch: TensorDict) -> None:
    """The update as TorchRL's calls spell it: loss_module(batch), backward, clip, Adam, target updater."""
    loss = learner.loss_module(batch)["loss"]
    learner.optimizer.zero_grad(set_to_none=True)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(learner.loss_module.parameters(), learner.max_grad_norm, foreach=True)
    learner.optimizer.step()
    learner.target_updater.step()


@pytest.mark.parametrize("target_update", ["hard", "soft"])
def test_learner_update_with_target_cache_matches_the_plain_torchrl_update_bit_for_bit(target_update: str) -> None:
    """Learner.update on GatherStorage batches (plain tensors, cached bootstrap values across hard updates and slot
    rewrites) and the TorchRL calls on LazyTensorStorage batches give the same weights, update after update."""
    fast, plain = _learner(target_period=3, target_update=target_update), _learner(target_period=3,
                                                                                   target_update=target_update)
    assert (fast.target_cache is not None) == (target_update == "hard")
    fast_buffer, plain_buffer = _filled_buffers(size=300, batch=64)
    for step in range(12):
        if step % 4 == 3:  # new experience overwrites slots the cache has seen
            rows = mlp_transitions(100, seed=100 + step)
            fast_buffer.extend(rows.clone())
            plain_buffer.extend(rows.clone())
        torch.manual_seed(step)
        fast.update(fast_buffer.sample())
        torch.manual_seed(step)
        _plain_torchrl_update(plain, plain_buffer.sample())
        for a, b in zip(fast.loss_module.parameters(), plain.loss_module.parameters()):
            assert torch.equal(a, b), f"update {step}"
    if fast.target_cache is not None:  # the cache did skip target rows (64 samples over 300 slots revisit some)
        assert 0 < fast.target_cache.computed < fast.target_cache.looked_up == 12 * 64


@pytest.mark.parametrize("batch", [2, 64])
def test_update_many_draws_once_and_steps_exactly_like_one_draw_per_update(batch: int) -> None:
    """One sampling call of count x batch rows split in order = count calls of batch rows: same rows, same weights
    bit for bit (with the target cache at 64 rows, without it at the paper's batch of 2)."""
    once, each = _learner(target_period=3, batch_size=batch), _learner(target_period=3, batch_size=batch)
    assert (once.target_cache is None) == (batch < 64)
    once_buffer, _ = _filled_buffers(size=300, batch=batch)
    each_buffer, _ = _filled_buffers(size=300, batch=batch)
    torch.manual_seed(5)
    losses = once.update_many(once_buffer, 7)
    torch.manual_seed(5)
    expected = [each.update(each_buffer.sample()) for _ in range(7)]
    assert len(losses) == 7 and all(torch.equal(a, b) for a, b in zip(losses, expected))
    for a, b in zip(once.loss_module.parameters(), each.loss_module.parameters()):
        assert torch.equal(a, b)
    assert once.update_many(once_buffer, 0) == []


def test_target_cache_is_cleared_by_a_hard_update_and_by_loading_a_state() -> None:
    learner = _learner(target_period=2)
    buffer, _ = _filled_buffers(size=300, batch=64)
    cache = learner.target_cache
    learner.update(buffer.sample())
    assert (cache.stamps >= 0).any()
    learner.update(buffer.sample())  # the second step copies the online weights into the target
    assert (cache.stamps == -1).all()
    learner.update(buffer.sample())
    learner.load_state_dict(learner.state_dict())
    assert (cache.stamps == -1).all()


def test_target_cache_refuses_double_dqn() -> None:
    with pytest.raises(ValueError, match="double_dqn"):
        from modules.loss import TargetValueCache

        TargetValueCache(mlp_loss(double_dqn=True))
    assert _learner(double_dqn=True).target_cache is None


@pytest.mark.parametrize("stale_rows", [1, 2, 3, 5])
def test_target_cache_recomputes_a_few_stale_rows_with_the_bits_of_a_full_batch(stale_rows: int) -> None:
    """A handful of rewritten slots are recomputed alone; their values must equal those of the whole batch (MKL's
    products of 1-3 rows take another path, hence the padding)."""
    from modules.loss import TargetValueCache

    loss = mlp_loss()
    cache = TargetValueCache(loss)
    batch = mlp_transitions(64, seed=1)
    slots, stamps = torch.arange(64), torch.zeros(64, dtype=torch.long)
    next_observation, available = batch["next", "observation"], batch["next", "action_mask"]
    cache.lookup(slots, stamps, next_observation, available)
    rewritten = mlp_transitions(64, seed=2)
    next_observation = next_observation.clone()
    next_observation[:stale_rows] = rewritten["next", "observation"][:stale_rows]
    stamps[:stale_rows] = 1
    before = cache.computed
    cached = cache.lookup(slots, stamps, next_observation, available)
    assert cache.computed - before == stale_rows
    assert torch.equal(cached, loss.bootstrap_value(next_observation, available))
