"""Targets improved by search (`search_targets`): DQfD's margin loss by hand, the teacher labels real collected
moves with its Q-guided search (inside the greedy mask, only the seat asked for), reads the network as it is now,
the learner adds the loss, and a real run with it is reproducible."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from ncbot.modules.search.guided_mcts import GuidedMCTS, TurnFeatures
from ncbot.modules.policies.policy import make_policies
from ncbot.modules.networks.qnet import make_qnet, seeded_init
from ncbot.modules.search.search_targets import EXPERT_ACTION_KEY, LABEL_MASK_KEY, SearchTeacher, margin_loss
from ncbot.pipelines.config import load_config
from ncbot.pipelines.run_env import make_run_env
from ncbot.pipelines.train.build import make_collector
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)


def test_margin_loss_by_hand() -> None:
    q = torch.tensor([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [1.0, 2.0, 3.0]])
    mask = torch.tensor([[True, True, True], [True, True, True], [True, True, False]])
    expert = torch.tensor([0, 2, 0])
    # row 0: max(1, 2 + 1, 3 + 1) - 1 = 3; row 1: the searched move leads by 1 >= margin: max(2, 3, 3) - 3 = 0;
    # row 2: the move outside the mask does not count: max(1, 2 + 1) - 1 = 2
    assert float(margin_loss(q, expert, mask, 1.0)) == pytest.approx((3 + 0 + 2) / 3)
    assert float(margin_loss(q, torch.tensor([2, 2, 1]), mask, 0.5)) == pytest.approx((0 + 0 + 0) / 3)


def _agent_and_batch(game: str = "ultimate", frames: int = 1024):
    config = load_config(_config_path(game), [])
    env = make_run_env(config.env, batch_size=16, seed=0)
    qnet = make_qnet(env.n_features, env.n_actions, [32])
    seeded_init(qnet, 0)
    agent = make_policies(qnet, env.action_spec_unbatched, config.lookahead, eps_init=1.0, eps_end=1.0,
                          annealing_frames=1)
    collector = make_collector(env, agent.explore, frames, frames)
    batch = next(iter(collector)).clone()
    collector.shutdown()
    env.close()
    return config, agent, batch


def _config_path(game: str) -> Path:
    return Path(__file__).resolve().parents[2] / "pipelines" / "configs" / ("ultimate.yaml" if game == "ultimate" else "default.yaml")


def _teacher(config, agent, seat: str = "both", rows: int = 6, simulations: int = 8,
             gap: float | None = None) -> SearchTeacher:
    env = config.env
    search = GuidedMCTS(agent.greedy[0].module, TurnFeatures(env.game, env.temporal, env.free_move), env.game,
                        env.free_move, simulations)
    return SearchTeacher(agent.greedy, search, rows_per_batch=rows, seat=seat, gap=gap, buffer_size=100, batch_size=4,
                         seed=1)


@pytest.mark.parametrize("seat", ["both", "second"])
def test_teacher_labels_robot_moves_with_a_choice_inside_the_greedy_mask(seat: str) -> None:
    config, agent, batch = _agent_and_batch()
    teacher = _teacher(config, agent, seat)
    rows = teacher.candidates(batch)
    flat = batch.reshape(-1)
    assert rows.numel() > 6
    assert torch.all(flat["greedy_mask"][rows, :81].sum(-1) >= 2)
    if seat == "second":
        assert not flat["robot_first"][rows].any()
        assert teacher.candidates(batch).numel() < _teacher(config, agent, "both").candidates(batch).numel()
    assert teacher.label(batch) == 6 and len(teacher.labels) == 6 and teacher.ready()  # gap None: every row kept
    labels = teacher.labels[:]
    chosen = labels[LABEL_MASK_KEY].gather(-1, labels[EXPERT_ACTION_KEY].unsqueeze(-1))
    assert chosen.all() and torch.all(labels[EXPERT_ACTION_KEY] < 81)  # a game move the greedy policy could play
    assert teacher.policy.decisions == 6 and teacher.cpu_seconds > 0
    again = _teacher(config, agent, seat)  # same seed, same network, same batch: same labels
    again.label(batch)
    assert torch.equal(again.labels[:][EXPERT_ACTION_KEY], labels[EXPERT_ACTION_KEY])


def test_decisive_masks_keep_the_searched_move_and_the_clearly_worse_ones() -> None:
    config, agent, batch = _agent_and_batch(frames=16)
    teacher = _teacher(config, agent, gap=0.1)
    teacher.policy.root_values = {0: {3: 0.9, 4: 0.85, 5: 0.5, 6: 0.2}, 1: {7: 0.6}}
    greedy_mask = torch.ones(2, 90, dtype=torch.bool)
    greedy_mask[0, 6] = False  # not a move the greedy policy could play: never in a label
    mask = teacher.decisive_masks(torch.tensor([3, 7]), greedy_mask)
    assert mask[0].nonzero().flatten().tolist() == [3, 5]  # 4 is a near tie (0.05 < gap)
    assert mask[1].nonzero().flatten().tolist() == [7]  # nothing clearly worse: the row is dropped by label()


def test_labels_with_a_gap_rank_the_searched_move_against_clearly_worse_moves_only() -> None:
    config, agent, batch = _agent_and_batch()
    teacher = _teacher(config, agent, rows=12, simulations=32, gap=0.05)
    kept = teacher.label(batch)
    assert teacher.searched == 12 and 0 < kept <= 12 and teacher.kept == kept
    labels = teacher.labels[:]
    assert torch.all(labels[LABEL_MASK_KEY].sum(-1) >= 2)
    assert labels[LABEL_MASK_KEY].gather(-1, labels[EXPERT_ACTION_KEY].unsqueeze(-1)).all()


def test_search_reads_the_network_as_it_is_after_refresh() -> None:
    config, agent, _ = _agent_and_batch(frames=16)
    search = _teacher(config, agent).search
    x = TurnFeatures("ultimate", True, config.env.free_move)([0, 10], [40], 40)
    before = search._reader(x.copy())
    with torch.no_grad():
        for parameter in search.qnet.parameters():
            parameter.add_(0.1)
    assert torch.allclose(torch.from_numpy(search._reader(x.copy())), torch.from_numpy(before))  # a stale copy
    search.refresh()
    expected = search.qnet(torch.from_numpy(x).unsqueeze(0))[0].detach()
    assert torch.allclose(torch.from_numpy(search._reader(x.copy())), expected, atol=1e-5)


def test_learner_adds_the_weighted_margin_loss_to_the_td_loss() -> None:
    """The teacher is an auxiliary loss of the learner: its weight x the margin loss on the objective's online Q of
    a batch of labels is added to the TD loss of the same update."""
    from tests.modules.test_loss import _learner, mlp_transitions
    from tensordict import TensorDict

    config, agent, _ = _agent_and_batch(frames=16)
    teacher = _teacher(config, agent)
    teacher.weight, teacher.margin = 0.5, 2.0
    learner, reference = _learner(batch_size=8), _learner(batch_size=8)
    learner.auxiliary.append(teacher)
    batch = mlp_transitions(8, seed=2)
    labels = TensorDict({"observation": torch.rand(4, 6), LABEL_MASK_KEY: torch.ones(4, 4, dtype=torch.bool),
                         EXPERT_ACTION_KEY: torch.tensor([0, 1, 2, 3])}, [4])
    td_loss = reference.objective(batch.clone())["loss"]
    q = reference.objective.q_values(labels)
    expected = td_loss + 0.5 * margin_loss(q, labels[EXPERT_ACTION_KEY], labels[LABEL_MASK_KEY], 2.0)
    assert float(learner.update(batch.clone(), [labels])) == pytest.approx(expected.item(), rel=1e-5)
    assert teacher.draw(3) == [None] * 3  # fewer labels than a batch: no term yet


def test_a_real_run_with_search_targets_is_reproducible(tmp_path: Path) -> None:
    overrides = ["search_targets.enabled=true", "search_targets.start_frames=128", "search_targets.simulations=16",
                 "search_targets.rows_per_batch=4", "search_targets.batch_size=8"]

    def run(name: str, extra: list[str]) -> dict:
        config = load_config(write_tiny_config(tmp_path), extra)
        train(config, tmp_path / name)
        return json.loads((tmp_path / name / "eval.json").read_text())

    def weights(name: str) -> list[torch.Tensor]:
        return list(torch.load(tmp_path / name / "checkpoint.pt", weights_only=True)["qnet"].values())

    first, again, plain = run("a", overrides), run("b", overrides), run("p", [])
    assert first["search_targets"]["searched"] > 0 and "search_targets" not in plain
    assert first["search_targets"]["labels"] == again["search_targets"]["labels"]
    assert all(torch.equal(a, b) for a, b in zip(weights("a"), weights("b")))
    assert not all(torch.equal(a, b) for a, b in zip(weights("a"), weights("p")))


@pytest.mark.parametrize("overrides,message", [
    (["search_targets.value=/no/such/value.pt"], "value network '/no/such/value.pt' not found"),
    (["search_targets.value={value}", "env.game=standard"], "'search_targets.value' scores Ultimate positions"),
    (["search_targets.value={value}", "env.free_move=open_subgrids"], "trained on the 'anywhere' free-move rule"),
])
def test_a_bad_teacher_value_network_is_one_line_before_the_run_folder_is_made(tmp_path: Path, overrides, message) -> None:
    from ncbot.modules.search.value_net import make_value_net, value_checkpoint
    from tests.learning_helpers import ncbot

    value = tmp_path / "value.pt"
    torch.save(value_checkpoint(make_value_net([8]), [8], "anywhere", {}), value)
    config = write_tiny_config(tmp_path, env={"game": "ultimate", "free_move": "anywhere"})
    result = ncbot("train", str(config), "--out", str(tmp_path / "run"), "search_targets.enabled=true",
                   *[o.format(value=value) for o in overrides])
    assert result.returncode == 2 and message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()
