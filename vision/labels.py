"""The cell labels, in the classifier's output order, and their board spelling."""
from __future__ import annotations

LABELS = ("nought", "cross", "nothing")
NOUGHT, CROSS, NOTHING = 0, 1, 2
BOARD_SYMBOL = {"nought": "o", "cross": "x", "nothing": ""}
CELL_SIZE = 40  # the classifier's input side, pixels (the paper's 40x40 grayscale cells)


def symbol_to_index(symbol: str) -> int:
    """Board spelling ("o", "x", "") -> label index."""
    for name, sym in BOARD_SYMBOL.items():
        if sym == symbol:
            return LABELS.index(name)
    raise ValueError(f"board cell {symbol!r} is unknown; expected 'o', 'x' or ''")
