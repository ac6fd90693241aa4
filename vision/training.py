"""The shipped weights: what they are trained on and the one function that reproduces them.

Three sources, all from the "pen" stroke model only (the "sketch" and "hershey" styles stay unseen, as the
held-out handwriting): generated cells (clean and noisy mixed); cells cut from generated camera frames
by the real reading pipeline (`ncbot.vision.grid.extract_cells`) with their true labels, so the classifier sees
exactly the crops, warps and grid-line remnants it will get when reading boards; and generated cells taken
through what a harsh photo does to a cell (`ncbot.vision.data.harsh_cells`: motion streaks, dim light and its
amplified noise, JPEG, faint ink), which the first two never show.

Reproduce: `ncbot vision train --out vision/weights/cell_cnn.pt` (defaults below).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from dataclasses import asdict, dataclass, field

import numpy as np

from ncbot.vision.classifier.model import CellCNN
from ncbot.vision.classifier.train import FitConfig, fit
from ncbot.vision.data import TRAIN_SEED
from ncbot.vision.data.cells import make_cells
from ncbot.vision.data.frames import make_frame
from ncbot.vision.data.harsh_cells import make_harsh_cells
from ncbot.vision.grid import extract_cells
from ncbot.vision.labels import symbol_to_index


@dataclass
class DefaultTraining:
    """Data and optimisation of the shipped weights."""

    n_cells: int = 24_000          # generated cells (60% noisy)
    n_frames_3: int = 700          # 3x3 photos whose cells are cut by the reader (9 cells each)
    n_frames_9: int = 120          # 9x9 photos (81 cells each)
    n_harsh_cells: int = 8_000     # generated cells as a harsh photo leaves them (seed + 300,000)
    cell_styles: tuple[str, ...] = ("pen",)   # handwriting of the generated cells (vision.strokes.TRAINING_STYLES)
    harsh_styles: tuple[str, ...] = ("pen", "hasty")  # ... and of the harsh cells
    seed: int = TRAIN_SEED         # data seed; test data uses vision.data.TEST_SEED and up
    train: FitConfig = field(default_factory=lambda: FitConfig(epochs=14, batch_size=64, lr=3e-3, seed=0))


def frame_cells(grid: int, n_frames: int, seed: int, progress: Callable[..., Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cells cut by the reading pipeline from n generated photos, with their true labels."""
    images, labels = [], []
    frames = range(n_frames)
    for i in progress(frames, desc=f"{grid}x{grid} photos", unit="photo", leave=False) if progress else frames:
        frame = make_frame(grid, seed + i)
        try:
            view = extract_cells(frame.image, grid)
        except ValueError:
            continue  # the reader could not find the grid: nothing to learn from this photo
        images.append(view.cell_images)
        labels.extend(symbol_to_index(s) for s in frame.board)
    if not images:
        return np.zeros((0, 40, 40), np.uint8), np.zeros(0, np.int64)
    return np.concatenate(images), np.array(labels, np.int64)


def training_set(config: DefaultTraining, progress: Callable[..., Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """All training cells of the shipped weights (deterministic in config.seed)."""
    cells, labels = make_cells(config.n_cells, config.seed, noisy_fraction=0.6, styles=config.cell_styles)
    f3, l3 = frame_cells(3, config.n_frames_3, config.seed + 100_000, progress)
    f9, l9 = frame_cells(9, config.n_frames_9, config.seed + 200_000, progress)
    harsh, harsh_labels = make_harsh_cells(config.n_harsh_cells, config.seed + 300_000, styles=config.harsh_styles)
    return np.concatenate([cells, f3, f9, harsh]), np.concatenate([labels, l3, l9, harsh_labels])


def train_default(config: DefaultTraining = DefaultTraining(), progress: Callable[..., Any] | None = None) -> tuple[CellCNN, dict]:
    """Train the shipped classifier; returns it and the metadata stored with the weights."""
    images, labels = training_set(config, progress)
    model = fit(images, labels, config.train, progress=progress, description="train default CNN")
    meta = {k: ",".join(v) if isinstance(v, tuple) else v for k, v in asdict(config).items() if k != "train"}
    meta.update({f"train_{k}": v for k, v in asdict(config.train).items()})
    meta["n_training_cells"] = int(len(images))
    return model, meta
