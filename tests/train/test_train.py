"""A tiny real training run (TorchRL Collector, replay buffer, competitive DQN loss, real dialogue env) writes
every artefact, and the same seed + config gives the same evaluation numbers."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from ncbot.pipelines.checkpoint import load_checkpoint
from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.run import train
from tests.learning_helpers import TINY, write_tiny_config

torch.set_num_threads(1)


def _numbers(report: dict) -> dict:
    """Everything in eval.json except wall-clock times and the run's identity."""
    drop = {"wall_time", "train_wall_time_s", "train_cpu_time_s", "time_to_0995_s", "run_id"}
    clean = {k: v for k, v in report.items() if k not in drop and k != "history"}
    clean["history"] = [{k: v for k, v in h.items() if k not in drop} for h in report["history"]]
    return clean


def test_tiny_run_writes_every_artefact(tmp_path: Path) -> None:
    config = load_config(write_tiny_config(tmp_path), ["logger.mcap=true"])
    run = tmp_path / "run"
    report = train(config, run)
    for name in ("checkpoint.pt", "config.yaml", "eval.json", "learning_curve.png"):
        assert (run / name).is_file() and (run / name).stat().st_size > 0, name
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["step-000000256.pt", "step-000000512.pt"]
    assert list(run.glob("episodes-*.mcap")), "the run's MCAP log is missing"
    assert not list(run.rglob("*.tmp")), "a temporary file was left behind"

    saved = json.loads((run / "eval.json").read_text())
    assert saved["frames"] == 512 and saved["updates"] > 0 and saved["episodes"] > 0
    for seat in ("first", "second"):
        assert saved[seat]["games"] == 60
        assert abs(saved[seat]["win"] + saved[seat]["draw"] + saved[seat]["loss"] - 1.0) < 1e-9
    assert [h["frames"] for h in saved["history"]] == [256, 512]
    assert all(h["wall_time"] > 0 for h in saved["history"])  # the wall time of each periodic evaluation
    assert 0 < saved["train_cpu_time_s"]  # the process's CPU seconds: a cost that a shared machine's load spares

    final = load_checkpoint(run / "checkpoint.pt")
    assert final["n_features"] == 73 and final["n_actions"] == 18
    assert load_config(run / "config.yaml") == config

    # the MCAP log holds the training and evaluation episodes of the run
    from ncbot.logs import read_episodes

    phases = {episode["phase"] for episode in read_episodes(run)}
    assert {"train", "eval"} <= phases


@pytest.mark.parametrize("agent", ["dqn_original", "dqn_variant"])
def test_baselines_train_through_the_same_pipeline(tmp_path: Path, agent: str) -> None:
    config = load_config(write_tiny_config(tmp_path), [f"agent.name={agent}", "collector.total_frames=128",
                                                       "env.temporal=false"])
    report = train(config, tmp_path / agent)
    assert report["first"]["games"] == 60 and load_checkpoint(tmp_path / agent)["n_features"] == 64


def test_same_seed_same_numbers_other_seed_other_numbers(tmp_path: Path) -> None:
    path = write_tiny_config(tmp_path)
    first = train(load_config(path), tmp_path / "a")
    again = train(load_config(path), tmp_path / "b")
    assert _numbers(first) == _numbers(again)
    other = train(load_config(path, ["train.seed=4"]), tmp_path / "c")
    assert _numbers(other) != _numbers(first)


def test_episodes_budget_stops_after_that_many_training_games(tmp_path: Path) -> None:
    """`--episodes N` runs an open-ended collector (total_frames=-1) and stops once N games have ended."""
    config = load_config(write_tiny_config(tmp_path), ["train.episodes=120"])
    report = train(config, tmp_path / "run")
    state = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    assert 120 <= report["episodes"] == state["episodes"]
    assert report["frames"] > TINY["collector"]["total_frames"]  # the frame budget did not stop it


def test_bf16_precision_reaches_the_learner_and_is_reproducible(tmp_path: Path) -> None:
    """optim.precision=bf16 trains through the same pipeline: same seed, same numbers; other numbers than fp32."""
    path = write_tiny_config(tmp_path)
    fast = train(load_config(path, ["optim.precision=bf16"]), tmp_path / "bf16")
    again = train(load_config(path, ["optim.precision=bf16"]), tmp_path / "bf16_again")
    assert _numbers(fast) == _numbers(again)
    exact = train(load_config(path), tmp_path / "fp32")
    assert [h["train_loss"] for h in fast["history"]] != [h["train_loss"] for h in exact["history"]]
    assert load_config(tmp_path / "bf16" / "config.yaml").optim.precision == "bf16"


@pytest.mark.parametrize("eps_init, eps_end, steps", [(1.0, 0.005, 1000), (1.0, 0.005, 37), (0.3, 0.3, 10)])
def test_anneal_epsilon_is_torchrl_step_bit_for_bit(eps_init: float, eps_end: float, steps: int) -> None:
    """The loop's epsilon schedule skips TorchRL's step only where it cannot move eps: same eps, batch after batch."""
    from torchrl.data import Categorical
    from torchrl.modules import EGreedyModule

    from ncbot.pipelines.train.loop import anneal_epsilon

    torchrl_steps, ours = (EGreedyModule(Categorical(4), eps_init=eps_init, eps_end=eps_end, annealing_num_steps=steps)
                           for _ in range(2))
    for _ in range(200):  # 1600 frames: past the end of the annealing in every case
        torchrl_steps.step(8)
        anneal_epsilon(ours, 8)
        assert torch.equal(torchrl_steps.eps, ours.eps)
    assert float(ours.eps) == pytest.approx(eps_end)


def test_learning_curve_shows_both_seats_and_a_readable_loss_axis(tmp_path: Path) -> None:
    from ncbot.pipelines.plots import learning_curve_figure, pyplot

    history = [{"frames": 1000 * i, "wall_time": float(i), "task_success": 0.9, "avg_reward": 0.1,
                "avg_length": 10.0, "train_loss": 1.6 + 0.1 * (i % 3),
                "seats": {"robot_first": {"task_success": 0.95}, "robot_second": {"task_success": 0.85}}}
               for i in range(1, 6)]
    within = learning_curve_figure(history)
    across = learning_curve_figure([dict(h, train_loss=10.0 ** i) for i, h in enumerate(history)])
    across.canvas.draw()
    success = within.axes[2]  # row 1 (task success), left column
    assert [line.get_label() for line in success.get_lines()][:2] == ["robot first", "robot second"]
    assert within.axes[6].get_yscale() == "linear"  # a loss inside one decade: linear, every tick labelled
    assert across.axes[6].get_yscale() == "log"
    labels = [t.get_text() for t in across.axes[6].get_yticklabels() if t.get_text()]
    assert 0 < len(labels) <= 7  # whole decades only: labels that cannot overlap
    for fig in (within, across):
        pyplot().close(fig)


def test_cpu_time_is_unknown_after_resuming_from_a_checkpoint_that_did_not_keep_it() -> None:
    import time

    from ncbot.pipelines.train.loop import run_cpu_time

    started = time.process_time()
    assert run_cpu_time(None, started) is None
    assert run_cpu_time(12.5, started) >= 12.5
