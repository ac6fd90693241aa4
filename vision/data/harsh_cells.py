"""Training cells as a harsh photo leaves them: one cell through the "harsh" camera and the reader.

Why: on harsh 9x9 photos most wrong cells are the classifier's, even when cut at the true grid crossings,
and they follow the motion blur (docs/vision.md): a 5-7 px streak turns a thin pen stroke into a faint blob,
which the generated noisy cells (Gaussian blur only) never show. So a generated cell is taken the way a
cell of a harsh photo goes: shrunk to its size in the frame (a 9x9 cell is 22-30 px inside its grid lines,
a 3x3 cell 40-75 px), dimmed and colour-cast, streaked by motion, given sensor noise, JPEG-compressed in
colour, white-balanced back (which amplifies the noise of a dim, cast channel), resampled at the reader's
rho pixels per cell, smoothed by the reader's own grain filter and area-shrunk to 40x40. The ranges are the
harsh conditions' own (`ncbot.vision.data.conditions.HARSH`); only the training handwriting ("pen") and training
seeds are used for these cells (`ncbot.vision.training`).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ncbot.vision.data.cells import draw_cell, generated_cells
from ncbot.vision.data.conditions import CAST_GAINS, HARSH, HarshRanges, motion_kernel
from ncbot.vision.grid import CELL_INSET, DEFAULT_RHO, denoise
from ncbot.vision.labels import CELL_SIZE

BALANCED_PAPER = 225.0  # the reader's white balance brings paper to about this level (vision.illumination)
MAX_GAIN = 4.0          # ... gaining a channel up by at most this much, never down


@dataclass(frozen=True)
class HarshCellRanges:
    """How a harsh training cell is drawn, beyond the photo conditions' own ranges (`HarshRanges`)."""

    noisy_share: float = 0.5               # cells drawn with the noisy set's extras (grid remnants, smudges, ...)
    nine_share: float = 0.7                # cells sized as on a 9x9 sheet (small: blur matters most there)
    side_9: tuple[int, int] = (22, 31)     # px of a 9x9 cell inside its grid lines, in a 640x480 frame
    side_3: tuple[int, int] = (40, 76)     # px of a 3x3 cell
    faint_chance: float = 0.3              # a light pen or light pressure ...
    faint_ink: tuple[float, float] = (0.4, 0.8)  # ... keeps this much of the ink's contrast


HARSH_CELL = HarshCellRanges()


def harsh_cell(label: int, rng: np.random.Generator, style: str = "pen", ranges: HarshRanges = HARSH,
               cell: HarshCellRanges = HARSH_CELL) -> np.ndarray:
    """One 40x40 uint8 gray cell of the given label as the reader cuts it from a harsh photo."""
    big = draw_cell(label, rng, noisy=bool(rng.random() < cell.noisy_share), style=style)
    if rng.random() < cell.faint_chance:
        paper = float(np.percentile(big, 90))
        big = paper - (paper - big) * rng.uniform(*cell.faint_ink)
    nine = bool(rng.random() < cell.nine_share)
    side = int(rng.integers(*(cell.side_9 if nine else cell.side_3)))
    small = cv2.resize(big, (side, side), interpolation=cv2.INTER_AREA)
    cast = str(rng.choice(ranges.casts))
    exposure = float(rng.uniform(*ranges.exposure))
    gains = np.array([rng.uniform(*g) for g in CAST_GAINS[cast]], np.float32) * exposure
    bgr = small[:, :, None] * gains[None, None, :]
    streak = motion_kernel(float(rng.uniform(*ranges.motion_px)), float(rng.uniform(0, np.pi)))
    bgr = cv2.filter2D(bgr, -1, streak, borderType=cv2.BORDER_REFLECT)
    bgr += rng.normal(0, rng.uniform(*ranges.noise_sigma) / np.sqrt(exposure), bgr.shape).astype(np.float32)
    quality = int(rng.integers(ranges.jpeg_quality[0], ranges.jpeg_quality[1] + 1))
    _, jpeg = cv2.imencode(".jpg", np.clip(bgr, 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, quality])
    bgr = cv2.imdecode(jpeg, cv2.IMREAD_COLOR).astype(np.float32)
    paper_level = np.percentile(bgr.reshape(-1, 3), 90, axis=0)
    bgr *= np.clip(BALANCED_PAPER / np.maximum(paper_level, 1.0), 1.0, MAX_GAIN)
    gray = cv2.cvtColor(np.clip(bgr, 0, 255).astype(np.uint8), cv2.COLOR_BGR2GRAY)
    inner = int(round(DEFAULT_RHO[9 if nine else 3] * (1 - 2 * CELL_INSET)))
    gray = denoise(cv2.resize(gray, (inner, inner), interpolation=cv2.INTER_LINEAR))
    return cv2.resize(gray, (CELL_SIZE, CELL_SIZE), interpolation=cv2.INTER_AREA)


def make_harsh_cells(n: int, seed: int, styles: tuple[str, ...] = ("pen",), ranges: HarshRanges = HARSH,
                     cell: HarshCellRanges = HARSH_CELL) -> tuple[np.ndarray, np.ndarray]:
    """n harsh cells with balanced labels in shuffled order: (uint8 (n, 40, 40), int64 (n,)); same seed, same cells."""
    if n < 0:
        raise ValueError(f"number of harsh cells must be >= 0; got {n}")
    return generated_cells(n, seed, lambda label, rng: harsh_cell(label, rng, styles[int(rng.integers(len(styles)))],
                                                                  ranges, cell))
