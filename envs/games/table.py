"""Every position of a small game, enumerated once with its rules, and what follows from them as tables.

A position is a rules state plus which seat (1 robot, 2 human) holds x, as the env and the opponents see the board;
the empty start is one position (nobody holds x until someone moves). For each position the table keeps its board in
seat codes, its outcome, and for each cell and seat the position a move leads to. From these the one-step look-ahead
of the paper's rewards is read off per (position, cell, seat), with these meanings, all from the rules:

- win / draw / lose: the move ends the game with the mover winning, drawn, losing (+5, +1, -5);
- about to lose (-5): the other side then has a move that wins it the game at once, or a reply after which every
  move of the mover loses at once (misère's trap: the mover is left only squares that complete its own line);
- about to draw (+1): after the move nobody can win any more (no sequence of legal moves ends in a win), where
  someone still could before;
- about to win (+5): the other side has a reply after which the mover wins at once, or every reply of the other side
  ends the game in the mover's win; with ``about_to="created"`` only when the mover had no winning move before.

On the 3x3 rules these read as the 3x3 engine's events wherever both definitions say the same (win, draw, about to
lose always; the others on most positions: ``tests/envs/test_game_table.py``).

Priority as the built-in engines: win, draw, lose / about to lose, about to draw, about to win. ``tests/envs/
test_game_table.py`` checks each against a replay of the rules.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ncbot.envs.core import DRAWN, O, REWARD_LOSE, X
from ncbot.envs.engine.tables import prioritise
from ncbot.envs.games.symmetries import board_symmetries

_OUTCOME = {None: 0, "draw": DRAWN}


class GameTable:
    """The positions of ``game`` (see the module doc); numpy arrays indexed by position id, 0 the empty start."""

    def __init__(self, game: Any, limit: int) -> None:
        self.game, self.cells = game, game.n_cells
        states, boards, outcome, nxt = _enumerate(game, limit)
        self.states = states  # (rules state, seat holding x) of each position
        self.boards = boards  # (S, cells) int8 seat codes
        self.outcome = outcome  # (S,) int64: 0 on, 1 / 2 that seat won, 3 drawn
        self.next = nxt  # (S, cells, 2) int64: the position after seat p + 1 takes the cell, -1 when it may not
        self.legal = (nxt >= 0).any(2)  # (S, cells) the cells the seat to move may take
        self.to_move = np.array([(x_seat if game.mark_to_move(state) == X else 3 - x_seat) if x_seat else 0
                                 for state, x_seat in states], dtype=np.int64)  # (S,) the seat to move (0: the start)
        self.n_marks = (boards != 0).sum(1)
        self._index = {(self._code(board), int(seat)): i for i, (board, seat) in enumerate(zip(boards, self.to_move))}
        self.wins, self.rewards = {}, {}
        can_win = self._can_win()
        for player in (1, 2):
            self.wins[player], self.rewards[player] = self._rewards(player, can_win)
        self.lose_value = REWARD_LOSE

    @staticmethod
    def _code(board: np.ndarray) -> bytes:
        return np.asarray(board, dtype=np.int8).tobytes()

    def position(self, board: Any, player: int) -> int:
        """The id of the position with ``board`` (seat codes) and ``player`` to move; -1 if the rules never reach it."""
        code = self._code(board)
        found = self._index.get((code, player))
        return self._index.get((code, 0), -1) if found is None else found

    def board_rows(self, boards: torch.Tensor, player: int, rows: np.ndarray) -> torch.Tensor:
        """(B, cells) ``rows[position]`` of each board with ``player`` to move (all False / 0 where never reached)."""
        found = [self.position(board, player) for board in boards.to(torch.int8).numpy()]
        out = np.zeros((len(found), self.cells), dtype=rows.dtype)
        reached = np.array([i for i, p in enumerate(found) if p >= 0], dtype=np.int64)
        if len(reached):
            out[reached] = rows[np.array([found[i] for i in reached])]
        return torch.from_numpy(out)

    # -- what follows from the rules ---------------------------------------------------------------------------
    def _after(self, player: int) -> tuple[np.ndarray, np.ndarray]:
        """(S, cells) the position after ``player`` takes each cell (0 where it may not) and whether it may."""
        after = self.next[:, :, player - 1]
        return np.where(after >= 0, after, 0), after >= 0

    def _wins_now(self, player: int) -> np.ndarray:
        """(S, cells) bool: ``player`` taking the cell wins the game at once."""
        after, valid = self._after(player)
        return valid & (self.outcome[after] == player)

    def _can_win(self) -> np.ndarray:
        """(S,) bool: some sequence of legal moves from the position ends in a win (positions by marks, last first)."""
        can = np.isin(self.outcome, (1, 2))
        for marks in range(int(self.n_marks.max()), -1, -1):
            layer = np.flatnonzero(self.n_marks == marks)
            after = self.next[layer].reshape(len(layer), -1)
            reach = np.where(after >= 0, can[np.where(after >= 0, after, 0)], False).any(1)
            can[layer] |= reach
        return can

    def _rewards(self, p: int, can_win: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(S, cells) bool the moves of ``p`` that win now, and (S, cells) float32 their one-step rewards (module doc)."""
        q = 3 - p
        after, valid = self._after(p)
        result = self.outcome[after]
        on = valid & (result == 0)
        win_now_any = {s: self._wins_now(s).any(1) for s in (p, q)}
        squeezed = {s: self._squeezed(s) for s in (p, q)}  # every move of that seat, to move, loses at once
        reply, reply_valid = self._after(q)  # (S, cells): q's replies from each position
        reply_on = reply_valid & (self.outcome[reply] == 0)
        threat = (reply_on & win_now_any[p][reply]).any(1)  # (S,) q to move: a reply leaves p a winning move
        trapped = (reply_on & squeezed[p][reply]).any(1)  # (S,) q to move: a reply leaves p only losing moves
        about_to_win = on & (threat | squeezed[q])[after]
        win = valid & (result == p)
        about_to_lose = on & (win_now_any[q] | trapped)[after]
        about_to_draw = on & ~can_win[after] & can_win[:, None]
        lose = valid & (result == q)
        draw = valid & (result == DRAWN)
        tensors = [torch.from_numpy(np.ascontiguousarray(a)) for a in (win, draw, lose | about_to_lose, about_to_draw)]
        rewards = {}
        for reading, events in (("standing", about_to_win), ("created", about_to_win & ~win_now_any[p][:, None])):
            rewards[reading] = prioritise(*tensors, torch.from_numpy(np.ascontiguousarray(events))).numpy()
        self.__dict__.setdefault("_created", {})[p] = rewards["created"]
        return win, rewards["standing"]

    def _squeezed(self, player: int) -> np.ndarray:
        """(S,) bool: ``player``, to move, has moves and every one of them loses the game at once."""
        after, valid = self._after(player)
        loses = valid & (self.outcome[after] == 3 - player)
        return valid.any(1) & (loses | ~valid).all(1)

    def reward_rows(self, player: int, about_to: str) -> np.ndarray:
        """(S, cells) float32 the one-step rewards of ``player`` under the reading ``about_to``."""
        return self.rewards[player] if about_to == "standing" else self._created[player]

    # -- exact play and symmetries -----------------------------------------------------------------------------
    def solver(self) -> "TableSolver":
        solver = self.__dict__.get("_solver")
        if solver is None:
            solver = self.__dict__["_solver"] = TableSolver(self)
        return solver

    def symmetries(self) -> torch.Tensor:
        """(G, cells) the board maps (``board_symmetries``, identity first) under which every position maps to a
        position with the same seat to move, the same outcome and the mapped legal cells."""
        kept = []
        for image in board_symmetries(self.game.rows, self.game.cols, self.game.gravity).numpy():
            preimage = np.argsort(image)
            turned = self.boards[:, preimage]
            ids = np.array([self._index.get((self._code(board), int(seat)), -1) for board, seat in zip(turned, self.to_move)])
            if (ids >= 0).all() and (self.outcome[ids] == self.outcome).all() and \
                    (self.legal[ids] == self.legal[:, preimage]).all():
                kept.append(image)
        return torch.from_numpy(np.stack(kept)).long()


class TableSolver:
    """Exact play: the game value of every position for the seat to move (negamax over the table)."""

    def __init__(self, table: GameTable) -> None:
        self.table = table
        value = np.zeros((len(table.boards), 3), dtype=np.int8)  # [position, seat to move]: +1 win, 0 draw, -1 loss
        optimal = np.zeros((len(table.boards), 3, table.cells), dtype=bool)
        for marks in range(int(table.n_marks.max()), -1, -1):
            for position in np.flatnonzero(table.n_marks == marks):
                outcome = table.outcome[position]
                for seat in ((1, 2) if table.to_move[position] == 0 else (int(table.to_move[position]),)):
                    if outcome:
                        value[position, seat] = 0 if outcome == DRAWN else 1 if outcome == seat else -1
                        continue
                    after = table.next[position, :, seat - 1]
                    moves = np.flatnonzero(after >= 0)
                    scores = -value[after[moves], 3 - seat]
                    value[position, seat] = scores.max()
                    optimal[position, seat, moves[scores == scores.max()]] = True
        self.value, self.optimal = value, optimal

    def optimal_cells(self, boards: torch.Tensor, player: int) -> torch.Tensor:
        """(B, cells) bool the cells of optimal value for ``player`` to move (none on a board the rules never reach)."""
        return self.table.board_rows(boards, player, self.optimal[:, player])


def _enumerate(game: Any, limit: int) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
    """Breadth-first over the positions reachable from ``game.new()`` with the rules; ValueError past ``limit``.

    Each rules state is expanded once (its moves shared by the positions that differ only in who holds x)."""
    cells = game.n_cells
    start = (game.new(), 0)
    positions, ids, rows = [start], {start: 0}, []
    expanded: dict[Any, list[tuple[int, Any]]] = {}
    children = getattr(game, "children", None) or (lambda state: [(cell, game.play(state, cell)) for cell in game.legal(state)])
    i = 0
    while i < len(positions):
        state, x_seat = positions[i]
        row = [[-1, -1] for _ in range(cells)]
        if game.outcome(state) is None:
            mover = game.mark_to_move(state)
            if state not in expanded:
                expanded[state] = children(state)
            for cell, after in expanded[state]:
                for seat in ((1, 2) if x_seat == 0 else (x_seat if mover == X else 3 - x_seat,)):
                    key = (after, x_seat or (seat if mover == X else 3 - seat))
                    if key not in ids:
                        if len(positions) >= limit:
                            raise ValueError(f"game {game.name!r} has more than {limit:,} positions: too many to tabulate "
                                             "from its rules; give it its own engine() (docs/games.md)")
                        ids[key] = len(positions)
                        positions.append(key)
                    row[cell][seat - 1] = ids[key]
        rows.append(row)
        i += 1
    boards = np.zeros((len(positions), cells), dtype=np.int8)
    outcome = np.zeros(len(positions), dtype=np.int64)
    for index, (state, x_seat) in enumerate(positions):
        marks = np.asarray(state.board)
        boards[index] = np.where(marks == X, x_seat, np.where(marks == O, 3 - x_seat, 0)) if x_seat else 0
        result = game.outcome(state)
        outcome[index] = _OUTCOME[result] if result in _OUTCOME else (x_seat if result == "x" else 3 - x_seat)
    return positions, boards, outcome, np.array(rows, dtype=np.int64).reshape(len(positions), cells, 2)
