"""Checkpoints: written atomically (`fileio.atomic_path`), read back with `weights_only=True`.

Two kinds live in a run folder:
- `checkpoint.pt`: the final agent (Q-network weights + resolved config): what `ncbot eval` loads.
- `checkpoints/step-NNNNNNNNN.pt`: periodic training state (network, target network, optimiser, epsilon, replay
  buffer, counters, RNG, evaluation history) that `ncbot train --resume DIR` continues from.
A crash can leave a stray `.NAME.*.tmp` file but never a half-written checkpoint under its final name; `--resume`
removes such leftovers, since the resumed run is now the folder's only writer.
"""
from __future__ import annotations

import os
import pickle
import re
import zipfile
from pathlib import Path
from typing import Any

import torch

from fileio import TEMP_GLOB, atomic_path

FORMAT = "ncbot-dqn/1"
FINAL_NAME = "checkpoint.pt"
PERIODIC_DIR = "checkpoints"
PERIODIC_PATTERN = re.compile(r"^step-(\d{9})\.pt$")


def atomic_save(obj: Any, path: str | os.PathLike) -> Path:
    """torch.save `obj` to `path` atomically."""
    with atomic_path(path) as temp:
        torch.save(obj, temp)
    return Path(path)


def load_checkpoint(path: str | os.PathLike) -> dict[str, Any]:
    """Load an ncbot checkpoint safely (`weights_only=True`); one-line errors for missing or corrupt files."""
    path = Path(path)
    if path.is_dir():
        path = path / FINAL_NAME
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {str(path)!r} not found (expected a .pt file written by ncbot train)")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, OSError) as error:
        reason = str(error).splitlines()[0][:120] if str(error) else type(error).__name__
        raise ValueError(f"checkpoint {str(path)!r} is corrupt or unreadable ({reason})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"checkpoint {str(path)!r} is not an ncbot DQN checkpoint (expected format {FORMAT})")
    return data


def periodic_path(run_dir: str | os.PathLike, frames: int) -> Path:
    return Path(run_dir) / PERIODIC_DIR / f"step-{frames:09d}.pt"


def periodic_checkpoints(run_dir: str | os.PathLike) -> list[Path]:
    """Periodic checkpoints of a run, oldest first."""
    folder = Path(run_dir) / PERIODIC_DIR
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if PERIODIC_PATTERN.match(p.name))


def save_periodic(state: dict[str, Any], run_dir: str | os.PathLike, frames: int, keep: int) -> Path:
    """Write one periodic checkpoint and delete the oldest beyond `keep`."""
    path = atomic_save({"format": FORMAT, **state}, periodic_path(run_dir, frames))
    for old in periodic_checkpoints(run_dir)[:-keep]:
        old.unlink(missing_ok=True)
    return path


def latest_training_state(run_dir: str | os.PathLike) -> dict[str, Any]:
    """The newest periodic checkpoint of a run, for `--resume`; one-line errors if none exists or it is corrupt."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise FileNotFoundError(f"run folder {str(run_dir)!r} not found (expected the --out folder of an earlier ncbot train)")
    found = periodic_checkpoints(run_dir)
    if not found:
        raise FileNotFoundError(f"no periodic checkpoint in {str(run_dir / PERIODIC_DIR)!r} to resume from")
    remove_stray_temp_files(run_dir)
    state = load_checkpoint(found[-1])
    if "learner" not in state:
        raise ValueError(f"checkpoint {str(found[-1])!r} holds no training state to resume from")
    return state


def remove_stray_temp_files(run_dir: str | os.PathLike) -> list[Path]:
    """Delete the temp files `fileio.atomic_path` leaves when a run is killed mid-write (run folder and its
    checkpoints); returns what was removed. Only for a folder no other process is writing to."""
    run_dir = Path(run_dir)
    stray = [p for folder in (run_dir, run_dir / PERIODIC_DIR) if folder.is_dir()
             for p in folder.glob(TEMP_GLOB) if p.is_file()]
    for path in stray:
        path.unlink(missing_ok=True)
    return stray
