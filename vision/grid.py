"""Reading a whole board from a camera frame: page -> grid -> grid-line removal -> rows x cols cells -> CNN.

The frame is first white-balanced and brightened against its brightest paper-like pixels (a tungsten or
fluorescent cast, dim light: vision.illumination). The sheet layout is not assumed: after the page is
warped square and its shading divided out (a shadow's edge), the grid's long straight ink lines are found
by morphological opening, their ends (or the outer frame lines, when there are n+1 evenly spaced ones)
give the grid's extent and the inner lines give the cell boundaries (hand-drawn grids are rarely even).
On a 9x9 grid the lines' bow (a wide-angle lens) is then measured and each cell resampled between its
own four grid-line crossings (vision.lattice), straight from the frame at rho pixels per cell, so small
9x9 cells keep the camera's detail. All cells go through the CNN in one batch.

A grid is 3, 9 or (rows, cols) of a declared game (`ncbot.vision.sheet.Grid`); a declared grid is read as
the built-in size it is closest to in density (`ncbot.vision.sheet.built_in_like`), each axis with its own
number of cells.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import NamedTuple

import cv2
import numpy as np

from ncbot.vision.classifier.inference import CellClassifier, load_classifier
from ncbot.vision.illumination import balance_frame, flatten, non_paper
from ncbot.vision.labels import BOARD_SYMBOL, CELL_SIZE, LABELS
from ncbot.vision.lattice import lattice, remap_cells
from ncbot.vision.page import check_frame, locate_balanced_page
from ncbot.vision.sheet import Grid, built_in_like, grid_label, grid_shape

PAGE_SIDE = {3: 320, 9: 480}   # pixels of the first (whole page) warp
DEFAULT_RHO = {3: 64, 9: 40}   # pixels per cell of the grid warp (the paper's rho)
CELL_INSET = 0.07              # fraction of a cell trimmed on each side (grid-line remnants)
FOREIGN_SIDE = 160             # pixels of the page warp searched for hands
OCCLUSION_FRACTION = 0.04      # a cell with more than this much hand/arm is "occluded"
RIM_OPEN = 5                   # pixels (of the 160 px warp): thinner non-paper at the rim is ink, not an arm
MARK_EXTENT = 0.85             # blobs narrower and shorter than this many cells are marks (bold ink), not hands
NOISE_FREE = 3.0              # median neighbour step (gray levels) of the grid warp up to which nothing is smoothed
NOISE_BLUR = 0.35             # Gaussian sigma per gray level of step beyond that ...
NOISE_BLUR_MAX = 1.2          # ... up to this many pixels
CELL_FLATTEN = 1.0             # of a cell: the paper shade under the cells is a grey closing this wide (no mark fits)
PAGE_RIM = 0.02               # of the page warp's side: no grid line lies this close to the page's edge
LINE_GAP = 0.025              # of the page warp's side: gaps this long in a missing 3x3 line's ink are bridged
WEAK_LINE = 0.2               # of the strongest line's ink: a weaker straight run is a mark's stroke, not the grid
END_MATCH = 0.35              # of a cell: a line end no further inside than this from where even spacing puts
                              # a sparse grid's edge may be that edge (a broken line ends further inside)
FRAME_MATCH = 0.15            # of a cell: lines ending this close to a crossing line end at the grid's frame
UNSURE_MARGIN = 0.5            # SVM score gap below which a cell is looked at again, turned and mirrored


@dataclass
class PageCells:
    """What the geometry stage found in one frame, before any classification."""

    cell_images: np.ndarray        # (rows*cols, 40, 40) uint8: exactly what the CNN sees
    occluded: np.ndarray           # (rows*cols,) bool: a hand/arm covers part of the cell
    hand_fraction: float           # fraction of the page under large non-paper blobs (hand, arm, shadow)
    edge_fraction: float           # fraction of the page's rim that is not paper (a hand over the edge)
    rim_foreign: np.ndarray        # (FOREIGN_SIDE, FOREIGN_SIDE) bool: the rim's non-paper pixels (edge_fraction's)
    page_corners: np.ndarray       # (4, 2) frame pixels, TL TR BR BL
    grid_corners: np.ndarray       # (4, 2) frame pixels of the grid square
    grid_image: np.ndarray         # (rows*rho, cols*rho) gray grid warp with the grid lines removed


@dataclass
class PageReading(PageCells):
    """PageCells plus the classifier's verdict; `cells` is the board as 'x' / 'o' / ''."""

    cells: list[str] = field(default_factory=list)
    probabilities: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (rows*cols, 3), order LABELS


def _line_mask(ink: np.ndarray, length: int, horizontal: bool, thicken: int = 3, bridge: int = 0) -> np.ndarray:
    """Ink that forms straight lines at least `length` long (thickened across so slight tilts survive;
    gaps up to `bridge` pixels along the line closed first: a faint or streaked pen line thresholds in dashes)."""
    across = np.ones((thicken, 1) if horizontal else (1, thicken), np.uint8)
    along = np.ones((1, length) if horizontal else (length, 1), np.uint8)
    thick = cv2.dilate(ink, across)
    if bridge > 1:
        thick = cv2.morphologyEx(thick, cv2.MORPH_CLOSE, np.ones((1, bridge) if horizontal else (bridge, 1), np.uint8))
    return cv2.morphologyEx(thick, cv2.MORPH_OPEN, along)


def _ink(gray: np.ndarray, block: int) -> np.ndarray:
    block = max(3, block | 1)
    return cv2.adaptiveThreshold(gray, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, 12)


def _bands(profile: np.ndarray, minimum: float) -> list[tuple[int, int]]:
    """Runs of consecutive indices whose profile exceeds `minimum`."""
    on = np.flatnonzero(profile > minimum)
    if len(on) == 0:
        return []
    splits = np.flatnonzero(np.diff(on) > 1) + 1
    return [(int(run[0]), int(run[-1]) + 1) for run in np.split(on, splits)]


class Line(NamedTuple):
    """One straight ink line of a line mask: its centre across, where it starts and ends along, its ink."""

    centre: float
    start: float
    end: float
    ink: float


def _lines(mask: np.ndarray, min_length: float) -> list[Line]:
    """The horizontal lines of a line mask, without weak scraps: a stroke of a mark or a smudge that happens
    to run straight for min_length makes a thin band of little ink, and four lines (two of them scraps)
    would pass for a framed grid (`_framed`)."""
    profile = mask.sum(axis=1) / 255.0
    found = []
    for a, b in _bands(profile, min_length):
        hits = np.flatnonzero(mask[a:b].any(axis=0))
        weights = profile[a:b]
        found.append(Line(float((np.arange(a, b) * weights).sum() / weights.sum()), float(hits[0]),
                          float(hits[-1] + 1), float(weights.sum())))
    if not found:
        return []
    strongest = max(line.ink for line in found)
    return [line for line in found if line.ink >= WEAK_LINE * strongest]


def _edges(along: list[Line], across: list[Line], cells: int, sparse: bool) -> tuple[float, float]:
    """A sparse grid's extent along one axis from the lines running along it (`along`: where they start and
    end) and its inner lines crossing it (`across`: their centres).

    A line's end is where a shadow's edge, a faint stretch of pen or a motion streak broke it off, so the
    median end of the lines is pulled inwards when one of them breaks short. Even spacing of the inner lines
    says where each edge should lie, one cell beyond the outermost inner line: the line end nearest to that, of
    those not clearly short of it, is the edge (a hand-drawn # is uneven and overshoots); when every line stops
    short, the prediction, unless they stop at a crossing line and none goes past it (then that line is a frame).
    `cells`: the grid's cells along the axis; `sparse`: a grid read like 3x3 (`built_in_like`). A dense grid
    (9x9, a declared 6x7), or inner lines not all found or not evenly spaced, takes the median ends."""
    starts, ends = [line.start for line in along], [line.end for line in along]
    median = (float(np.median(starts)), float(np.median(ends)))
    if not sparse or len(across) != cells - 1:  # dense: n-1 lines found are often not the inner ones (a frame, a gap)
        return median
    centres = sorted(line.centre for line in across)
    low, high = centres[0], centres[-1]
    step = (high - low) / (cells - 2)
    gaps = np.diff(centres)
    if step <= 0 or gaps.min() < 0.6 * step or gaps.max() > 1.4 * step:
        return median
    reach = END_MATCH * step
    near = [e for e in starts if e <= low - step + reach]
    far = [e for e in ends if e >= high + step - reach]
    frame = FRAME_MATCH * step  # lines that stop at a crossing line, none going past it: that line is a frame
    framed0 = min(starts) > low - frame and any(abs(e - low) < frame for e in starts)
    framed1 = max(ends) < high + frame and any(abs(e - high) < frame for e in ends)
    edge0 = min(near, key=lambda e: abs(e - (low - step))) if near else (median[0] if framed0 else low - step)
    edge1 = min(far, key=lambda e: abs(e - (high + step))) if far else (median[1] if framed1 else high + step)
    return float(edge0), float(edge1)


def _snap(start: float, stop: float, n: int, found: list[float]) -> np.ndarray:
    """n+1 cell boundaries: evenly spaced, each inner one moved onto a detected line close to it."""
    bounds = np.linspace(start, stop, n + 1)
    step = (stop - start) / n
    for k in range(1, n):
        if found:
            nearest = min(found, key=lambda c: abs(c - bounds[k]))
            if abs(nearest - bounds[k]) < 0.3 * step:
                bounds[k] = nearest
    return bounds


def _grid_lines(page_gray: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(xs, ys, ink mask of the page warp) or None: the straight grid first, the lattice bends it later."""
    n_rows, n_cols = grid_shape(grid)
    side = page_gray.shape[0]
    rows, cols, ink = _page_lines(page_gray, grid)
    if not rows or not cols:
        return None
    sparse = built_in_like(grid) == 3
    x0, x1 = _framed(cols, n_cols, _edges(rows, cols, n_cols, sparse))
    y0, y1 = _framed(rows, n_rows, _edges(cols, rows, n_rows, sparse))
    if x1 - x0 < 0.25 * side or y1 - y0 < 0.25 * side:
        return None
    return _snap(x0, x1, n_cols, [c.centre for c in cols]), _snap(y0, y1, n_rows, [r.centre for r in rows]), ink


def _page_lines(page_gray: np.ndarray, grid: Grid) -> tuple[list[Line], list[Line], np.ndarray]:
    """The straight ink lines of a page warp, (horizontal, vertical), and its ink mask."""
    n_rows, n_cols = grid_shape(grid)
    side = page_gray.shape[0]
    ink = _ink(flatten(page_gray, side // 16), side // 12)
    min_length = side / 5
    thicken = max(3, side // 50) | 1  # hand-drawn grid lines slant and bow by a few pixels
    # a sliver of table along the warp's border (a curled sheet's edge bows out of the page quad) is a long
    # dark straight line too, but the grid never reaches the very edge of the page
    rim = max(3, int(PAGE_RIM * side))

    def lines(horizontal: bool, bridge: int = 0) -> list[Line]:
        mask = _line_mask(ink, int(min_length), horizontal, thicken, bridge)
        mask = mask if horizontal else mask.T  # rows of a horizontal mask, columns of a vertical one
        mask[:rim], mask[-rim:] = 0, 0
        return _lines(mask, min_length)

    rows, cols = lines(True), lines(False)
    # a 3x3 grid has only two inner lines a way: one that a motion streak or a dim stretch left in dashes
    # is looked for again with its gaps bridged (only then: bridging everywhere joins grain into "lines")
    if n_rows == 3 and len(rows) < 2:
        rows = lines(True, int(LINE_GAP * side))
    if n_cols == 3 and len(cols) < 2:
        cols = lines(False, int(LINE_GAP * side))
    return rows, cols, ink


def lines_found(frame: np.ndarray, grid: Grid = 3) -> tuple[int, int] | None:
    """How many straight grid lines (inner and frame) the reader finds across and down the sheet read as `grid`, or
    None without a sheet: a sheet whose grid is not the one asked for (a 3x3 sheet read as 9x9) shows in them."""
    found = _page_warp(check_frame(frame), grid)
    if found is None:
        return None
    rows, cols, _ = _page_lines(found[-1], grid)
    return len(rows), len(cols)


def _page_warp(frame: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(balanced frame, page corners, paper mask, frame -> page warp, grey page warp) or None without a sheet."""
    frame = balance_frame(frame)  # a colour cast or dim light: paper neutral and bright again, ink contrast back
    corners, paper_mask = locate_balanced_page(frame)
    if corners is None:
        return None
    page_side = PAGE_SIDE[built_in_like(grid)]
    square = np.array([[0, 0], [page_side, 0], [page_side, page_side], [0, page_side]], np.float32)
    to_page = cv2.getPerspectiveTransform(corners, square)
    page_gray = cv2.cvtColor(cv2.warpPerspective(frame, to_page, (page_side, page_side), flags=cv2.INTER_LINEAR),
                             cv2.COLOR_BGR2GRAY)
    return frame, corners, paper_mask, to_page, page_gray


def _framed(lines: list[Line], cells: int, ends: tuple[float, float]) -> tuple[float, float]:
    """The grid's extent along one axis: its outer frame lines when exactly n+1 evenly spaced lines were
    found (a mark sitting on a frame line or a shadow breaks the lines' ends, never their centres), else
    the ends found by `_edges`."""
    centres = [line.centre for line in lines]
    if len(centres) != cells + 1:
        return ends
    gaps = np.diff(np.sort(centres))
    if gaps.min() < 0.6 * gaps.mean() or gaps.max() > 1.4 * gaps.mean():
        return ends
    return float(min(centres)), float(max(centres))


def _remove_lines(gray: np.ndarray, rho: int) -> np.ndarray:
    """Paint long straight ink (the grid) with the nearby paper shade; marks are shorter than a cell."""
    ink = _ink(gray, rho // 2)
    length = int(1.6 * rho)
    lines = cv2.bitwise_or(_line_mask(ink, length, True), _line_mask(ink, length, False))
    lines = cv2.dilate(lines, np.ones((3, 3), np.uint8))
    paper = cv2.dilate(gray, np.ones((9, 9), np.uint8))
    out = gray.copy()
    out[lines > 0] = paper[lines > 0]
    return out


def denoise(gray: np.ndarray) -> np.ndarray:
    """A grainy grid warp (dim light amplified, JPEG) smoothed just enough that empty cells look empty.

    The noise is measured on the warp itself (the median absolute step between neighbouring pixels, which
    ink edges barely move), so a clean photo is left alone."""
    noise = float(np.median(np.abs(np.diff(gray[::2].astype(np.int16), axis=1))))
    if noise <= NOISE_FREE:
        return gray
    return cv2.GaussianBlur(gray, (0, 0), min(NOISE_BLUR_MAX, NOISE_BLUR * (noise - NOISE_FREE)))


def _rim_band(side: int) -> np.ndarray:
    """The page warp's rim where a hand reaching over the sheet's edge shows (the outermost 2 px excluded)."""
    rim = np.ones((side, side), bool)
    rim[8:-8, 8:-8] = False
    rim[:2], rim[-2:], rim[:, :2], rim[:, -2:] = False, False, False, False
    return rim


def rim_fraction(rim_foreign: np.ndarray, ignore: np.ndarray | None = None) -> float:
    """Fraction of the rim that is not paper, not counting the `ignore` pixels (the sheet's own outline, e.g.
    a curled edge's sliver of table, seen before anyone reached over it)."""
    rim = _rim_band(rim_foreign.shape[0])
    counted = rim_foreign if ignore is None else rim_foreign & ~ignore
    return float(counted[rim].mean())


def _foreign(paper_mask_page: np.ndarray, page_bgr: np.ndarray, grid: Grid, cell_step: float) -> tuple[np.ndarray, np.ndarray]:
    """Large non-paper blobs on the warped page (hand, arm, sleeve, their shadow); ink strokes are thin.

    Non-paper is judged against the local paper colour (vision.illumination): a tinted light, a dark
    vignette or a clipped bright strip changes the paper smoothly, a hand does not. A blob that fits inside
    one cell (cell_step pixels of this warp) is a mark, however bold: a hand with its wrist spans more.
    """
    side = paper_mask_page.shape[0]
    not_paper = non_paper(page_bgr, paper_mask_page)
    # a hand reaching over the sheet's edge: non-paper along the page's rim, even if too thin for the
    # palm-sized opening below; but wider than a grid line, which may run to the rim of a cropped page
    wide = cv2.morphologyEx(not_paper.astype(np.uint8), cv2.MORPH_OPEN, np.ones((RIM_OPEN, RIM_OPEN), np.uint8))
    rim_foreign = (wide > 0) & _rim_band(side)
    # a palm is wider than this; grid crossings and marks are not (a 9x9 page is dense with ink, and the
    # robot sees it from closer, so the hand looks bigger on it)
    k = max(5, side // (16 if built_in_like(grid) == 3 else 9)) | 1
    foreign = cv2.morphologyEx(not_paper.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    foreign = cv2.morphologyEx(foreign, cv2.MORPH_OPEN, np.ones((k, k), np.uint8))  # pale skin is speckled
    border = max(2, side // 50)  # the warped page's own edge is not a hand
    foreign[:border], foreign[-border:], foreign[:, :border], foreign[:, -border:] = 0, 0, 0, 0
    count, labels, stats, _ = cv2.connectedComponentsWithStats(foreign, connectivity=8)
    if count > 1:
        mark_sized = (stats[1:, cv2.CC_STAT_WIDTH] < MARK_EXTENT * cell_step) & (stats[1:, cv2.CC_STAT_HEIGHT] < MARK_EXTENT * cell_step)
        foreign = np.r_[False, ~mark_sized][labels].astype(np.uint8)
    return foreign, rim_foreign


def _cell_occlusion(foreign: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    n_rows, n_cols = len(ys) - 1, len(xs) - 1
    out = np.zeros(n_rows * n_cols, bool)
    for r in range(n_rows):
        for c in range(n_cols):
            # an edge predicted from even spacing may lie past the warp's border (a page found cropped)
            block = foreign[max(0, int(ys[r])):max(0, int(np.ceil(ys[r + 1]))),
                            max(0, int(xs[c])):max(0, int(np.ceil(xs[c + 1])))]
            out[r * n_cols + c] = block.size > 0 and block.mean() > OCCLUSION_FRACTION
    return out


def cut_cells(frame: np.ndarray, crossings: np.ndarray, grid: Grid, rho: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows*cols, 40, 40) cells and the grid warp they were cut from (lines removed), for a white-balanced BGR
    frame and the grid-line crossings (rows+1, cols+1, 2) in it: the reader's own cut, also used at known
    crossings (the benches' "true crossings", which leave the reader's geometry out)."""
    n_rows, n_cols = grid_shape(grid)
    gray = cv2.cvtColor(remap_cells(frame, crossings, rho), cv2.COLOR_BGR2GRAY)
    gray = _remove_lines(denoise(flatten(gray, int(CELL_FLATTEN * rho))), rho)
    # each cell is rho x rho in this warp: the lattice already holds the uneven boundaries
    gx, gy = np.arange(n_cols + 1, dtype=np.float64) * rho, np.arange(n_rows + 1, dtype=np.float64) * rho
    cells = np.empty((n_rows * n_cols, CELL_SIZE, CELL_SIZE), np.uint8)
    for r in range(n_rows):
        for c in range(n_cols):
            w, h = gx[c + 1] - gx[c], gy[r + 1] - gy[r]
            x0, x1 = int(round(gx[c] + CELL_INSET * w)), int(round(gx[c + 1] - CELL_INSET * w))
            y0, y1 = int(round(gy[r] + CELL_INSET * h)), int(round(gy[r + 1] - CELL_INSET * h))
            crop = gray[max(y0, 0):max(y1, y0 + 2), max(x0, 0):max(x1, x0 + 2)]
            cells[r * n_cols + c] = cv2.resize(crop, (CELL_SIZE, CELL_SIZE), interpolation=cv2.INTER_AREA)
    return cells, gray


def extract_cells(frame: np.ndarray, grid: Grid = 3, rho: int | None = None) -> PageCells:
    """Find the sheet and grid in a BGR frame and cut the cells; raises ValueError if either is missing."""
    n_rows, n_cols = grid_shape(grid)
    frame = check_frame(frame)
    rho = rho or DEFAULT_RHO[built_in_like(grid)]
    if rho < 16:
        raise ValueError(f"rho (pixels per cell) must be at least 16; got {rho}")
    warped = _page_warp(frame, grid)
    if warped is None:
        raise ValueError("no paper sheet found in the frame (expected a white page on a darker background)")
    frame, corners, paper_mask, to_page, page_gray = warped
    page_side = page_gray.shape[0]
    found = _grid_lines(page_gray, grid)
    if found is None:
        raise ValueError(f"no {grid_label(grid)} grid found on the sheet (expected dark grid lines across the page)")
    xs, ys, ink = found
    # hands are big: look for them on a small warp of the page (cheap), boundaries scaled to it
    scale = FOREIGN_SIDE / page_side
    to_small = np.diag([scale, scale, 1.0]) @ to_page
    small = (FOREIGN_SIDE, FOREIGN_SIDE)
    foreign, rim_foreign = _foreign(cv2.warpPerspective(paper_mask, to_small, small, flags=cv2.INTER_NEAREST),
                                      cv2.warpPerspective(frame, to_small, small, flags=cv2.INTER_LINEAR), grid,
                                      cell_step=scale * min((xs[-1] - xs[0]) / n_cols, (ys[-1] - ys[0]) / n_rows))
    # the grid-line crossings as they really lie (bowed by the lens, wandering if hand-drawn), in the frame
    from_page = np.linalg.inv(to_page)
    crossings = cv2.perspectiveTransform(lattice(ink, xs, ys, 3).reshape(1, -1, 2), from_page).reshape(n_rows + 1, n_cols + 1, 2)
    grid_frame = crossings[[0, 0, -1, -1], [0, -1, -1, 0]].astype(np.float32)
    cells, gray = cut_cells(frame, crossings, grid, rho)
    return PageCells(cells, _cell_occlusion(foreign, xs * scale, ys * scale), float(foreign.mean()),
                     rim_fraction(rim_foreign), rim_foreign, corners, grid_frame, gray)


def cell_probabilities(classifier: CellClassifier, cells: np.ndarray, margin: float = UNSURE_MARGIN) -> np.ndarray:
    """(N, 3) label probabilities; a cell whose two best SVM scores lie within `margin` is scored again
    turned by quarter turns and mirrored (labels that do not change under those, as in training) and its
    scores averaged: a blurred or faint mark the network is unsure of gets eight looks instead of one,
    while the many clear cells cost one look (a second batched call over the unsure few)."""
    scores = classifier.scores(cells)
    if len(scores):
        top2 = np.sort(scores, axis=1)[:, -2:]
        unsure = np.flatnonzero(top2[:, 1] - top2[:, 0] < margin)
        if len(unsure):
            few = cells[unsure]
            views = [np.rot90(few, k, axes=(1, 2)) for k in range(4)]
            views += [np.flip(v, axis=2) for v in views]
            again = classifier.scores(np.ascontiguousarray(np.concatenate(views[1:])))
            scores[unsure] = (scores[unsure] + again.reshape(7, len(unsure), -1).sum(axis=0)) / 8
    e = np.exp(scores - scores.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


def read_page(frame: np.ndarray, grid: Grid = 3, classifier: CellClassifier | None = None,
              rho: int | None = None) -> PageReading:
    """Read the sheet in a BGR frame (batched CNN calls); raises ValueError if no sheet or grid."""
    view = extract_cells(frame, grid, rho)
    classifier = classifier or load_classifier()
    probabilities = cell_probabilities(classifier, view.cell_images)
    labels = [BOARD_SYMBOL[LABELS[i]] for i in probabilities.argmax(axis=1)]
    return PageReading(**{f.name: getattr(view, f.name) for f in fields(PageCells)},
                       cells=labels, probabilities=probabilities)


def read_board(frame: np.ndarray, grid: Grid = 3, classifier: CellClassifier | None = None,
               rho: int | None = None) -> list[str]:
    """Frame (H, W, 3 uint8 BGR) -> row-major list of 'x' / 'o' / '' per cell; raises ValueError if unreadable."""
    return read_page(frame, grid, classifier, rho).cells
