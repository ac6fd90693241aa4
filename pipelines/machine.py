"""Which machine and kernels produced a run: recorded in every eval.json beside the numbers.

Why: "same seed and config, same numbers" holds on one machine. Across machines the float results of training can
differ, because torch picks its CPU kernels by the instruction sets it finds (``ATEN_CPU_CAPABILITY``: default,
avx2, avx512) and a different kernel sums in a different order; library versions and thread counts change the order
too. A reader comparing two runs can only tell a real difference from a different machine if each run says which
CPU, which kernels, how many threads and which versions made it (docs/reproduction.md, "Same numbers").
"""
from __future__ import annotations

import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

VERSIONED = ("torch", "torchrl", "tensordict", "numpy")


def cpu_model(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The CPU's model name (Linux: /proc/cpuinfo's "model name"; elsewhere the platform's processor string)."""
    try:
        for line in cpuinfo.read_text(encoding="utf-8", errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and value.strip():
                return value.strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _version(package: str) -> str | None:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def machine_record() -> dict[str, Any]:
    """What made this process's numbers: CPU model and count, torch's CPU kernel level and thread count, the
    ``ATEN_CPU_CAPABILITY`` the user forced (None: torch chose), CUDA device if any, and the library versions."""
    import torch

    record: dict[str, Any] = {
        "cpu_model": cpu_model(),
        "cpu_count": os.cpu_count(),
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "aten_cpu_capability_env": os.environ.get("ATEN_CPU_CAPABILITY"),
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        **{package: _version(package) for package in VERSIONED},
    }
    if torch.cuda.is_available():
        record["cuda_device"] = torch.cuda.get_device_name(0)
    return record
