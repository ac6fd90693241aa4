"""Every run's eval.json says which machine, kernels, threads and library versions made its numbers."""
from __future__ import annotations

import json
from pathlib import Path

import torch

from ncbot.pipelines.config import load_config
from ncbot.pipelines.machine import cpu_model, machine_record
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)


def test_the_record_names_the_cpu_kernels_threads_and_versions(monkeypatch) -> None:
    import tensordict
    import torchrl

    monkeypatch.setenv("ATEN_CPU_CAPABILITY", "default")  # read back as set; torch chose its kernels at import
    record = machine_record()
    assert record["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert record["aten_cpu_capability_env"] == "default"
    assert record["torch_threads"] == torch.get_num_threads() == 1
    assert (record["torch"], record["torchrl"], record["tensordict"]) == (
        torch.__version__, torchrl.__version__, tensordict.__version__)
    assert record["cpu_model"] and record["cpu_count"] >= 1
    json.dumps(record)  # goes into eval.json as it is


def test_cpu_model_reads_cpuinfo_and_falls_back(tmp_path: Path) -> None:
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC 9654\n")
    assert cpu_model(cpuinfo) == "AMD EPYC 9654"
    assert cpu_model(tmp_path / "missing")  # the platform's string, never empty


def test_a_run_records_its_machine_in_eval_json(tmp_path: Path) -> None:
    config = load_config(write_tiny_config(tmp_path), ["collector.total_frames=128"])
    train(config, tmp_path / "run")
    saved = json.loads((tmp_path / "run" / "eval.json").read_text())
    assert saved["machine"] == machine_record()
