"""`train.device`: the config's spellings, one line for a GPU the machine lacks, the CPU's numbers unchanged, Ray
tasks that ask for what their run uses; and, on a CUDA machine (`-m cuda`), real tiny runs on the GPU whose
checkpoints load and play on the CPU."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from ncbot.pipelines.config import load_config
from tests.learning_helpers import ncbot, write_tiny_config

torch.set_num_threads(1)
HAS_CUDA = torch.cuda.is_available()
no_gpu_here = pytest.mark.skipif(HAS_CUDA, reason="checks what a machine without a CUDA GPU does; this one has one")


def _numbers(report: dict) -> dict:
    """Everything in eval.json except wall-clock times and the run's identity."""
    drop = {"wall_time", "train_wall_time_s", "train_cpu_time_s", "time_to_0995_s", "run_id"}
    clean = {k: v for k, v in report.items() if k not in drop and k != "history"}
    clean["history"] = [{k: v for k, v in h.items() if k not in drop} for h in report["history"]]
    return clean


# --- the option ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("spelling", ["auto", "cpu", "cuda", "cuda:0", "cuda:3"])
def test_config_accepts_the_device_spellings(tmp_path: Path, spelling: str) -> None:
    assert load_config(write_tiny_config(tmp_path), [f"train.device={spelling}"]).train.device == spelling


def test_default_device_is_auto(tmp_path: Path) -> None:
    assert load_config(write_tiny_config(tmp_path)).train.device == "auto"


@pytest.mark.parametrize("spelling", ["gpu", "CUDA", "cuda:x", "mps", "cpu:0", "cuda:0,1"])
def test_config_rejects_other_devices_in_one_line(tmp_path: Path, spelling: str) -> None:
    with pytest.raises(ValueError) as caught:
        load_config(write_tiny_config(tmp_path), [f"train.device={spelling}"])
    assert str(caught.value) == (f"config key 'train.device' must be auto, cpu, cuda or cuda:N (N a GPU index), "
                                 f"got {spelling!r}")


def test_config_rejects_a_device_that_is_not_a_string(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"^config key 'train.device' must be a string, got 1$"):
        load_config(write_tiny_config(tmp_path), ["train.device=1"])


def test_auto_and_cpu_resolve_to_what_torch_sees() -> None:
    from ncbot.modules.device import resolve_device

    assert resolve_device("cpu") == torch.device("cpu")
    assert resolve_device("auto").type == ("cuda" if HAS_CUDA else "cpu")


@no_gpu_here
@pytest.mark.parametrize("spelling", ["cuda", "cuda:1"])
def test_a_gpu_this_machine_lacks_is_one_line_naming_the_key_and_what_is_available(spelling: str) -> None:
    from ncbot.modules.device import resolve_device

    with pytest.raises(ValueError) as caught:
        resolve_device(spelling)
    line = str(caught.value)
    assert "\n" not in line and "'train.device'" in line and repr(spelling) in line and "available: cpu" in line


def test_a_gpu_index_past_the_machines_gpus_is_one_line() -> None:
    from ncbot.modules.device import resolve_device

    with pytest.raises(ValueError, match=r"'train.device' is 'cuda:999'.*available: cpu"):
        resolve_device("cuda:999")


@no_gpu_here
def test_cli_train_on_cuda_without_a_gpu_is_one_line_and_exit_code_2(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = ncbot("train", str(write_tiny_config(tmp_path)), "train.device=cuda", "--out", str(out), timeout=240)
    assert done.returncode == 2, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("ncbot: error: config key 'train.device' is 'cuda'"), done.stderr
    assert "available: cpu" in lines[0] and "Traceback" not in done.stderr
    assert not out.exists()  # refused before the run folder is claimed


def test_cli_train_with_a_misspelt_device_is_one_line_and_exit_code_2(tmp_path: Path) -> None:
    done = ncbot("train", str(write_tiny_config(tmp_path)), "train.device=gpu", "--out", str(tmp_path / "r"),
                 timeout=240)
    assert done.returncode == 2 and done.stderr.strip().splitlines() == [
        "ncbot: error: config key 'train.device' must be auto, cpu, cuda or cuda:N (N a GPU index), got 'gpu'"]


# --- the CPU's numbers ---------------------------------------------------------------------------------------------

@no_gpu_here
def test_tiny_run_on_cpu_equals_the_run_on_auto_here(tmp_path: Path) -> None:
    from ncbot.pipelines.train.run import train

    path = write_tiny_config(tmp_path)
    on_cpu = train(load_config(path, ["train.device=cpu"]), tmp_path / "cpu")
    on_auto = train(load_config(path, ["train.device=auto"]), tmp_path / "auto")
    assert _numbers(on_cpu) == _numbers(on_auto)
    first = torch.load(tmp_path / "cpu" / "checkpoint.pt", weights_only=True)["qnet"]
    second = torch.load(tmp_path / "auto" / "checkpoint.pt", weights_only=True)["qnet"]
    assert all(torch.equal(first[key], second[key]) for key in first)


def test_cpu_adapters_change_nothing() -> None:
    """On the CPU the evaluation calls the policy itself and a checkpoint's state is saved as it is."""
    from ncbot.modules.device import on_device, to_cpu
    from ncbot.modules.networks.qnet import MLPReader, make_qnet

    qnet = make_qnet(5, 3, [4])
    assert on_device(qnet) is qnet
    state = {"qnet": qnet.state_dict(), "history": [{"a": 1.0}], "rng": torch.get_rng_state()}
    assert to_cpu(state) is state
    reader = MLPReader.of(qnet.module)
    x = torch.rand(5)
    assert torch.allclose(torch.from_numpy(reader(x.numpy())), qnet.module(x).detach(), atol=1e-6)


# --- on a CUDA GPU (scripts/device_check.sh) ---------------------------------------------------------------------

ULTIMATE = {"env": {"game": "ultimate", "batch_size": 32}, "agent": {"hidden": [64, 64]},
            "collector": {"frames_per_batch": 128, "total_frames": 1024, "init_random_frames": 128,
                          "annealing_frames": 512},
            "loss": {"gamma": 0.95, "bootstrap": "greedy"}, "train": {"eval_every_frames": 512},
            "eval": {"games": 20, "periodic_games": 10}, "checkpoint": {"every_frames": 512, "keep": 1}}


@pytest.mark.cuda
def test_learner_networks_and_replay_storage_live_on_cuda(tmp_path: Path) -> None:
    from ncbot.pipelines.train.build import assemble, check_run

    config = load_config(write_tiny_config(tmp_path), ["train.device=cuda", "buffer.prioritized=true",
                                                       "buffer.augment=d4", "optim.precision=bf16"])
    parts = assemble(config, check_run(config), seed=0)
    try:
        assert parts.device.type == "cuda"
        assert all(p.device.type == "cuda" for p in parts.qnet.parameters())
        assert all(p.device.type == "cuda" for p in parts.learner.objective.parameters())
        target = parts.learner.objective.target_value_network_params
        assert all(p.device.type == "cuda" for p in target.values(True, True))
        assert parts.agent.egreedy.eps.device.type == "cuda"
        assert torch.device(parts.buffer.storage.device).type == "cuda"
        assert parts.learner.symmetries.generator.device.type == "cuda"
        # a few real updates on batches the env made: the state lives on the GPU, the Adam moments too
        from ncbot.modules.replay.transitions import prepare_transitions
        from ncbot.pipelines.train.build import make_collector

        collector = make_collector(parts.env, parts.agent.explore, 128, 256, device=parts.device)
        for batch in collector:
            assert batch.device.type == "cuda"
            parts.buffer.extend(prepare_transitions(batch, reward="outcome", loss_reward=-5.0, bootstrap="available",
                                                    lookahead=config.lookahead))
        collector.shutdown()
        losses = parts.learner.update_many(parts.buffer, 3)
        assert len(losses) == 3 and all(bool(torch.isfinite(loss)) for loss in losses)
        sample = parts.buffer.sample(4)
        assert sample.get("observation").device.type == "cuda"
        moments = [s["exp_avg"] for s in parts.learner.optimizer.state.values()]
        assert moments and all(m.device.type == "cuda" for m in moments)
    finally:
        parts.env.close()


@pytest.mark.cuda
def test_tiny_3x3_run_on_cuda_completes_and_its_checkpoint_plays_on_the_cpu(tmp_path: Path) -> None:
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.checkpoint import load_checkpoint
    from ncbot.pipelines.evaluate.games import evaluate_agent
    from ncbot.pipelines.train.run import train

    config = load_config(write_tiny_config(tmp_path), ["train.device=cuda", "checkpoint.save_buffer=true"])
    report = train(config, tmp_path / "run")
    assert report["frames"] == 512 and report["updates"] > 0 and report["first"]["games"] == 60
    saved = json.loads((tmp_path / "run" / "eval.json").read_text())
    assert saved["second"]["games"] == 60

    for path in [tmp_path / "run" / "checkpoint.pt", *sorted((tmp_path / "run" / "checkpoints").glob("*.pt"))]:
        data = torch.load(path, map_location="cpu", weights_only=True)  # plain tensors only
        tensors = [t for t in _leaves(data) if isinstance(t, torch.Tensor)]
        assert tensors and all(t.device.type == "cpu" for t in tensors), path
    final = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    assert final["n_actions"] == 18
    loaded, greedy = load_agent(tmp_path / "run" / "checkpoint.pt")  # on the CPU
    assert all(p.device.type == "cpu" for p in greedy.parameters())
    result = evaluate_agent(loaded, greedy, games=20, first="robot", seed=5)
    assert result.games == 20
    on_gpu = evaluate_agent(*load_agent(tmp_path / "run" / "checkpoint.pt", device="cuda"), games=20, first="robot",
                            seed=5)
    assert on_gpu.games == 20


def _leaves(value):
    if isinstance(value, dict):
        for item in value.values():
            yield from _leaves(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _leaves(item)
    else:
        yield value


@pytest.mark.cuda
def test_tiny_run_on_cuda_resumes_from_its_checkpoint(tmp_path: Path) -> None:
    from ncbot.pipelines.train.run import train

    path = write_tiny_config(tmp_path, checkpoint={"save_buffer": True})
    config = load_config(path, ["train.device=cuda", "collector.total_frames=256"])
    train(config, tmp_path / "run")
    longer = load_config(tmp_path / "run" / "config.yaml", ["collector.total_frames=512"])
    (tmp_path / "run" / "eval.json").unlink()
    report = train(longer, tmp_path / "run", resume=True)
    assert report["frames"] == 512


@pytest.mark.cuda
def test_tiny_run_on_cuda_with_the_learning_options(tmp_path: Path) -> None:
    """Prioritised replay, board symmetries, bf16 autocast, n-step returns and the self-play user on the GPU."""
    from ncbot.pipelines.train.run import train

    config = load_config(write_tiny_config(tmp_path), [
        "train.device=cuda", "buffer.prioritized=true", "buffer.augment=d4", "optim.precision=bf16", "loss.n_step=3",
        "selfplay.enabled=true", "selfplay.snapshot_every_frames=256"])
    report = train(config, tmp_path / "run")
    assert report["frames"] == 512 and report["updates"] > 0


@pytest.mark.cuda
def test_tiny_ultimate_run_on_cuda_completes(tmp_path: Path) -> None:
    from ncbot.pipelines.train.run import train

    config = load_config(write_tiny_config(tmp_path, **ULTIMATE), ["train.device=cuda"])
    report = train(config, tmp_path / "run")
    assert report["frames"] == 1024 and report["updates"] > 0 and report["first"]["games"] == 20


@pytest.mark.cuda
def test_guided_search_reads_a_network_on_cuda(tmp_path: Path) -> None:
    from ncbot.pipelines.agents import guided_search, load_agent
    from ncbot.modules.search.guided_mcts import GuidedMCTSPolicy
    from ncbot.pipelines.evaluate.games import evaluate_agent
    from ncbot.pipelines.train.run import train

    config = load_config(write_tiny_config(tmp_path), ["train.device=cuda", "collector.total_frames=256"])
    train(config, tmp_path / "run")
    loaded, greedy = load_agent(tmp_path / "run" / "checkpoint.pt", device="cuda")
    policy = GuidedMCTSPolicy(greedy, guided_search(loaded, greedy, 16), seed=0)
    result = evaluate_agent(loaded, policy, games=8, first="robot", seed=1)
    assert result.games == 8 and policy.decisions > 0

