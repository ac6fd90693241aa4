"""A tolerant grid model: grid lines that bow (a cheap wide-angle lens) or wander (a hand-drawn #).

A perspective warp keeps straight lines straight, but a barrel lens bends them: on a 9x9 sheet seen close
up, a line near the page's edge bows by several pixels, which puts grid-line remnants into the cells of
the outer rows. So the grid's lines are measured where they are (short pieces of long ink lines near the
straight boundaries found first), a smooth displacement field is fitted to those pieces (low-order
polynomials, one for the vertical lines' sideways shift and one for the horizontal lines'), and every
cell is then cut from its own four corners on that field: the (n+1) x (n+1) lattice of grid-line
crossings, with each cell resampled bilinearly between them (one cv2.remap for the whole grid).
"""
from __future__ import annotations

import cv2
import numpy as np

SEARCH = 0.3        # of a cell: how far from the straight boundary a piece of its line may lie
MIN_SAMPLES = 8     # fewer measured pieces than this: keep the lines straight
MIN_CELLS = 5       # a 3x3 grid has too few lines to pin a bow down (and its cells are big): kept straight
OUTLIER_PX = 3.0    # a piece further than this from the first fit is a mark, not the line


def _terms(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Basis of the sideways shift of lines running along y: constant, linear, and a bow varying along x."""
    return np.stack([np.ones_like(x), x, y, x * y, y * y, x * y * y], axis=-1)


def _fit(along: np.ndarray, across: np.ndarray, shift: np.ndarray, scale: float) -> np.ndarray | None:
    if len(shift) < MIN_SAMPLES:
        return None
    a = _terms(across / scale, along / scale)
    keep = np.ones(len(shift), bool)
    coef = None
    for _ in range(2):
        if keep.sum() < MIN_SAMPLES:
            return coef
        coef, *_ = np.linalg.lstsq(a[keep], shift[keep], rcond=None)
        keep = np.abs(a @ coef - shift) < OUTLIER_PX
    return coef


def _pieces(lines: np.ndarray, bounds: np.ndarray, span: np.ndarray, step: float) -> tuple[np.ndarray, ...]:
    """Measured (along, across, shift) of the vertical line pieces of a line mask near each boundary
    (all sample rows and boundaries at once: a Python loop over them cost ~15 ms a read)."""
    reach = int(SEARCH * step)
    rows = np.round(np.linspace(span[0], span[-1], 4 * (len(span) - 1) + 1)[1:-1]).astype(int)
    rows = np.clip(rows, 0, lines.shape[0] - 1)
    offsets = np.arange(-reach, reach + 1)
    cols = np.round(bounds).astype(int)[:, None] + offsets[None, :]            # (boundaries, window)
    inside = (cols >= 0) & (cols < lines.shape[1])
    hits = lines[rows[:, None, None], np.clip(cols, 0, lines.shape[1] - 1)[None]] > 0
    hits &= inside[None]                                                         # (rows, boundaries, window)
    count = hits.sum(axis=2)
    first = np.where(count > 0, hits.argmax(axis=2), 0)
    last = np.where(count > 0, hits.shape[2] - 1 - hits[:, :, ::-1].argmax(axis=2), 0)
    centre = (hits * offsets[None, None, :]).sum(axis=2) / np.maximum(count, 1)
    good = (count > 0) & (last - first < SEARCH * step)  # one piece of line, not a line and a mark
    r, k = np.nonzero(good)
    shift = np.round(bounds).astype(int)[k] + centre[r, k] - bounds[k]
    return rows[r].astype(float), bounds[k].astype(float), shift


def lattice(ink: np.ndarray, xs: np.ndarray, ys: np.ndarray, thicken: int) -> np.ndarray:
    """(rows+1, cols+1, 2) page-warp positions (x, y) of the grid-line crossings, bow and wander included."""
    n_rows, n_cols = len(ys) - 1, len(xs) - 1
    gx, gy = np.meshgrid(xs, ys)  # gx[row, col]
    out = np.stack([gx, gy], axis=-1).astype(np.float64)
    if min(n_rows, n_cols) < MIN_CELLS:
        return out
    step = min((xs[-1] - xs[0]) / n_cols, (ys[-1] - ys[0]) / n_rows)
    length = max(8, int(0.6 * step))  # short pieces: a bowed line is still straight over half a cell
    vertical = cv2.morphologyEx(cv2.dilate(ink, np.ones((1, thicken), np.uint8)), cv2.MORPH_OPEN,
                                np.ones((length, 1), np.uint8))
    horizontal = cv2.morphologyEx(cv2.dilate(ink, np.ones((thicken, 1), np.uint8)), cv2.MORPH_OPEN,
                                  np.ones((1, length), np.uint8))
    scale = float(ink.shape[0])
    coef = _fit(*_pieces(vertical, xs, ys, step), scale)
    if coef is not None:
        out[..., 0] += _terms(gx / scale, gy / scale) @ coef
    along, across, shift = _pieces(horizontal.T, ys, xs, step)
    coef = _fit(along, across, shift, scale)
    if coef is not None:
        out[..., 1] += _terms(gy / scale, gx / scale) @ coef
    return out


def remap_cells(frame: np.ndarray, crossings: np.ndarray, rho: int) -> np.ndarray:
    """The grid resampled to (rows*rho, cols*rho) pixels, each cell bilinear between its four crossings
    (`crossings`: (rows+1, cols+1, 2) frame positions)."""
    crossings = crossings.astype(np.float32)
    n_rows, n_cols = crossings.shape[0] - 1, crossings.shape[1] - 1
    s = np.arange(n_cols * rho, dtype=np.float32) / rho
    k = np.minimum(s.astype(int), n_cols - 1)
    t = (s - k)[None, :, None]
    # separable: along x within each lattice row, then along y (gathers only: a matrix product here
    # would spin up BLAS threads, which cost tens of milliseconds on a busy machine)
    rows = crossings[:, k] * (1 - t) + crossings[:, k + 1] * t                     # (rows+1, cols*rho, 2)
    s = np.arange(n_rows * rho, dtype=np.float32) / rho
    k = np.minimum(s.astype(int), n_rows - 1)
    ty = (s - k)[:, None, None]
    maps = (rows[k] * (1 - ty) + rows[k + 1] * ty).astype(np.float32)             # (rows*rho, cols*rho, 2)
    map_x, map_y = maps[..., 0], maps[..., 1]
    return cv2.remap(frame, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
