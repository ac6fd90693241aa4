"""Cells the games settled, as labelled examples: what the reader learns from while it plays.

A game shows the robot its sheet many times (after every move it looks); the game itself then says what every cell
held at each look: the moves were made in an order both sides agreed on (the dialogue confirmed each move, the final
board was agreed), so a look taken after k moves shows exactly the first k of them and nothing elsewhere. That makes
every cell of every look a labelled example without anyone labelling it.

A share of each game's cells is held back for the check an update must pass (`held_back`): chosen per (game, cell
position), so one physical mark is never both trained on and checked with.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ncbot.fileio import atomic_path
from ncbot.vision.labels import CELL_SIZE, LABELS, NOTHING

HELD_BACK_SHARE = 0.2  # of a game's cell positions, kept for the check set


@dataclass(frozen=True)
class View:
    """One look at the sheet: its cells as the reader cuts them, and how many moves had been made then."""

    cells: np.ndarray  # uint8 (n, 40, 40)
    moves: int


@dataclass
class CellExamples:
    """Labelled cells: images, label indices (`vision.labels.LABELS`), the game each came from, its cell position
    on the sheet, and whether it is held back for the check set."""

    images: np.ndarray     # uint8 (N, 40, 40)
    labels: np.ndarray     # int64 (N,)
    games: np.ndarray      # int64 (N,)
    positions: np.ndarray  # int64 (N,)
    held_back: np.ndarray  # bool (N,)

    @classmethod
    def empty(cls) -> "CellExamples":
        return cls(np.zeros((0, CELL_SIZE, CELL_SIZE), np.uint8), *(np.zeros(0, np.int64) for _ in range(3)),
                   np.zeros(0, bool))

    def __len__(self) -> int:
        return len(self.labels)

    def select(self, keep: np.ndarray) -> "CellExamples":
        return CellExamples(self.images[keep], self.labels[keep], self.games[keep], self.positions[keep],
                            self.held_back[keep])

    def concat(self, other: "CellExamples") -> "CellExamples":
        return CellExamples(*(np.concatenate([a, b]) for a, b in zip(self._arrays(), other._arrays())))

    def _arrays(self) -> tuple[np.ndarray, ...]:
        return self.images, self.labels, self.games, self.positions, self.held_back

    def counts(self) -> dict[str, int]:
        """Examples per label name (what a game taught, in the report)."""
        return {name: int((self.labels == k).sum()) for k, name in enumerate(LABELS)}

    def save(self, path: str | Path) -> Path:
        """One compressed .npz, written atomically (a crash leaves the previous file)."""
        with atomic_path(path) as temp, open(temp, "wb") as handle:
            np.savez_compressed(handle, images=self.images, labels=self.labels, games=self.games,
                                positions=self.positions, held_back=self.held_back)
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> "CellExamples":
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                return cls(data["images"], data["labels"], data["games"], data["positions"], data["held_back"])
        except (OSError, KeyError, ValueError) as error:
            raise ValueError(f"{path} is not a file of settled cells written by ncbot ({type(error).__name__}: "
                             f"{str(error)[:120]})") from None


def is_held_back(game: int, position: int, share: float = HELD_BACK_SHARE) -> bool:
    """Whether cell `position` of game `game` belongs to the check set (a fixed hash: the same on every run)."""
    return zlib.crc32(f"{game}:{position}".encode()) % 1000 < share * 1000


def settled_examples(views: Sequence[View], moves: Sequence[tuple[int, int]], game: int,
                     share: float = HELD_BACK_SHARE) -> CellExamples:
    """Every cell of every view labelled by the settled game: `moves` are (cell, label index) in the order they were
    made (both sides' moves); a view taken after k moves shows the first k of them. Views of a position after a
    move there that no view saw are labelled like any other."""
    if not views:
        return CellExamples.empty()
    images, labels, positions = [], [], []
    for view in views:
        board = np.full(len(view.cells), NOTHING, np.int64)
        for cell, label in list(moves)[: view.moves]:
            if not 0 <= cell < len(board):
                raise ValueError(f"settled move in cell {cell} lies outside the {len(board)}-cell sheet")
            board[cell] = label
        images.append(view.cells)
        labels.append(board)
        positions.append(np.arange(len(board)))
    position = np.concatenate(positions)
    held = np.array([is_held_back(game, int(p), share) for p in position], bool)
    return CellExamples(np.concatenate(images).astype(np.uint8), np.concatenate(labels),
                        np.full(len(position), game, np.int64), position, held)
