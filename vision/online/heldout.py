"""The cells a reader that learns from play is scored on: per handwriting style, never trained or tuned on.

For the budget's held-out styles ("sketch", "hershey") these are exactly the budget's held-out cells (so a figure
before play is the data-budget figure of docs/vision.md); any other style (the tuning "marker", or a style added
later) gets its own seed from `ncbot.vision.data.STYLE_CHECK_SEED`.
"""
from __future__ import annotations

import zlib

import numpy as np

from ncbot.vision.classifier.inference import CellClassifier
from ncbot.vision.data import STYLE_CHECK_SEED, TEST_SEED
from ncbot.vision.data.cells import make_cells
from ncbot.vision.strokes import HELDOUT_STYLES, STYLES

STYLE_CELLS = 600  # per style, half noisy: the budget's held-out size


def style_cells(style: str, n: int = STYLE_CELLS) -> tuple[np.ndarray, np.ndarray]:
    """(images, labels) of `n` cells in handwriting `style`, half of them noisy."""
    if style not in STYLES:
        raise ValueError(f"handwriting style {style!r} is unknown; expected one of {', '.join(STYLES)}")
    seed = TEST_SEED + 1 + HELDOUT_STYLES.index(style) if style in HELDOUT_STYLES else \
        STYLE_CHECK_SEED + zlib.crc32(style.encode()) % 100_000
    return make_cells(n, seed, noisy_fraction=0.5, styles=(style,))


def accuracy_by_style(classifier: CellClassifier, cells: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, float]:
    """Share of each style's cells read right."""
    return {style: float((classifier.predict(images) == labels).mean()) for style, (images, labels) in cells.items()}
