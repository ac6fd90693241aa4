"""The game-move recogniser: Algorithm 1 of the paper over a stream of camera frames.

Per frame: find the page, warp it square; if the warped page changed by more than tau over the last two
frames (dist(P_t, P_t-1) + dist(P_t-1, P_t-2)) a hand is drawing, so skip the frame; otherwise read every
cell, keep a window of the last `window` frames' per-cell label probabilities, and among the cells empty
in the known game history pick the one whose summed nought/cross probability is largest; if its summed
label is not "nothing", that is the person's move.

Additions over the paper, all from its field-trial lesson that hand detection mattered: a frame in which
a large non-paper blob (hand, arm, sleeve; judged against the page's own paper colour, vision.illumination)
covers any cell or the sheet's rim is skipped too (a hand resting still passes the motion test); the
window is emptied whenever a frame is skipped, so probabilities seen before or during the drawing never
vote after it. The motion test warps the last three frames with this frame's page corners (a corner that
jitters under a dim vignette is not motion), also counts changed pixels, and looks 30% beyond the page
(a hand drawing at the sheet's edge may have only its pen over it). An arm that cuts a piece off the page is caught by the
page's area instead: it changing between frames is "moving", it staying below the area of earlier clean
frames is "occluded". Given a frame of the sheet with nobody's hand over it (`reset(reference=...)`), the rim
test counts only non-paper the sheet's own outline did not already show there: a curled or folded sheet bows
out of its four-corner quad, so a sliver of table lies along the rim in every frame, hand or not.
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from ncbot.vision.classifier.inference import CellClassifier, load_classifier
from ncbot.vision.grid import extract_cells, read_page, rim_fraction
from ncbot.vision.labels import BOARD_SYMBOL, LABELS, NOTHING
from ncbot.vision.page import check_frame, find_page, warp
from ncbot.vision.sheet import Grid, grid_shape

STATUSES = ("move", "moving", "occluded", "no_page", "waiting")
EDGE_FRACTION = 0.02   # of the page's rim not paper: a hand or arm reaches over the sheet's edge
HAND_FRACTION = 0.006  # of the page area under large non-paper blobs: a hand (or its shadow) is there
AREA_CHANGE = 0.04     # the page's area in the frame changing more between frames: its outline is occluded or it moved
MOTION_MARGIN = 0.3    # the wider motion warp reaches this fraction of the page beyond each side
LOCAL_CHANGE = 20.0    # gray levels: a blurred pixel of the motion warp changing more has something new on it
LOCAL_AREA = 0.004     # ... and more than this fraction of such pixels is a hand, however small (tau is an average)
MOTION_SIDE = 48  # the warped page is compared at this size, blurred: pen strokes barely count, a hand does
RIM_SLACK = 3     # pixels (of the rim's 160 px warp) the sheet's own rim outline may shift from frame to frame


@dataclass
class Recognition:
    """What one frame said.

    status: "move" (a new mark found: see move/label), "moving" (page changed > tau: a hand is drawing),
    "occluded" (a hand/arm lies over the grid), "no_page" (no sheet or grid visible; see detail),
    "waiting" (sheet readable, no new mark yet, or too few frames to judge motion).
    """

    status: str
    move: int | None = None               # row-major cell of the new mark
    label: str | None = None              # "x" or "o"
    probabilities: np.ndarray | None = None  # (n*n, 3) mean over the window, order vision.labels.LABELS
    cells: list[str] | None = None        # this frame's reading of the whole board
    motion: float | None = None           # dist(P_t,P_t-1) + dist(P_t-1,P_t-2), gray levels (RMS)
    detail: str = ""


def _empty_cells(known_board: Sequence, n_cells: int) -> np.ndarray:
    """Known board ('x'/'o'/'' or ints with 0 = empty, like the env's board) -> bool mask of empty cells."""
    if len(known_board) != n_cells:
        raise ValueError(f"known board must have {n_cells} cells; got {len(known_board)}")
    empty = []
    for value in known_board:
        if isinstance(value, str):
            if value not in ("", "x", "o"):
                raise ValueError(f"known board cell {value!r} is unknown; expected 'x', 'o' or ''")
            empty.append(value == "")
        else:
            empty.append(int(value) == 0)
    return np.array(empty, bool)


class MoveRecogniser:
    """Stateful Algorithm 1: feed frames with `update`, or let `recognise` loop over a stream."""

    def __init__(self, grid: Grid = 3, tau: float = 12.0, rho: int | None = None, window: int = 3,
                 gamma_ms: float = 100.0, classifier: CellClassifier | None = None) -> None:
        """grid: 3, 9 or a declared game's (rows, cols) (`ncbot.vision.sheet.Grid`); tau: motion threshold in
        gray levels (RMS over the blurred 48x48 page, summed over two steps); rho: pixels per cell of the grid
        warp (default 64 for 3x3, 40 for 9x9); window: frames whose probabilities are summed; gamma_ms: pause
        between frames in `recognise`."""
        rows, cols = grid_shape(grid)  # a one-line ValueError for anything else
        self.grid = grid
        self.cells = rows * cols
        if tau <= 0 or window < 1 or gamma_ms < 0:
            raise ValueError(f"need tau > 0, window >= 1, gamma_ms >= 0; got tau={tau}, window={window}, gamma_ms={gamma_ms}")
        self.tau, self.rho, self.window, self.gamma_ms = tau, rho, window, gamma_ms
        self.classifier = classifier or load_classifier()
        self.reset()

    def reset(self, reference: np.ndarray | None = None) -> None:
        """Forget past frames (call when the recogniser becomes active for a new turn). `reference`: a BGR frame
        of the sheet with no hand over it (the robot's last look before the turn); the rim test then ignores
        what of the rim was not paper there already (within RIM_SLACK pixels), e.g. a curled edge."""
        self._grays: deque[np.ndarray] = deque(maxlen=3)  # the last frames, gray, for the motion test
        self._areas: deque[float] = deque(maxlen=3)       # their page areas (frame pixels)
        self._clean_ratio: float | None = None            # largest page-to-grid area ratio of a frame that passed every test
        self._probs: deque[np.ndarray] = deque(maxlen=self.window)
        self._rim_reference: np.ndarray | None = None    # the sheet's own non-paper rim pixels, widened
        if reference is not None:
            try:
                rim = extract_cells(check_frame(reference), self.grid, self.rho).rim_foreign
            except ValueError:
                return  # no sheet in the reference: judge the rim as it is
            if rim.any():
                kernel = np.ones((2 * RIM_SLACK + 1, 2 * RIM_SLACK + 1), np.uint8)
                self._rim_reference = cv2.dilate(rim.astype(np.uint8), kernel) > 0

    def _forget(self) -> None:
        self._probs.clear()

    def _motion(self, corners: np.ndarray) -> tuple[float, float] | None:
        """(dist(P_t, P_t-1) + dist(P_t-1, P_t-2), fraction of pixels that changed by > LOCAL_CHANGE), the
        last three frames all warped with this frame's page corners: a dim or cluttered page corner found a
        few pixels elsewhere in each frame then does not count as motion, while a hand (or the page itself
        moving) does. Also measured on a wider warp reaching MOTION_MARGIN beyond the page on every side,
        the larger of the two counting: a hand drawing near the sheet's edge may have only its pen over
        the page, its palm just outside, and an RMS over the whole warp dilutes it (hence the count)."""
        if len(self._grays) < 3:
            return None
        centre = corners.mean(axis=0, keepdims=True)
        wider = centre + (corners - centre) * (1 + 2 * MOTION_MARGIN)
        rms, changed = 0.0, 0.0
        for quad in (corners, wider):
            p = [cv2.GaussianBlur(cv2.resize(warp(gray, quad, MOTION_SIDE * 2), (MOTION_SIDE, MOTION_SIDE),
                                             interpolation=cv2.INTER_AREA), (0, 0), 1.5).astype(np.float32)
                 for gray in self._grays]
            rms = max(rms, float(np.sqrt(np.mean((p[2] - p[1]) ** 2)) + np.sqrt(np.mean((p[1] - p[0]) ** 2))))
            moved = (np.abs(p[2] - p[1]) > LOCAL_CHANGE) | (np.abs(p[1] - p[0]) > LOCAL_CHANGE)
            changed = max(changed, float(moved.mean()))
        return rms, changed

    def update(self, frame: np.ndarray, known_board: Sequence) -> Recognition:
        """Process one BGR frame given the board as known from the game history."""
        frame = check_frame(frame)
        empty = _empty_cells(known_board, self.cells)
        corners = find_page(frame)
        if corners is None:
            self._grays.clear()
            self._areas.clear()
            self._forget()
            return Recognition("no_page", detail="no paper sheet found in the frame")
        self._grays.append(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
        self._areas.append(float(cv2.contourArea(corners)))
        measured = self._motion(corners)
        if measured is None:
            self._forget()
            return Recognition("waiting", detail="collecting frames to judge motion")
        motion, changed = measured
        if motion > self.tau or changed > LOCAL_AREA:
            self._forget()
            return Recognition("moving", motion=motion,
                               detail="" if motion > self.tau else f"{100 * changed:.1f}% of the page and its surround changed")
        areas = list(self._areas)
        change = max(abs(b - a) / max(a, 1.0) for a, b in zip(areas, areas[1:]))
        if change > AREA_CHANGE:
            # an arm across the sheet's edge cuts a piece off the page; warped with this frame's corners
            # the three frames then look alike although the hand is there
            self._forget()
            return Recognition("moving", motion=motion, detail=f"the page's outline changed by {100 * change:.0f}%")
        try:
            reading = read_page(frame, self.grid, self.classifier, self.rho)
        except ValueError as error:
            self._forget()
            return Recognition("no_page", motion=motion, detail=str(error))
        edge = reading.edge_fraction if self._rim_reference is None else rim_fraction(reading.rim_foreign, self._rim_reference)
        if reading.occluded.any() or reading.hand_fraction > HAND_FRACTION or edge > EDGE_FRACTION:
            self._forget()
            return Recognition("occluded", cells=reading.cells, motion=motion,
                               detail=f"hand over cells {np.flatnonzero(reading.occluded).tolist()}")
        # an arm resting across the sheet's edge keeps a piece of the page hidden: still not clean. Measured
        # against the grid, which the arm leaves whole: a sheet nudged further away mid-turn shrinks in the
        # frame with its grid and stays readable (its page area alone fell 5 % in random seed 11 game 13)
        ratio = self._areas[-1] / max(float(cv2.contourArea(reading.grid_corners.astype(np.float32))), 1.0)
        if self._clean_ratio is not None and ratio < (1 - AREA_CHANGE) * self._clean_ratio:
            self._forget()
            return Recognition("occluded", cells=reading.cells, motion=motion,
                               detail=f"part of the sheet is hidden (page {100 * ratio / self._clean_ratio:.0f}% of before, against its grid)")
        self._clean_ratio = max(ratio, self._clean_ratio or 0.0)
        self._probs.append(reading.probabilities)
        summed = np.sum(self._probs, axis=0)
        mean = summed / len(self._probs)
        if not empty.any():
            return Recognition("waiting", probabilities=mean, cells=reading.cells, motion=motion, detail="board full")
        marked = np.where(empty, summed[:, :NOTHING].max(axis=1), -np.inf)
        best = int(marked.argmax())
        label = int(summed[best].argmax())
        if label == NOTHING:
            return Recognition("waiting", probabilities=mean, cells=reading.cells, motion=motion)
        return Recognition("move", move=best, label=BOARD_SYMBOL[LABELS[label]], probabilities=mean,
                           cells=reading.cells, motion=motion)

    def recognise(self, frames: Iterable[np.ndarray], known_board: Sequence, max_frames: int | None = None,
                  sleep: bool = True) -> Recognition:
        """Loop of Algorithm 1: update on each frame until a move is found (pausing gamma ms between
        frames); returns the move, or the last result when the stream or max_frames ends."""
        self.reset()
        result = Recognition("waiting", detail="no frames")
        for count, frame in enumerate(frames, start=1):
            result = self.update(frame, known_board)
            if result.status == "move" or (max_frames is not None and count >= max_frames):
                break
            if sleep and self.gamma_ms > 0:
                time.sleep(self.gamma_ms / 1000.0)
        return result
