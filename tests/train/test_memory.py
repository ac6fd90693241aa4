"""agent.memory (modules/networks/recurrent.py) with real TorchRL parts: the hidden state runs through a dialogue and
restarts with the next, replayed slices stay inside one dialogue, the loss unrolls them as the actor stepped,
a tiny recurrent run trains, checkpoints and evaluates, and memory none changes nothing."""
from __future__ import annotations

import json
import types
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from ncbot.envs import make_env
from ncbot.modules.learner import Learner
from ncbot.modules.networks.recurrent import IS_INIT_KEY, make_agent_qnet, memory_env, unroll_in_recurrent_mode
from ncbot.modules.objectives.common import make_target_updater
from ncbot.modules.objectives.recurrent_dqn import RecurrentDQNLoss
from ncbot.modules.policies.policy import make_policies
from ncbot.modules.replay.prioritized_slices import sequence_priority
from ncbot.modules.replay.sequences import EPISODE_KEY, STEP_KEY, VALID_KEY, SequenceRows, make_sequence_buffer
from ncbot.modules.replay.transitions import LOSS_KEYS, prepare_transitions
from ncbot.pipelines.checkpoint import load_checkpoint
from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.build import make_collector
from ncbot.pipelines.train.run import train
from tests.learning_helpers import ncbot, write_tiny_config

torch.set_num_threads(1)

MEMORY = {"buffer": {"sequence_length": 8, "burn_in": 2}}


def _agent(memory: str = "gru", hidden=(16,), size: int = 8):
    return types.SimpleNamespace(hidden=list(hidden), memory=memory, memory_size=size)


def _network(memory: str = "gru", game: str = "standard", **env_options):
    env = make_env(game=game, batch_size=(4,), seed=0, first="alternate", **env_options)
    qnet = make_agent_qnet(env.n_features, env.n_actions, _agent(memory), seed=0)
    return env, qnet


def _steps(qnet, observations: torch.Tensor, first_is_init: bool = True) -> torch.Tensor:
    """Q-values of `qnet` stepped one observation at a time (acting mode), carrying its state; (T, A)."""
    state_keys = [key for key in qnet.in_keys if key not in ("observation", IS_INIT_KEY)]
    td = TensorDict({"observation": observations[:1], IS_INIT_KEY: torch.tensor([[first_is_init]])}, batch_size=[1])
    out = []
    for t in range(observations.shape[0]):
        td.set("observation", observations[t:t + 1])
        qnet(td)
        out.append(td.get("action_value")[0].clone())
        td.set(IS_INIT_KEY, torch.tensor([[False]]))
        for key in state_keys:
            td.set(key, td.get(("next", key)))
    return torch.stack(out)


@pytest.mark.parametrize("memory", ["gru", "lstm"])
def test_history_changes_q_and_a_new_game_resets_it(memory: str) -> None:
    env, qnet = _network(memory)
    generator = torch.Generator().manual_seed(1)
    x = torch.rand(1, env.n_features, generator=generator)
    history_a = torch.rand(3, env.n_features, generator=generator)
    history_b = torch.rand(3, env.n_features, generator=generator)
    with torch.no_grad():
        after_a = _steps(qnet, torch.cat([history_a, x]))[-1]
        after_b = _steps(qnet, torch.cat([history_b, x]))[-1]
        fresh = _steps(qnet, x)[-1]
        # the same observation after two different histories: different Q-values (the state is carried) ...
        assert not torch.allclose(after_a, after_b)
        assert not torch.allclose(after_a, fresh)
        # ... and is_init on it makes the history irrelevant: the zero state of a new game
        state_keys = [key for key in qnet.in_keys if key not in ("observation", IS_INIT_KEY)]
        td = TensorDict({"observation": history_a[:1], IS_INIT_KEY: torch.tensor([[True]])}, batch_size=[1])
        qnet(td)
        carried = TensorDict({"observation": x, IS_INIT_KEY: torch.tensor([[True]]),
                              **{key: td.get(("next", key)) for key in state_keys}}, batch_size=[1])
        assert torch.allclose(qnet(carried).get("action_value")[0], fresh)


def test_batched_env_partial_resets_mark_is_init_and_restart_the_state() -> None:
    """In the real batched env (games ending at different steps), the collector's data carries is_init on the first
    step of every dialogue, the hidden state there is zero, and within a dialogue each step starts from the state
    the previous step left."""
    env, qnet = _network("gru")
    policies = make_policies(qnet, env.action_spec_unbatched, "one_step", eps_init=0.3)
    env = memory_env(env, policies.explore)
    collector = make_collector(env, policies.explore, 4 * 20, 4 * 40)
    rows, config, frames, batches = SequenceRows("gru"), load_config(_tiny_path(), []), 0, []
    for part in collector:  # two batches: dialogues running across the batch boundary keep their id and count on
        tagged = rows(part, _transitions(part, config), frames)
        frames += part.numel()
        assert torch.equal(tagged.get(STEP_KEY), part.get("turn").reshape(-1))  # the env's own count of acts
        batches.append((part.clone(), tagged.get(EPISODE_KEY).reshape(4, -1)))
    collector.shutdown()
    batch = torch.cat([part for part, _ in batches], dim=1)
    episode = torch.cat([ids for _, ids in batches], dim=1)
    assert torch.equal(episode[:, 1:] != episode[:, :-1], batch.get(IS_INIT_KEY).squeeze(-1)[:, 1:])
    assert len(set(episode.flatten().tolist())) == int(batch.get(IS_INIT_KEY).sum())  # one id per dialogue
    is_init = batch.get(IS_INIT_KEY).squeeze(-1)
    done = batch.get(("next", "done")).squeeze(-1)
    assert bool(is_init[:, 0].all())
    assert int(is_init[:, 1:].sum()) >= 4, "expected several dialogues per env row"
    assert torch.equal(is_init[:, 1:], done[:, :-1])  # a new dialogue right after each ending one, row by row
    state, next_state = batch.get("recurrent_state"), batch.get(("next", "recurrent_state"))
    assert float(state[is_init].abs().max()) == 0.0
    carried = ~is_init[:, 1:]
    assert torch.equal(state[:, 1:][carried], next_state[:, :-1][carried])
    assert float(state[~is_init].abs().max()) > 0.0


def _filled_buffer(game: str = "standard", lookahead: str = "one_step", memory: str = "gru", batches: int = 6,
                   length: int = 8, batch_size: int = 64, prioritized: bool = False, **env_options):
    env, qnet = _network(memory, game, **env_options)
    policies = make_policies(qnet, env.action_spec_unbatched, lookahead, eps_init=0.5)
    env = memory_env(env, policies.explore)
    config = load_config(_tiny_path(), [])  # its loss section: which bootstrap mask the transitions carry
    config.agent.lookahead = lookahead
    rows = SequenceRows(memory)
    buffer = make_sequence_buffer(5000, batch_size, length, prioritized=prioritized)
    collector = make_collector(env, policies.explore, 4 * 16, 4 * 16 * batches)
    frames = 0
    for batch in collector:
        buffer.extend(rows(batch, _transitions(batch, config), frames))
        frames += batch.numel()
    collector.shutdown()
    return qnet, buffer, config


def _transitions(batch, config):
    loss = config.loss
    return prepare_transitions(batch, reward=loss.reward, loss_reward=loss.loss_reward, bootstrap=loss.bootstrap,
                               lookahead=config.lookahead)


_TINY: Path | None = None


def _tiny_path() -> Path:
    global _TINY
    if _TINY is None:
        import tempfile

        _TINY = write_tiny_config(Path(tempfile.mkdtemp()))
    return _TINY


@pytest.mark.parametrize("prioritized", [False, True])
def test_sampled_slices_never_cross_a_dialogue_boundary(prioritized: bool) -> None:
    _, buffer, _ = _filled_buffer(batches=8, prioritized=prioritized)
    length = 8
    for _ in range(20):
        sample = buffer.sample().reshape(-1, length)
        real = sample.get(VALID_KEY)
        episode, step = sample.get(EPISODE_KEY), sample.get(STEP_KEY)
        assert bool((episode == episode[:, :1]).all())  # padding repeats the last real step: same dialogue
        # real steps are consecutive steps of that dialogue, and each next observation is the next step's one
        assert bool(((step[:, 1:] - step[:, :-1] == 1) | ~real[:, 1:]).all())
        assert bool((real[:, :-1] | ~real[:, 1:]).all())  # padding only at the end
        following = real[:, 1:]
        assert torch.equal(sample.get(("next", "observation"))[:, :-1][following],
                           sample.get("observation")[:, 1:][following])
        # a dialogue's end is the slice's last real step
        done = sample.get(("next", "done")).squeeze(-1)
        assert not bool((done[:, :-1] & following).any())
        stored_init = sample.get(IS_INIT_KEY).squeeze(-1)
        assert bool(stored_init[:, 0].all()) and not bool((stored_init[:, 1:] & following).any())
    # short dialogues come whole and padded: some slices start at the dialogue's first step
    assert bool((sample.get(STEP_KEY)[:, 0] == 0).any())


def test_the_loss_unrolls_a_slice_as_the_actor_stepped_it() -> None:
    """Recurrent mode over a slice from its stored state gives the Q-values the acting network gave step by step."""
    qnet, buffer, _ = _filled_buffer(batches=4)
    sample = buffer.sample().reshape(-1, 8)
    loss = RecurrentDQNLoss(qnet, sequence_length=8)
    row = int(torch.nonzero(sample.get(VALID_KEY).all(-1))[0])
    observations = sample.get("observation")[row]
    with torch.no_grad():
        unrolled = loss._unroll(observations.unsqueeze(0), {"recurrent_state": sample.get("recurrent_state")[row, 0:1]})[0]
        td = TensorDict({"observation": observations[:1], IS_INIT_KEY: torch.tensor([[False]]),
                         "recurrent_state": sample.get("recurrent_state")[row, 0:1]}, batch_size=[1])
        stepped = []
        for t in range(8):
            td.set("observation", observations[t:t + 1])
            qnet(td)
            stepped.append(td.get("action_value")[0].clone())
            td.set("recurrent_state", td.get(("next", "recurrent_state")))
    assert torch.allclose(unrolled, torch.stack(stepped), atol=1e-5)


@pytest.mark.parametrize("memory", ["gru", "lstm"])
def test_the_loss_unroll_is_torchrls_recurrent_mode_bit_for_bit(memory: str) -> None:
    """The loss unrolls on the tensors (the MLP, the recurrent module's torch RNN, the head) for speed; Q-values and
    gradients equal TorchRL's recurrent mode over the same slices from the same stored states, bit for bit."""
    _, qnet = _network(memory)
    loss = RecurrentDQNLoss(qnet, sequence_length=8)
    generator = torch.Generator().manual_seed(3)
    rows, steps = 5, 9
    observations = torch.randn(rows, steps, qnet.module[0].module[0].in_features, generator=generator)
    states = {key: torch.randn(rows, 1, 8, generator=generator) for key in loss.state_keys}

    def recurrent_mode() -> torch.Tensor:
        return unroll_in_recurrent_mode(qnet, observations, states)

    gradients = []
    for unroll in (recurrent_mode, lambda: loss._unroll(observations, states)):
        qnet.zero_grad()
        q_values = unroll()
        (q_values * torch.linspace(-1, 1, q_values.shape[-1])).sum().backward()
        gradients.append((q_values.detach(), [p.grad.clone() for p in qnet.parameters()]))
    (reference, reference_grads), (unrolled, unrolled_grads) = gradients
    assert torch.equal(unrolled, reference)
    assert all(torch.equal(a, b) for a, b in zip(unrolled_grads, reference_grads, strict=True))
    with torch.no_grad():
        for weight in loss.target_value_network_params.values(True, True):
            weight.add_(0.05)  # a target network that differs from the online one
        with loss.target_value_network_params.to_module(loss.value_network):
            target = loss._unroll(observations, states)
            assert torch.equal(target, recurrent_mode())  # the target's unroll too
        assert not torch.equal(target, unrolled)


def test_prioritised_slices_get_r2d2_priorities_after_an_update() -> None:
    """With buffer.prioritized each slice start carries eta * max + (1 - eta) * mean of its |TD errors|; the next
    draw prefers slices by it and scales their loss by the importance weight."""
    qnet, buffer, _ = _filled_buffer(batches=4, prioritized=True)
    sampler = buffer.sampler
    objective = RecurrentDQNLoss(qnet, sequence_length=8, burn_in=2)
    objective.set_keys(**LOSS_KEYS)
    objective.make_value_estimator(gamma=0.9)
    learner = Learner.build(objective, optim=types.SimpleNamespace(lr=1e-3, weight_decay=0.0, max_grad_norm=10.0),
                            loss=types.SimpleNamespace(target_update="hard", target_period=10, tau=0.005))
    fresh = sampler._priority[:len(buffer)].clone()
    assert torch.equal(fresh, torch.ones_like(fresh))  # new rows: the largest priority so far (1 at the start)
    torch.manual_seed(0)
    learner.update_many(buffer, 2)
    changed = (sampler._priority[:len(buffer)] != fresh).nonzero().squeeze(-1)
    assert changed.numel() >= 8  # one start row per replayed slice, not every step's row
    assert changed.numel() <= 2 * 64 // 8
    assert float(sampler._priority[changed].std()) > 0.0  # slices differ
    # what the loss writes: one priority per slice, on all its steps, and the start row keeps (p + eps) ** alpha
    part = buffer.sample()
    learner.update(part)
    priority = part.get("td_error").reshape(-1, 8)
    assert torch.equal(priority, priority[:, :1].expand_as(priority))
    buffer.update_priority(part.get("index"), part.get("td_error"))
    start_rows = part.get("index").reshape(-1, 8)[:, 0]
    expected = (priority[:, 0].double() + sampler.eps).pow(sampler.alpha)
    last = {int(row): float(value) for row, value in zip(start_rows, expected)}  # a row drawn twice: the last write
    assert all(abs(float(sampler._priority[row]) - value) < 1e-9 for row, value in last.items())
    # R2D2's mixture of a slice's |TD errors| over its loss steps
    errors, trained = torch.tensor([[1.0, 3.0, 0.0, 5.0]]), torch.tensor([[True, True, False, False]])
    assert torch.allclose(sequence_priority(errors, trained), torch.tensor([0.9 * 3.0 + 0.1 * 2.0]))
    # the draw follows the priorities and carries one importance weight per slice (1 for the rarest start)
    favourite = int(start_rows[0])
    sampler._priority[favourite] = 1e6
    sample = buffer.sample().reshape(-1, 8)
    drawn = sample.get("index").reshape(-1, 8)[:, 0] == favourite
    assert int(drawn.sum()) >= 6
    weight = sample.get("priority_weight")
    assert torch.equal(weight, weight[:, :1].expand_as(weight)) and float(weight.max()) <= 1.0
    assert float(weight[drawn].max()) < 1e-2  # the over-drawn slice counts for little
    # a resumed run keeps the priorities (they are in the buffer's state, which the checkpoint stores)
    restored = make_sequence_buffer(5000, 64, 8, prioritized=True)
    restored.load_state_dict(buffer.state_dict())
    assert torch.equal(restored.sampler._priority, sampler._priority)
    assert restored.sampler._max_priority == sampler._max_priority


def test_the_recurrent_objective_honours_the_value_estimator_asked_for() -> None:
    """recurrent_dqn's targets come from TorchRL's TD(0), TD(1) or TD(lambda) estimator over each slice: TD(lambda)
    near lambda 0 is TD(0) and at lambda 1 is TD(1), and TD(1) differs from TD(0) on slices of unfinished dialogues."""
    from torchrl.objectives import ValueEstimators

    qnet, buffer, _ = _filled_buffer(batches=4)
    torch.manual_seed(0)
    batch = buffer.sample()

    def target_mean(value_type, **hyperparams) -> float:
        loss = RecurrentDQNLoss(qnet, sequence_length=8)
        loss.set_keys(**LOSS_KEYS)
        with torch.no_grad():
            for weight in loss.target_value_network_params.values(True, True):
                weight.add_(0.3)  # a target network whose values are far from the rewards
        loss.make_value_estimator(value_type, gamma=0.9, **hyperparams)
        assert loss.value_type is value_type
        return float(loss(batch.clone())["target_mean"])

    td0, td1 = target_mean(ValueEstimators.TD0), target_mean(ValueEstimators.TD1)
    assert target_mean(ValueEstimators.TDLambda, lmbda=1e-6) == pytest.approx(td0, abs=1e-4)
    assert target_mean(ValueEstimators.TDLambda, lmbda=1.0) == pytest.approx(td1, abs=1e-5)
    assert td0 != pytest.approx(td1, abs=1e-3)
    with pytest.raises(ValueError, match="TD\\(0\\), TD\\(1\\) or TD\\(lambda\\)"):
        RecurrentDQNLoss(qnet, sequence_length=8).make_value_estimator(ValueEstimators.GAE)


@pytest.mark.parametrize("game,lookahead,memory,temporal", [
    ("standard", "none", "gru", True), ("standard", "variant", "lstm", False), ("standard", "one_step", "gru", False),
    ("standard", "k2", "lstm", True), ("ultimate", "one_step", "gru", False), ("ultimate", "k2", "lstm", True),
])
def test_updates_run_with_every_mask_game_and_feature_set(game: str, lookahead: str, memory: str,
                                                          temporal: bool) -> None:
    qnet, buffer, _ = _filled_buffer(game, lookahead, memory, batches=3, temporal=temporal)
    loss = RecurrentDQNLoss(qnet, sequence_length=8, burn_in=2, double_dqn=memory == "lstm")
    loss.set_keys(**LOSS_KEYS)
    loss.make_value_estimator(gamma=0.9)
    updater = make_target_updater(loss, "hard", 2)
    optimizer = torch.optim.Adam(loss.parameters(), lr=1e-3)
    before = [p.detach().clone() for p in qnet.parameters()]
    for _ in range(3):
        out = loss(buffer.sample())
        assert torch.isfinite(out["loss"])
        optimizer.zero_grad()
        out["loss"].backward()
        optimizer.step()
        updater.step()
    assert any(not torch.equal(a, b) for a, b in zip(before, qnet.parameters()))  # the acting network learnt


def test_tiny_prioritised_gru_run_trains_checkpoints_and_evaluates(tmp_path: Path) -> None:
    config = load_config(write_tiny_config(tmp_path, **MEMORY),
                         ["agent.memory=gru", "buffer.augment=d4", "buffer.prioritized=true"])
    run = tmp_path / "run"
    report = train(config, run)
    assert report["updates"] > 0 and report["first"]["games"] == 60
    final = load_checkpoint(run / "checkpoint.pt")  # weights_only=True
    assert torch.load(run / "checkpoint.pt", weights_only=True)["config"]["agent"]["memory"] == "gru"
    assert any(".gru." in key for key in final["qnet"])
    result = ncbot("eval", str(run / "checkpoint.pt"), "--games", "40", "--json")
    assert result.returncode == 0, result.stderr
    numbers = json.loads(result.stdout)
    assert numbers["games"] == 40 and 0.0 <= numbers["task_success"] <= 1.0
    from ncbot.pipelines.agents import load_robot

    with pytest.raises(ValueError, match="agent.memory=gru"):  # the search reads positions without a dialogue
        load_robot(str(run / "checkpoint.pt"), search=4)


def test_memory_refuses_what_reads_the_network_as_an_mlp(tmp_path: Path) -> None:
    path = write_tiny_config(tmp_path, **MEMORY)
    with pytest.raises(ValueError, match="loss.n_step"):
        load_config(path, ["agent.memory=gru", "loss.n_step=3"])
    with pytest.raises(ValueError, match="multiple of buffer.sequence_length"):
        load_config(path, ["agent.memory=lstm", "buffer.batch_size=30"])
    with pytest.raises(ValueError, match="burn_in"):
        load_config(path, ["agent.memory=gru", "buffer.burn_in=8"])
    load_config(path, ["buffer.prioritized=true", "buffer.batch_size=30"])  # memory none: as before


# eval.json of the tiny config with augment d4 and prioritised replay, trained by the code before agent.memory
# existed (main at a19b48d, `ncbot train tiny.yaml`): memory none must give exactly these numbers
BEFORE_MEMORY = {"first": {"win": 0.9166666666666666, "draw": 0.06666666666666667, "loss": 0.016666666666666666},
                 "second": {"win": 0.7166666666666667, "draw": 0.2, "loss": 0.08333333333333333},
                 "history": [0.95, 0.95]}


def test_memory_none_gives_the_numbers_from_before(tmp_path: Path) -> None:
    config = load_config(write_tiny_config(tmp_path, buffer={"augment": "d4", "prioritized": True}), [])
    report = train(config, tmp_path / "run")
    for seat in ("first", "second"):
        assert {key: report[seat][key] for key in ("win", "draw", "loss")} == BEFORE_MEMORY[seat]
    assert [record["task_success"] for record in report["history"]] == BEFORE_MEMORY["history"]
