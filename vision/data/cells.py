"""Seeded 40x40 grayscale cell images: nought / cross / nothing, clean or noisy.

Stands in for the paper's photos of real handwriting (109 clean, 201 noisy cells). A cell is drawn at
twice the size and shrunk (as a camera would), with a random pen, ink and hand. "Noisy" adds what a
cell cut from a photo of a game sheet shows: partial grid lines at the borders, blur, lighting gradients,
sensor noise, smudges, off-centre marks and bits of a neighbour's mark.
"""
from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from ncbot.vision.labels import CELL_SIZE, LABELS, NOTHING
from ncbot.vision.strokes import draw_mark

SCALE = 2  # draw at 80x80, shrink to 40x40
INK_COLOURS = ((25, 25, 25), (60, 50, 45), (140, 45, 20), (110, 30, 10), (40, 40, 160), (30, 110, 30),
               (120, 40, 100), (90, 90, 90), (160, 70, 40))


def random_ink(rng: np.random.Generator) -> tuple[int, int, int]:
    """A pen colour (BGR): black, blue, red, green, purple or pencil gray, a little varied."""
    base = np.array(INK_COLOURS[int(rng.integers(len(INK_COLOURS)))], float)
    return tuple(int(v) for v in np.clip(base + rng.normal(0, 12, 3), 0, 200))


def _gray_ink(rng: np.random.Generator) -> tuple[int, int, int]:
    b, g, r = random_ink(rng)
    level = int(0.114 * b + 0.587 * g + 0.299 * r)
    return (level, level, level)


def _grid_remnants(img: np.ndarray, rng: np.random.Generator) -> None:
    side = img.shape[0]
    for edge in rng.permutation(4)[: int(rng.integers(1, 5))]:
        depth = rng.uniform(-0.02, 0.12) * side
        pos = depth if edge in (0, 2) else side - 1 - depth
        start, stop = sorted(rng.uniform(-0.2, 1.2, 2) * side)
        if stop - start < 0.3 * side:
            stop = start + 0.3 * side
        thickness = int(rng.integers(1, 7))
        level = int(rng.uniform(20, 140))
        tilt = rng.uniform(-0.04, 0.04) * side
        if edge in (0, 1):  # vertical line near the left / right border
            p0, p1 = (pos, start), (pos + tilt, stop)
        else:
            p0, p1 = (start, pos), (stop, pos + tilt)
        cv2.line(img, tuple(int(v) for v in p0), tuple(int(v) for v in p1), level, thickness, cv2.LINE_AA)


def _smudges(img: np.ndarray, rng: np.random.Generator) -> None:
    side = img.shape[0]
    for _ in range(int(rng.integers(1, 3))):
        blob = np.zeros_like(img, np.float32)
        centre = tuple(int(v) for v in rng.uniform(0, side, 2))
        axes = tuple(int(v) for v in rng.uniform(2, 0.25 * side, 2))
        cv2.ellipse(blob, centre, axes, rng.uniform(0, 180), 0, 360, 1.0, -1)
        blob = cv2.GaussianBlur(blob, (0, 0), rng.uniform(2, 6))
        img[:] = np.clip(img - blob * rng.uniform(10, 60), 0, 255)


def _neighbour_piece(img: np.ndarray, rng: np.random.Generator) -> None:
    """The edge of a mark drawn in the next cell, overlapping this cell's border."""
    side = img.shape[0]
    edge = int(rng.integers(4))
    along = rng.uniform(0.1, 0.9) * side
    out = side * rng.uniform(0.4, 0.6)
    centre = [(-out, along), (side + out, along), (along, -out), (along, side + out)][edge]
    draw_mark(img, LABELS[int(rng.integers(2))], centre, side * rng.uniform(0.8, 1.1), rng, ink=_gray_ink(rng))


def render_cell(label: int, rng: np.random.Generator, noisy: bool = False, style: str = "pen") -> np.ndarray:
    """One 40x40 uint8 grayscale cell with the given label index (see vision.labels.LABELS)."""
    out = draw_cell(label, rng, noisy, style)
    out = cv2.resize(out, (CELL_SIZE, CELL_SIZE), interpolation=cv2.INTER_AREA)
    if noisy:
        out = out * rng.uniform(0.6, 1.0) + rng.uniform(0, 40)  # exposure / contrast
        out += rng.normal(0, rng.uniform(1, 12), out.shape)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def draw_cell(label: int, rng: np.random.Generator, noisy: bool = False, style: str = "pen") -> np.ndarray:
    """The cell drawn at SCALE x its size, float32 gray, before the camera shrinks it (render_cell finishes it)."""
    side = CELL_SIZE * SCALE
    paper = rng.uniform(200, 255)
    canvas = np.full((side, side), paper, np.float32)
    if noisy:
        ramp = np.linspace(-1, 1, side, dtype=np.float32)
        gx, gy = np.meshgrid(ramp, ramp)
        a = rng.uniform(0, 2 * np.pi)
        canvas *= 1.0 - rng.uniform(0, 0.35) * (0.5 + 0.5 * (np.cos(a) * gx + np.sin(a) * gy))
    img = np.clip(canvas, 0, 255).astype(np.uint8)
    if noisy and rng.random() < 0.7:
        _grid_remnants(img, rng)
    if label != NOTHING:
        spread = 0.16 if noisy else 0.05
        centre = side * (0.5 + rng.uniform(-spread, spread, 2))
        size = side * (rng.uniform(0.45, 0.85) if rng.random() < 0.85 else rng.uniform(0.3, 0.45))
        draw_mark(img, LABELS[label], tuple(centre), size, rng, ink=_gray_ink(rng), style=style)
    elif noisy and rng.random() < 0.25:
        cv2.circle(img, tuple(int(v) for v in rng.uniform(0.2, 0.8, 2) * side), int(rng.integers(1, 4)),
                   int(rng.uniform(30, 150)), -1, cv2.LINE_AA)  # a pen dot
    if noisy and rng.random() < 0.3:
        _neighbour_piece(img, rng)
    out = img.astype(np.float32)
    if noisy:
        if rng.random() < 0.35:
            _smudges(out, rng)
        if rng.random() < 0.6:
            out = cv2.GaussianBlur(out, (0, 0), rng.uniform(0.5, 2.5))
    return out


def generated_cells(n: int, seed: int, render: Callable[[int, np.random.Generator], np.ndarray]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """n cells with balanced labels in shuffled order, each drawn by `render(label, rng)` from one generator seeded
    with `seed` (the shuffle is its first draw): (images uint8 (n, 40, 40), labels int64 (n,))."""
    rng = np.random.default_rng(seed)
    labels = np.resize(np.arange(len(LABELS)), n)
    rng.shuffle(labels)
    images = np.empty((n, CELL_SIZE, CELL_SIZE), np.uint8)
    for i, label in enumerate(labels):
        images[i] = render(int(label), rng)
    return images, labels.astype(np.int64)


def make_cells(n: int, seed: int, noisy: bool = False, styles: tuple[str, ...] = ("pen",),
               noisy_fraction: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """n cells with balanced labels in shuffled order: (images uint8 (n, 40, 40), labels int64 (n,)).

    noisy_fraction mixes clean and noisy cells (overrides `noisy`); styles are picked uniformly per cell.
    """
    if n < 1:
        raise ValueError(f"number of cells must be at least 1; got {n}")
    def render(label: int, rng: np.random.Generator) -> np.ndarray:
        is_noisy = noisy if noisy_fraction is None else bool(rng.random() < noisy_fraction)
        style = styles[int(rng.integers(len(styles)))]
        return render_cell(label, rng, noisy=is_noisy, style=style)

    return generated_cells(n, seed, render)
