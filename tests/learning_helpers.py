"""Shared tiny-run settings for the learning-pipeline tests (a few hundred frames, small network)."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import yaml

TINY = {
    "env": {"game": "standard", "temporal": True, "batch_size": 16, "first": "alternate"},
    "agent": {"name": "proposed", "hidden": [32, 32]},
    "collector": {"frames_per_batch": 64, "total_frames": 512, "init_random_frames": 64, "annealing_frames": 256},
    "buffer": {"size": 2000, "batch_size": 32},
    "optim": {"lr": 0.001, "updates_per_batch": 2},
    "loss": {"gamma": 0.9, "target_period": 10, "reward": "outcome"},
    "train": {"seed": 3, "eval_every_frames": 256},
    "eval": {"games": 60, "periodic_games": 20},
    "logger": {"mcap": False, "progress": False},
    "checkpoint": {"every_frames": 256, "keep": 2},
}


def write_tiny_config(folder: Path, **sections: dict) -> Path:
    data = {key: dict(value) for key, value in TINY.items()}
    for section, values in sections.items():
        data.setdefault(section, {}).update(values)
    path = folder / "tiny.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def write_paper_configs(folder: Path, total_frames: int) -> Path:
    """A folder standing in for pipelines/configs/paper/ in reproduce tests: the 3x3 row's config, faithful options
    on, tiny network and budget."""
    configs = folder / "configs"
    configs.mkdir()
    tiny = write_tiny_config(folder, env={"taken_squares": "refused", "dialogues": "paper", "first": "robot"},
                             collector={"total_frames": total_frames}, eval={"games": 20, "periodic_games": 10})
    shutil.copy(tiny, configs / "standard_proposed_temporal.yaml")
    return configs


def ncbot(*args: str, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def ncbot_here(*args: str) -> tuple[int, str, str]:
    """Run `ncbot ARGS` in this process, through the CLI's error boundary: (exit code, stdout, stderr)."""
    import contextlib
    import io

    import pytest

    from ncbot.pipelines.cli.app import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), pytest.raises(SystemExit) as done:
        main(list(args))
    return done.value.code, out.getvalue(), err.getvalue()
