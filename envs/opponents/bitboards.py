"""Bitboard game engines for tree search: the same rules as ``ncbot.envs.rules``, cut down for speed.

MCTS spends nearly all its time in random playouts, so positions here are small tuples of 9-bit ints and
every question ("is this a line?", "which squares of this subgrid are free?") is one lookup in a table
precomputed over all 512 masks. Sides are 0 (to move first in the position we were given) and 1; results are
``ONGOING`` (-1), 0 or 1 (that side won) or ``DRAW`` (2). ``tests/envs/test_opponents.py`` checks these engines
against ``ncbot.envs.rules`` on random games of both games and both free-move variants.

Ultimate positions: ``(subs0, subs1, decided, macro0, macro1, target, turn, n_empty, result)`` with
``subs*`` tuples of nine 9-bit masks (bit p = square p of subgrid k), ``decided`` a 9-bit mask of won or
drawn subgrids, ``macro*`` the subgrids each side owns, ``target`` the subgrid the side to move must play in
(-1: free). Standard positions: ``(bits0, bits1, turn, result)``.
"""
from __future__ import annotations

from ncbot.envs.core import LINES_3X3, SUBGRID_CELLS, SUBGRID_OF_CELL, TARGET_OF_CELL
from ncbot.envs.opponents.declared_bits import DRAW, ONGOING

FULL = 0b111111111

LINE_MASKS = tuple(sum(1 << i for i in line) for line in LINES_3X3)
IS_LINE = tuple(any(mask & line == line for line in LINE_MASKS) for mask in range(512))


def _completing(mask: int) -> int:
    squares = 0
    for line in LINE_MASKS:
        if bin(line & mask).count("1") == 2:
            squares |= line & ~mask
    return squares


# the third square of each line holding two of a 9-bit mask: a threat where it is still empty (a mask with a line
# already keeps only these, as the env's threat planes do)
COMPLETING = tuple(_completing(mask) for mask in range(512))
FREE_SQUARES = tuple(tuple(p for p in range(9) if not mask >> p & 1) for mask in range(512))
SQUARES_OF_MASK = tuple(FREE_SQUARES[FULL ^ mask] for mask in range(512))  # 9-bit set -> its squares
N_FREE = tuple(len(squares) for squares in FREE_SQUARES)
CELL_OF = tuple(tuple(row) for row in SUBGRID_CELLS)  # (subgrid, square) -> full-grid cell
SUBGRID_OF = SUBGRID_OF_CELL  # cell -> its subgrid
SQUARE_OF = TARGET_OF_CELL  # cell -> its square inside the subgrid (= the subgrid it sends the opponent to)


class StandardBits:
    """3x3 Noughts & Crosses on two 9-bit masks."""

    n_cells = 9

    def from_board(self, board: list[int], mover: int, last_move: int = -1, owners=None) -> tuple:
        """Position from a board of codes (0 empty, else the player's code); ``mover`` is the code to move."""
        bits0 = sum(1 << c for c in range(9) if board[c] == mover)
        bits1 = sum(1 << c for c in range(9) if board[c] not in (0, mover))
        result = 1 if IS_LINE[bits1] else 0 if IS_LINE[bits0] else DRAW if (bits0 | bits1) == FULL else ONGOING
        return (bits0, bits1, 0, result)

    def result(self, pos: tuple) -> int:
        return pos[3]

    def turn(self, pos: tuple) -> int:
        return pos[2]

    def moves(self, pos: tuple) -> list[int]:
        if pos[3] != ONGOING:
            return []
        return list(FREE_SQUARES[pos[0] | pos[1]])

    def play(self, pos: tuple, cell: int) -> tuple:
        bits0, bits1, turn, _ = pos
        if turn == 0:
            bits0 |= 1 << cell
            mine = bits0
        else:
            bits1 |= 1 << cell
            mine = bits1
        result = turn if IS_LINE[mine] else DRAW if (bits0 | bits1) == FULL else ONGOING
        return (bits0, bits1, turn ^ 1, result)

    def position_cells(self, pos: tuple) -> tuple[list[int], list[int]]:
        """The cells of the side to move and of the other side."""
        lists = (list(SQUARES_OF_MASK[pos[0]]), list(SQUARES_OF_MASK[pos[1]]))
        return lists if pos[2] == 0 else (lists[1], lists[0])

    def threat_indices(self, pos: tuple) -> list[int]:
        """The env's threat planes of the position that are 1, seen from the side to move (``threat_features``)."""
        return position_threat_indices(pos, self.n_cells)

    def rollout(self, pos: tuple, rand) -> int:
        """Play uniformly random moves to the end; the result (0, 1 or DRAW)."""
        bits = [pos[0], pos[1]]
        turn, result = pos[2], pos[3]
        if result != ONGOING:
            return result
        while True:
            free = FREE_SQUARES[bits[0] | bits[1]]
            mine = bits[turn] | 1 << free[int(rand() * len(free))]
            bits[turn] = mine
            if IS_LINE[mine]:
                return turn
            if len(free) == 1:
                return DRAW
            turn ^= 1


class UltimateBits:
    """Ultimate Noughts & Crosses on per-subgrid 9-bit masks; ``anywhere`` selects the free-move rule."""

    n_cells = 81

    def __init__(self, free_move: str = "anywhere") -> None:
        self.anywhere = free_move == "anywhere"

    def from_board(self, board: list[int], mover: int, last_move: int = -1, owners=None) -> tuple:
        """Position from codes (0 empty), the code to move, the last cell (-1) and optional subgrid owners.

        ``owners`` (9 codes: 0 open, a player's code, 3 drawn) makes ownership exact. Without it owners are
        read from the board; a subgrid holding lines of both sides (possible only with ``anywhere``, where the
        board cannot tell who was first) is credited to code 1, as ``ncbot.envs.opponents.lines.subgrid_owners`` does.
        """
        subs0 = tuple(sum(1 << p for p in range(9) if board[CELL_OF[k][p]] == mover) for k in range(9))
        subs1 = tuple(sum(1 << p for p in range(9) if board[CELL_OF[k][p]] not in (0, mover)) for k in range(9))
        macro0 = macro1 = decided = 0
        for k in range(9):
            if owners is not None:
                code = int(owners[k])
                side = -1 if code == 0 else DRAW if code == 3 else 0 if code == mover else 1
            elif IS_LINE[subs0[k]] and IS_LINE[subs1[k]]:
                side = 0 if mover == 1 else 1
            else:
                side = 0 if IS_LINE[subs0[k]] else 1 if IS_LINE[subs1[k]] else DRAW if (subs0[k] | subs1[k]) == FULL else -1
            if side != -1:
                decided |= 1 << k
                if side == 0:
                    macro0 |= 1 << k
                elif side == 1:
                    macro1 |= 1 << k
        n_empty = sum(1 for c in range(81) if board[c] == 0)
        target = -1
        if last_move >= 0 and not decided >> SQUARE_OF[last_move] & 1:
            target = SQUARE_OF[last_move]
        if IS_LINE[macro1]:
            result = 1
        elif IS_LINE[macro0]:
            result = 0
        else:
            result = ONGOING
        pos = (subs0, subs1, decided, macro0, macro1, target, 0, n_empty, result)
        if result == ONGOING and not self.moves(pos):
            pos = pos[:8] + (DRAW,)
        return pos

    def result(self, pos: tuple) -> int:
        return pos[8]

    def turn(self, pos: tuple) -> int:
        return pos[6]

    def moves(self, pos: tuple) -> list[int]:
        subs0, subs1, decided, _, _, target, _, _, result = pos
        if result != ONGOING:
            return []
        if target >= 0:
            return [CELL_OF[target][p] for p in FREE_SQUARES[subs0[target] | subs1[target]]]
        cells = [
            CELL_OF[k][p]
            for k in range(9)
            if self.anywhere or not decided >> k & 1
            for p in FREE_SQUARES[subs0[k] | subs1[k]]
        ]
        cells.sort()
        return cells

    def play(self, pos: tuple, cell: int) -> tuple:
        subs0, subs1, decided, macro0, macro1, _, turn, n_empty, _ = pos
        k, p = SUBGRID_OF[cell], SQUARE_OF[cell]
        result = ONGOING
        if turn == 0:
            mine = subs0[k] | 1 << p
            subs0 = subs0[:k] + (mine,) + subs0[k + 1:]
        else:
            mine = subs1[k] | 1 << p
            subs1 = subs1[:k] + (mine,) + subs1[k + 1:]
        if not decided >> k & 1:
            if IS_LINE[mine]:
                decided |= 1 << k
                if turn == 0:
                    macro0 |= 1 << k
                    result = 0 if IS_LINE[macro0] else ONGOING
                else:
                    macro1 |= 1 << k
                    result = 1 if IS_LINE[macro1] else ONGOING
            elif (subs0[k] | subs1[k]) == FULL:
                decided |= 1 << k
        target = -1 if decided >> p & 1 else p
        n_empty -= 1
        if result == ONGOING and (n_empty == 0 if self.anywhere else decided == FULL):
            result = DRAW
        return (subs0, subs1, decided, macro0, macro1, target, turn ^ 1, n_empty, result)

    def position_cells(self, pos: tuple) -> tuple[list[int], list[int]]:
        """The cells of the side to move and of the other side."""
        lists = tuple([CELL_OF[k][p] for k in range(9) for p in SQUARES_OF_MASK[subs[k]]] for subs in (pos[0], pos[1]))
        return lists if pos[6] == 0 else (lists[1], lists[0])

    def threat_indices(self, pos: tuple) -> list[int]:
        """The env's threat planes of the position that are 1, seen from the side to move (``threat_features``)."""
        return position_threat_indices(pos, self.n_cells)

    def rollout(self, pos: tuple, rand) -> int:
        """Play uniformly random legal moves to the end; the result (0, 1 or DRAW). The hot loop of MCTS.

        Keeps one occupancy mask per subgrid (both sides) and updates a side's own mask only while its subgrid
        is open: a decided subgrid's owner never changes, so only its free squares still matter.
        """
        subs0, subs1, decided, macro0, macro1, target, turn, n_empty, result = pos
        if result != ONGOING:
            return result
        subs = (list(subs0), list(subs1))
        occ = [a | b for a, b in zip(subs0, subs1)]
        macro = [macro0, macro1]
        anywhere = self.anywhere
        free_squares, n_free, is_line = FREE_SQUARES, N_FREE, IS_LINE
        while True:
            if target >= 0:
                k = target
                o = occ[k]
                p = free_squares[o][int(rand() * n_free[o])]
            else:  # free move: uniform over the allowed empty squares, walking subgrids by their free counts
                if anywhere:
                    r = int(rand() * n_empty)
                    for k in range(9):
                        c = n_free[occ[k]]
                        if r < c:
                            break
                        r -= c
                else:
                    r = int(rand() * sum(n_free[occ[j]] for j in range(9) if not decided >> j & 1))
                    for k in range(9):
                        if decided >> k & 1:
                            continue
                        c = n_free[occ[k]]
                        if r < c:
                            break
                        r -= c
                p = free_squares[occ[k]][r]
            bit = 1 << p
            o = occ[k] | bit
            occ[k] = o
            n_empty -= 1
            if not decided >> k & 1:
                mine = subs[turn][k] | bit
                subs[turn][k] = mine
                if is_line[mine]:
                    decided |= 1 << k
                    owned = macro[turn] | 1 << k
                    macro[turn] = owned
                    if is_line[owned]:
                        return turn
                elif o == FULL:
                    decided |= 1 << k
            if anywhere:
                if n_empty == 0:
                    return DRAW
            elif decided == FULL:
                return DRAW
            target = -1 if decided >> p & 1 else p
            turn ^= 1


def position_threat_indices(pos: tuple, cells: int) -> list[int]:
    """Indices into the ``threat_planes`` of one bitboard position (``ncbot.envs.opponents.bitboards``) that are 1, seen
    from the side to move (its threats first, as the robot's).

    Why: the Q-guided search builds one position's features per expansion; the batched torch version costs ~0.3 ms
    there, these table lookups a few microseconds, and the bitboard knows the exact subgrid owners. Tested equal to
    ``threat_planes`` on random games of both games."""
    if cells == 9:
        bits0, bits1, turn, _ = pos
        sides = (bits0, bits1) if turn == 0 else (bits1, bits0)
        free = FULL ^ (bits0 | bits1)
        return [plane * 9 + c for plane, bits in enumerate(sides) for c in SQUARES_OF_MASK[COMPLETING[bits] & free]]
    subs0, subs1, decided, macro0, macro1, _, turn = pos[:7]
    sides, macros = ((subs0, subs1), (macro0, macro1)) if turn == 0 else ((subs1, subs0), (macro1, macro0))
    indices = []
    for plane, subs in enumerate(sides):
        for k in SQUARES_OF_MASK[FULL ^ decided]:  # open subgrids only
            threats = COMPLETING[subs[k]] & (FULL ^ (subs0[k] | subs1[k]))
            indices += [plane * 81 + CELL_OF[k][p] for p in SQUARES_OF_MASK[threats]]
    for plane, macro in enumerate(macros):
        indices += [162 + plane * 9 + k for k in SQUARES_OF_MASK[COMPLETING[macro] & (FULL ^ decided)]]
    return indices
