"""Seeded frame sequences of a person drawing a move: the recogniser's test material.

One fixed scene (camera, table, light); the board of the game so far; then the hand reaches in, draws the
mark stroke by stroke while moving, and leaves. Every frame has fresh sensor noise. `hand` flags which
frames show the hand, so a test can check that no move is ever reported from one of those.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncbot.vision.data.frames import random_board, random_hand, random_scene, render
from ncbot.vision.sheet import Grid


@dataclass
class MoveSequence:
    frames: list[np.ndarray]
    hand: list[bool]          # per frame: a hand is in view over the sheet
    known_board: list[str]    # the board before the move (what the game history says)
    move: int                 # the cell the person draws in
    symbol: str               # "x" or "o"


def make_move_sequence(grid: Grid, seed: int, before: int = 3, drawing: int = 5, after: int = 5,
                       width: int = 640, height: int = 480, styles: tuple[str, ...] = ("pen",),
                       still_hand: int = 0, conditions: str = "clean") -> MoveSequence:
    """before clean frames, `drawing` frames of the hand drawing (progress rising to 1), `still_hand`
    frames of the hand resting still after the mark is done, then `after` clean frames; grid: 3, 9 or a
    declared game's (rows, cols)."""
    rng = np.random.default_rng(seed)
    scene = random_scene(grid, rng, width, height, styles, conditions)
    board = random_board(grid, rng, fill=rng.uniform(0.0, 0.6))
    empty = [i for i, s in enumerate(board) if not s] or [int(rng.integers(len(board)))]
    move = int(rng.choice(empty))
    board[move] = ""
    symbol = "x" if rng.random() < 0.5 else "o"
    target = np.array(scene.cell_in_frame(move))
    hand = random_hand(rng, tuple(target))
    frames, flags = [], []
    for _ in range(before):
        frames.append(render(scene, board, rng)); flags.append(False)
    for k in range(drawing):
        hand.tip = tuple(target + rng.normal(0, 0.25 * hand.scale, 2))
        frames.append(render(scene, board, rng, partial=(move, symbol, (k + 1) / drawing), hand=hand)); flags.append(True)
    done = list(board)
    done[move] = symbol
    for _ in range(still_hand):
        frames.append(render(scene, done, rng, hand=hand)); flags.append(True)
    for _ in range(after):
        frames.append(render(scene, done, rng)); flags.append(False)
    return MoveSequence(frames, flags, board, move, symbol)
