"""Labels a look at the cell itself contradicts: the first defence against a wrong settlement.

A label from play can be wrong: a person claims a move they did not make, or confirms a misread by mistake. In a
game the label's symbol follows from the seats (the person always draws the same mark), so such a mistake moves a
mark from one cell to another: an empty cell is labelled with a mark and the cell holding the mark is labelled
empty. Both leave a trace the classifier does not need to judge: the ink in the cell. A mark leaves ink; an empty
cell holds far less of it than the person's own marks in the same game. Cells that contradict their label so are
not learned from (they are not thrown away: a later, better reader may judge them again).
"""
from __future__ import annotations

import numpy as np

from ncbot.vision.classifier.preprocess import to_input
from ncbot.vision.labels import NOTHING

INK_LEVEL = 0.5        # of the normalised cell input (ink bright, per-cell contrast stretched): a pixel of ink
MARK_MIN_INK = 0.02    # share of a cell's pixels: below it no mark was drawn there (1st percentile of training marks: 0.021)
EMPTY_SHARE = 0.5      # an empty cell holds less ink than this share of the median marked cell of the same game


def ink(cells: np.ndarray) -> np.ndarray:
    """Share of each cell's pixels that are ink (float (N,)), on the classifier's own normalised input."""
    if len(cells) == 0:
        return np.zeros(0)
    return (to_input(cells).numpy()[:, 0] > INK_LEVEL).mean(axis=(1, 2))


def plausible(cells: np.ndarray, labels: np.ndarray, games: np.ndarray) -> np.ndarray:
    """bool (N,): the label does not contradict the cell's ink. Marks need MARK_MIN_INK; an empty label needs less
    ink than EMPTY_SHARE of the median ink of its game's cells labelled with marks (no marks: not judged)."""
    amount = ink(cells)
    marked = labels != NOTHING
    keep = np.where(marked, amount >= MARK_MIN_INK, True)
    for game in np.unique(games):
        mine = games == game
        reference = amount[mine & marked & keep]
        if len(reference):
            limit = EMPTY_SHARE * float(np.median(reference))
            keep[mine & ~marked] = amount[mine & ~marked] < limit
    return keep
