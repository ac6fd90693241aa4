"""Self-play: a pool of frozen snapshots of the agent as the env's user; a tiny real training run with it."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from ncbot.envs import make_env
from ncbot.modules.networks.qnet import make_qnet, seeded_init
from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.selfplay import SelfPlayConfig, SnapshotPool
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)


def _pool(game: str = "standard", **settings) -> tuple[SnapshotPool, torch.nn.Module]:
    qnet = make_qnet(73 if game == "standard" else 289, 18 if game == "standard" else 90, [16])
    seeded_init(qnet, 0)
    pool = SnapshotPool(game, "anywhere", True, SelfPlayConfig(enabled=True, **settings), seed=0)
    return pool, qnet


def test_snapshots_are_frozen_copies_taken_on_schedule():
    pool, qnet = _pool(pool_size=2, snapshot_every_frames=100)
    assert pool.maybe_add(qnet, 0) and not pool.maybe_add(qnet, 99) and pool.maybe_add(qnet, 100)
    with torch.no_grad():
        qnet.module[0].weight.add_(1.0)  # the learner moves on; the snapshot must not
    assert not torch.equal(pool.snapshots[0][0].weight, qnet.module[0].weight)
    assert not any(p.requires_grad for p in pool.snapshots[0].parameters())
    pool.maybe_add(qnet, 250)
    assert len(pool.snapshots) == 2 and pool.added == 3  # the oldest was dropped
    with pytest.raises(ValueError, match="random_share"):
        SnapshotPool("standard", "anywhere", True, SelfPlayConfig(random_share=1.5))


def test_snapshot_plays_for_the_users_side():
    """Perspective: the snapshot reads its own marks as 'robot' marks and takes the user's winning cell."""
    pool, qnet = _pool(random_share=0.0, epsilon=0.0)
    pool.add(qnet)
    boards = torch.tensor([[1, 1, 0, 2, 2, 0, 1, 0, 0]], dtype=torch.int8)  # user (2) wins at 5; robot threatens 2
    legal = boards == 0
    for seed in range(5):
        cell = pool.select(boards, torch.tensor([3]), legal, 2, torch.Generator().manual_seed(seed))
        assert int(cell) == 5


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_pool_is_a_legal_reproducible_env_opponent(game):
    def play(seed: int) -> list:
        pool, qnet = _pool(game, random_share=0.2)
        pool.add(qnet)
        env = make_env(game, batch_size=(8,), seed=seed, first="alternate", opponent=pool)
        td, boards = env.reset(), []
        for _ in range(40):
            td = env.step(env.rand_action(td))["next"]  # the env raises if the opponent returns an illegal cell
            boards.append(td["board"].clone())
        return boards

    first, again = play(1), play(1)
    assert all(torch.equal(a, b) for a, b in zip(first, again))
    assert int((first[-1] == 2).sum()) > 0  # the user did move


def test_tiny_selfplay_run(tmp_path: Path):
    """A real training run whose user is the snapshot pool: snapshots are taken, the run reports them, and
    the evaluation (against the paper's random user) is reproducible with the same seed."""
    path = write_tiny_config(tmp_path)
    overrides = ["selfplay.enabled=true", "selfplay.snapshot_every_frames=128", "selfplay.pool_size=3",
                 "collector.total_frames=384"]
    config = load_config(path, overrides)
    report = train(config, tmp_path / "a")
    assert report["selfplay"] == {"snapshots_taken": 4, "snapshots_held": 3}
    saved = json.loads((tmp_path / "a" / "eval.json").read_text())
    assert saved["selfplay"]["snapshots_taken"] == 4 and saved["first"]["games"] == 60
    again = train(load_config(path, overrides), tmp_path / "b")
    assert again["first"] == report["first"] and again["second"] == report["second"]
