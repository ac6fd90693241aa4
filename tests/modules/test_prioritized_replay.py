"""Prioritised replay (`buffer.prioritized`): the proportional sampler draws rows by priority with TorchRL's
importance weights, the loss weights each row's error by them, the learner writes each row's new |TD error| back,
and a real run with it is reproducible."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict

from ncbot.pipelines.config import load_config
from ncbot.modules.replay.buffer import make_replay_buffer
from ncbot.modules.replay.prioritized_sampler import ProportionalSampler
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config
from tests.modules.test_loss import _learner, mlp_loss, mlp_transitions

torch.set_num_threads(1)


def _buffer(rows: int, alpha: float = 1.0, beta: float = 0.5):
    buffer = make_replay_buffer(rows, 4, prioritized=True, alpha=alpha, beta=beta)
    buffer.extend(TensorDict({"x": torch.arange(rows, dtype=torch.float32)}, [rows]))
    return buffer


def test_rows_are_drawn_in_proportion_to_their_priority_with_torchrl_weights() -> None:
    buffer = _buffer(4)
    buffer.update_priority(torch.arange(4), torch.tensor([1.0, 1.0, 2.0, 6.0]))  # alpha 1: p = 1, 1, 2, 6 (of 10)
    torch.manual_seed(0)
    draw = buffer.sample(40_000)
    share = torch.bincount(draw["index"], minlength=4).double() / 40_000
    assert share.tolist() == pytest.approx([0.1, 0.1, 0.2, 0.6], abs=0.01)
    weight = {int(i): float(w) for i, w in zip(draw["index"], draw["priority_weight"])}
    assert weight[0] == pytest.approx(1.0, rel=1e-4) and weight[3] == pytest.approx(6.0 ** -0.5, rel=1e-4)
    assert torch.equal(draw["x"], draw["index"].float())  # the rows themselves come with their index


def test_new_rows_start_at_the_largest_priority_seen_and_alpha_flattens() -> None:
    sampler = ProportionalSampler(8, alpha=0.5, beta=0.4)
    sampler.extend(torch.arange(3))
    assert sampler._priority[:3].tolist() == pytest.approx([1.0, 1.0, 1.0])
    sampler.update_priority(torch.tensor([0, 1]), torch.tensor([16.0, 0.0]))
    assert sampler._priority[:2].tolist() == pytest.approx([4.0, 1e-3], rel=1e-3)  # (|e| + eps) ** 0.5
    sampler.extend(torch.tensor([3]))
    assert float(sampler._priority[3]) == pytest.approx(4.0, rel=1e-6)
    restored = ProportionalSampler(8, alpha=0.5, beta=0.4)
    restored.load_state_dict(sampler.state_dict())
    assert torch.equal(restored._priority, sampler._priority) and restored._max_priority == sampler._max_priority


def test_loss_weights_each_rows_error_by_its_priority_weight() -> None:
    loss, batch = mlp_loss(), mlp_transitions(16, seed=3)
    plain = loss(batch.clone())["loss"]
    errors = batch.clone()
    loss(errors)
    squared = errors["td_error"].squeeze(-1) ** 2
    assert plain.item() == pytest.approx(float(squared.mean()), rel=1e-5)
    weight = torch.zeros(16)
    weight[:4] = torch.tensor([1.0, 0.5, 0.25, 2.0])
    weighted = batch.clone()
    weighted.set("priority_weight", weight)
    assert loss(weighted)["loss"].item() == pytest.approx(float((squared * weight).mean()), rel=1e-5)


def test_learner_sends_each_updated_rows_new_td_error_back_to_the_sampler() -> None:
    """After an update, each drawn row's priority is (|TD error| + eps) ** alpha with the TD error of that update
    (before its gradient step); rows not drawn keep the priority they entered with."""
    learner, reference = _learner(batch_size=8), _learner(batch_size=8)
    buffer, same = (make_replay_buffer(64, 8, prioritized=True, alpha=0.7, beta=0.4) for _ in range(2))
    buffer.extend(mlp_transitions(64, seed=1))
    same.extend(mlp_transitions(64, seed=1))
    torch.manual_seed(0)
    learner.update_many(buffer, 1)
    torch.manual_seed(0)
    drawn = same.sample(8)  # the rows the update drew (same priorities, same seed)
    reference.objective(drawn)
    expected = (drawn["td_error"].squeeze(-1).double() + buffer.sampler.eps) ** 0.7
    assert torch.allclose(buffer.sampler._priority[drawn["index"]], expected, rtol=1e-5)
    untouched = torch.ones(64, dtype=torch.bool)
    untouched[drawn["index"]] = False
    assert torch.all(buffer.sampler._priority[untouched] == 1.0)


def test_uniform_buffer_is_left_as_it_was() -> None:
    buffer = make_replay_buffer(16, 4)
    assert type(buffer.sampler).__name__ == "RandomSampler"


@pytest.mark.parametrize("key,value", [("buffer.alpha", "1.5"), ("buffer.beta", "-0.1")])
def test_alpha_and_beta_outside_zero_one_are_refused(tmp_path: Path, key: str, value: str) -> None:
    with pytest.raises(ValueError, match=key):
        load_config(write_tiny_config(tmp_path), [f"{key}={value}"])


def test_a_real_prioritised_run_is_reproducible_and_differs_from_uniform(tmp_path: Path) -> None:
    def run(name: str, prioritized: bool) -> dict:
        config = load_config(write_tiny_config(tmp_path), [f"buffer.prioritized={str(prioritized).lower()}"])
        train(config, tmp_path / name)
        return json.loads((tmp_path / name / "eval.json").read_text())

    def weights(name: str) -> list[torch.Tensor]:
        return list(torch.load(tmp_path / name / "checkpoint.pt", weights_only=True)["qnet"].values())

    first, again, uniform = run("a", True), run("b", True), run("u", False)
    assert first["first"] == again["first"] and first["second"] == again["second"]
    assert all(torch.equal(a, b) for a, b in zip(weights("a"), weights("b")))
    assert not all(torch.equal(a, b) for a, b in zip(weights("a"), weights("u")))


def test_exact_curve_bench_reads_every_snapshot_of_a_run(tmp_path: Path) -> None:
    """bench/studies/exact_curve.py (how prioritised replay was chosen for default.yaml): one exact row per kept snapshot,
    the same losses as `ncbot eval --exhaustive` of that snapshot, a PNG, and exit 2 for a folder without snapshots."""
    import subprocess
    import sys

    from ncbot.pipelines.evaluate.exact import exact_checkpoint

    config = load_config(write_tiny_config(tmp_path), ["buffer.prioritized=true", "checkpoint.keep=10"])
    train(config, tmp_path / "run")
    snapshots = sorted((tmp_path / "run" / "checkpoints").glob("step-*.pt"))
    assert len(snapshots) == 2  # 512 frames, a snapshot every 256
    bench = Path(__file__).resolve().parents[2] / "bench" / "studies" / "exact_curve.py"
    done = subprocess.run([sys.executable, str(bench), str(tmp_path / "run"), "--dialogue-seeds", "1",
                           "--png", str(tmp_path / "curves.png")], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    rows = [line.split() for line in done.stdout.splitlines() if line.startswith("run ")]
    assert [int(row[1]) for row in rows] == [256, 512]
    first, second = exact_checkpoint(str(snapshots[-1]), dialogue_seeds=1)
    assert (float(rows[-1][5]), float(rows[-1][7])) == pytest.approx((first.loss, second.loss), abs=1e-4)
    assert "| run |" in done.stdout and (tmp_path / "curves.png").stat().st_size > 0
    (tmp_path / "empty").mkdir()
    refused = subprocess.run([sys.executable, str(bench), str(tmp_path / "empty")], capture_output=True, text=True)
    assert refused.returncode == 2 and "no checkpoints" in refused.stderr and "Traceback" not in refused.stderr
    (tmp_path / "corrupt" / "checkpoints").mkdir(parents=True)
    (tmp_path / "corrupt" / "checkpoints" / "step-000000256.pt").write_bytes(b"not a checkpoint")
    corrupt = subprocess.run([sys.executable, str(bench), str(tmp_path / "corrupt")], capture_output=True, text=True)
    assert corrupt.returncode == 2 and "corrupt" in corrupt.stderr and "Traceback" not in corrupt.stderr
    assert len(corrupt.stderr.strip().splitlines()) == 1
