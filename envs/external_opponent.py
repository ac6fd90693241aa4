"""An opponent whose moves come from outside: the robot simulator (perceived human moves) or a test script.

Why: the env asks its opponent for the user's square inside ``step``. When a real (or simulated) person
plays, the caller knows the move before stepping; it queues it here and the env plays it as the user's.
"""
from __future__ import annotations

from collections import deque

import torch


class ExternalOpponent:
    """Plays queued moves. ``queue(cells)`` adds one move per game of the batch (a (B,) tensor or list);
    ``select`` pops the oldest for the rows that move. Raises ValueError when no move is queued or a
    queued move is not legal, so a perception error never silently becomes a different move.
    """

    name = "external"

    def __init__(self) -> None:
        self._pending: deque[torch.Tensor] = deque()

    def queue(self, cells) -> None:
        """Queue the user's next move for every game of the batch (entries of games that do not move are ignored)."""
        self._pending.append(torch.as_tensor(cells, dtype=torch.int64).reshape(-1))

    def __len__(self) -> int:
        return len(self._pending)

    def select(self, boards: torch.Tensor, last_move: torch.Tensor, legal: torch.Tensor, player: int, generator=None, rows: torch.Tensor | None = None) -> torch.Tensor:
        if not self._pending:
            raise ValueError("ExternalOpponent has no queued move: call queue(cells) before stepping the env")
        cells = self._pending.popleft()
        if rows is not None:
            cells = cells[rows]
        if cells.shape[0] != legal.shape[0]:
            raise ValueError(f"queued move holds {cells.shape[0]} cells, but {legal.shape[0]} games move now")
        ok = (cells >= 0) & (cells < legal.shape[1])
        if not bool(ok.all()) or not bool(legal.gather(1, cells.unsqueeze(1)).all()):
            raise ValueError(f"queued user move {cells.tolist()} is not legal here")
        return cells
