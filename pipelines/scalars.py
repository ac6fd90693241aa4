"""The run's scalar log through TorchRL's loggers (`torchrl.record.loggers.get_logger`), as TorchRL's sota scripts do.

Training writes `train/loss`, `train/epsilon`, `train/lr`, `train/updates_per_s`, `train/frames_per_s` per collected
batch and every periodic evaluation as `eval/<metric>` (task_success, win, draw, loss, avg_length, ...), each with
step = collected env frames, into the run folder. The backend is the config's `logger.backend`: csv (default;
RUN/scalars/scalars/<name>.csv, lines `step,value`), tensorboard, wandb, mlflow (each when installed) or none.
MCAP stays the episode log (logs package); eval.json keeps the same evaluation records the learning-curve PNG draws.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from typing import Any

EXPERIMENT = "scalars"  # TorchRL's experiment name: the sub-folder of the run folder the backend writes into
PACKAGES = {"tensorboard": "tensorboard", "wandb": "wandb", "mlflow": "mlflow"}  # backend -> package it needs
EVAL_KEYS = ("task_success", "win", "draw", "loss", "truncated", "all_negative", "avg_length", "avg_reward", "avg_return")


def check_backend(backend: str) -> None:
    """Raise one clear ValueError when `backend` needs a package that is not installed (before a run starts)."""
    package = PACKAGES.get(backend)
    if package is not None and importlib.util.find_spec(package) is None:
        raise ValueError(f"config key 'logger.backend' is {backend!r} but the {package!r} package is not installed "
                         f"(pip install {package}); use csv or none")


class ScalarLog:
    """A TorchRL logger bound to one run: `log(values, step)` writes every finite number under its name."""

    def __init__(self, backend: str, run_dir: str | Path) -> None:
        check_backend(backend)
        from torchrl.record.loggers import get_logger

        kwargs: dict[str, Any] = {}
        experiment = EXPERIMENT
        if backend == "wandb":  # files under the run folder; the W&B run is named after it
            kwargs["wandb_kwargs"] = {"project": "ncbot"}
            experiment = Path(run_dir).name
        self.logger = get_logger(backend, logger_name=str(run_dir), experiment_name=experiment, **kwargs)

    def log(self, values: dict[str, float], step: int) -> None:
        for name, value in values.items():
            if value is not None and math.isfinite(value):
                self.logger.log_scalar(name, float(value), step=step)


def open_scalar_log(backend: str, run_dir: str | Path) -> ScalarLog | None:
    """The run's scalar log, or None for `logger.backend: none`."""
    return None if backend == "none" else ScalarLog(backend, run_dir)


def eval_scalars(record: dict[str, Any]) -> dict[str, float]:
    """A periodic evaluation record (eval.json's history) as `eval/<metric>` scalars."""
    return {f"eval/{key}": record[key] for key in EVAL_KEYS if isinstance(record.get(key), (int, float))}


def read_csv_scalars(run_dir: str | Path) -> dict[str, list[tuple[int, float]]]:
    """The csv backend's records of a run: name (e.g. 'eval/task_success') -> [(step, value), ...]."""
    root = Path(run_dir) / EXPERIMENT / "scalars"
    series: dict[str, list[tuple[int, float]]] = {}
    for path in sorted(root.rglob("*.csv")):
        name = path.relative_to(root).with_suffix("").as_posix()
        rows = [line.split(",") for line in path.read_text().splitlines() if line.strip()]
        series[name] = [(int(float(step)), float(value)) for step, value in rows]
    return series
