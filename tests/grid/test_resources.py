"""What a grid's task asks a cluster for: a Ray task or a Slurm job gets its run's `train.num_threads` CPUs and a GPU
when the run trains on CUDA; a run no node can hold is refused before it waits forever; Slurm's options are checked
in one line each."""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.learning_helpers import write_tiny_config


def test_ray_tasks_ask_for_the_runs_threads_and_a_gpu_when_it_runs_on_cuda() -> None:
    from ncbot.pipelines.grid.ray_backend import RAY_MAX_RETRIES, task_resources

    assert RAY_MAX_RETRIES == 0
    assert task_resources(4, "cpu", cluster_gpus=2) == {"num_cpus": 4.0, "num_gpus": 0.0}
    assert task_resources(1, "cuda", cluster_gpus=2) == {"num_cpus": 1.0, "num_gpus": 1.0}
    assert task_resources(2, "cuda:0", cluster_gpus=2, gpus_per_run=0.25) == {"num_cpus": 2.0, "num_gpus": 0.25}
    assert task_resources(1, "auto", cluster_gpus=1) == {"num_cpus": 1.0, "num_gpus": 1.0}
    assert task_resources(1, "auto", cluster_gpus=0) == {"num_cpus": 1.0, "num_gpus": 0.0}


def test_a_run_no_node_can_hold_is_refused_before_it_waits_forever() -> None:
    from ncbot.pipelines.grid.ray_backend import check_fits

    nodes = [{"CPU": 16.0, "GPU": 1.0}, {"CPU": 64.0}]
    check_fits([("a", {"num_cpus": 64.0, "num_gpus": 0.0}), ("b", {"num_cpus": 8.0, "num_gpus": 1.0})], nodes)
    with pytest.raises(ValueError, match=r"run big asks for 32 CPUs \(train.num_threads\) and 1 GPUs"):
        check_fits([("big", {"num_cpus": 32.0, "num_gpus": 1.0})], nodes)


def test_planned_runs_report_their_threads_and_device(tmp_path: Path) -> None:
    from ncbot.pipelines.grid.plan import PlannedRun

    config = write_tiny_config(tmp_path)
    run = PlannedRun("x/seed0", tmp_path / "x", config, ["train.num_threads=3", "train.device=cpu"])
    assert run.settings() == ("x/seed0", 3, "cpu")
    assert PlannedRun("y", tmp_path / "y", config).settings() == ("y", 1, "auto")


def test_slurm_time_limits_and_sbatch_options_are_read_or_refused_in_one_line() -> None:
    from ncbot.pipelines.grid.slurm_backend import sbatch_options, time_minutes

    assert [time_minutes(text) for text in ("90", "2:00:00", "1-12:00:00", "0:00:30")] == [90, 120, 2160, 1]
    for bad in ("2h", "1:2:3", "0", "1:60:00", ""):
        with pytest.raises(ValueError, match="is not a Slurm time limit|longer than zero"):
            time_minutes(bad)
    assert sbatch_options(("mem=8G", "--account=proj", "cpus-per-gpu=4")) == \
        {"mem": "8G", "account": "proj", "cpus_per_gpu": "4"}
    with pytest.raises(ValueError, match="is not KEY=VALUE of an sbatch option"):
        sbatch_options(("mem",))


def test_backend_options_belong_to_their_backend() -> None:
    from ncbot.pipelines.grid.runner import Cluster

    with pytest.raises(ValueError, match="--address 1.2.3.4:6379 needs --backend ray"):
        Cluster(address="1.2.3.4:6379").check()
    with pytest.raises(ValueError, match="--partition needs --backend slurm"):
        Cluster(backend="ray", partition="gpu").check()
    with pytest.raises(ValueError, match="--retries must be 0 to 100"):
        Cluster(retries=-1).check()
    with pytest.raises(ValueError, match="unknown backend 'k8s'; expected one of local, ray, slurm"):
        Cluster(backend="k8s").check()
    with pytest.raises(ValueError, match="--time '2h' is not a Slurm time limit"):
        Cluster(backend="slurm", time_limit="2h").check()
