"""Cell image -> classifier input, the one normalisation shared by training, `classify` and board reading.

Ink is made bright on a dark background and the contrast is stretched per cell, so pen colour, paper
shade and exposure matter less; a floor on the stretch keeps an empty cell's noise small.
"""
from __future__ import annotations

import cv2
import numpy as np
import torch

from ncbot.vision.labels import CELL_SIZE

_MIN_CONTRAST = 60.0  # gray levels: an empty cell's noise is not stretched to full ink


def to_gray_cell(image: np.ndarray) -> np.ndarray:
    """Any uint8 gray/BGR/BGRA crop -> 40x40 uint8 gray (area-resampled)."""
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if image.ndim != 2 or image.size == 0:
        raise ValueError(f"a cell image must be a non-empty gray or colour image; got shape {image.shape}")
    if image.shape != (CELL_SIZE, CELL_SIZE):
        image = cv2.resize(image, (CELL_SIZE, CELL_SIZE), interpolation=cv2.INTER_AREA)
    return image


def to_input(cells: np.ndarray) -> torch.Tensor:
    """uint8 (N, 40, 40) gray cells -> float32 (N, 1, 40, 40) in [0, 1], ink bright."""
    if cells.ndim != 3 or cells.shape[1:] != (CELL_SIZE, CELL_SIZE):
        raise ValueError(f"cells must be an (N, {CELL_SIZE}, {CELL_SIZE}) array; got shape {cells.shape}")
    x = cells.astype(np.float32)
    flat = x.reshape(len(x), -1)
    n = flat.shape[1]
    ranks = [n // 100, n // 2]  # one partial sort gives both the 1st percentile and the median
    parts = np.partition(flat, ranks, axis=1)
    darkest, background = parts[:, ranks[0]], parts[:, ranks[1]]
    scale = np.maximum(background - darkest, _MIN_CONTRAST)
    ink = (background[:, None, None] - x) / scale[:, None, None]
    return torch.from_numpy(np.clip(ink, 0.0, 1.0))[:, None]
