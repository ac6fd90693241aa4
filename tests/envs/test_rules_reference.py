"""An independent check of `ncbot.envs.rules`: known counts, hand-made playthroughs and a second implementation.

Nothing here imports rule logic from `ncbot.envs.rules` except the two games under test: the reference game below
is written from the rule text with (row, col) coordinates and direction vectors instead of line tables, so a
shared mistake would have to be made twice in different ways.
"""
from __future__ import annotations

import random
from functools import lru_cache

import pytest

from ncbot.envs.rules import Standard, Ultimate

DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))


def three_in_a_row(owner_at, who: str) -> bool:
    """``owner_at(r, c)`` on a 3x3 grid: does ``who`` hold some full line? Checked by walking directions."""
    for r0 in range(3):
        for c0 in range(3):
            for dr, dc in DIRECTIONS:
                cells = [(r0 + i * dr, c0 + i * dc) for i in range(3)]
                if all(0 <= r < 3 and 0 <= c < 3 for r, c in cells) and all(owner_at(r, c) == who for r, c in cells):
                    return True
    return False


class ReferenceUltimate:
    """Ultimate N&C written from the rule text: a mutable game object holding a dict of marks by (row, col)."""

    def __init__(self, free_move: str) -> None:
        self.free_move = free_move
        self.marks: dict[tuple[int, int], str] = {}
        self.owner: dict[tuple[int, int], str] = {}  # (big row, big col) -> "x" | "o" | "draw"
        self.last: tuple[int, int] | None = None
        self.player = "x"
        self.winner: str | None = None

    def _small_full(self, br: int, bc: int) -> bool:
        return all((br * 3 + r, bc * 3 + c) in self.marks for r in range(3) for c in range(3))

    def moves(self) -> set[tuple[int, int]]:
        if self.winner is not None:
            return set()
        empty = {(r, c) for r in range(9) for c in range(9) if (r, c) not in self.marks}
        if self.last is not None:
            sent_to = (self.last[0] % 3, self.last[1] % 3)
            if sent_to not in self.owner:
                return {(r, c) for r, c in empty if (r // 3, c // 3) == sent_to}
        if self.free_move == "anywhere":
            return empty
        return {(r, c) for r, c in empty if (r // 3, c // 3) not in self.owner}

    def move(self, r: int, c: int) -> None:
        assert (r, c) in self.moves()
        self.marks[(r, c)] = self.player
        big = (r // 3, c // 3)
        if big not in self.owner:
            if three_in_a_row(lambda i, j: self.marks.get((big[0] * 3 + i, big[1] * 3 + j)), self.player):
                self.owner[big] = self.player
            elif self._small_full(*big):
                self.owner[big] = "draw"
        self.last = (r, c)
        if three_in_a_row(lambda i, j: self.owner.get((i, j)), self.player):
            self.winner = self.player
        self.player = "o" if self.player == "x" else "x"
        if self.winner is None and not self.moves():
            self.winner = "draw"


# ------------------------------------------------------------------------------------------------ 3x3 counts
def _count_games(game: Standard):
    """(games, x wins, o wins, draws, reachable boards, terminal boards) by exhaustive search over `game`."""
    reachable: set[tuple[int, ...]] = set()
    terminal: set[tuple[int, ...]] = set()

    @lru_cache(maxsize=None)
    def games_from(state) -> tuple[int, int, int]:
        reachable.add(state.board)
        result = game.outcome(state)
        if result is not None:
            terminal.add(state.board)
            return (result == "x", result == "o", result == "draw")
        totals = [0, 0, 0]
        for cell in game.legal(state):
            for i, n in enumerate(games_from(game.play(state, cell))):
                totals[i] += n
        return tuple(totals)

    x_wins, o_wins, draws = games_from(game.new())
    return x_wins + o_wins + draws, x_wins, o_wins, draws, len(reachable), len(terminal)


def test_standard_matches_the_known_game_counts() -> None:
    """Known facts about tic-tac-toe: 255,168 games (131,184 / 77,904 / 46,080), 5,478 positions, 958 terminal."""
    assert _count_games(Standard()) == (255_168, 131_184, 77_904, 46_080, 5_478, 958)


def test_reference_3x3_counts_by_bitmasks() -> None:
    """The same counts from a bitmask enumeration sharing nothing with the rules module (checks the check)."""
    wins = [sum(1 << (r * 3 + c) for r, c in cells) for cells in (
        [(i, j) for j in range(3)] for i in range(3))]
    wins += [sum(1 << (i * 3 + j) for i in range(3)) for j in range(3)]
    wins += [1 | 16 | 256, 4 | 16 | 64]

    def won(bits: int) -> bool:
        return any(bits & w == w for w in wins)

    totals = [0, 0, 0]

    def walk(mover: int, other: int, x_to_move: bool) -> None:
        for cell in range(9):
            bit = 1 << cell
            if (mover | other) & bit:
                continue
            new = mover | bit
            if won(new):
                totals[0 if x_to_move else 1] += 1
            elif (new | other) == 511:
                totals[2] += 1
            else:
                walk(other, new, not x_to_move)

    walk(0, 0, True)
    assert totals == [131_184, 77_904, 46_080]


# ------------------------------------------------------------------------------------------------ playthroughs
def test_hand_made_3x3_playthroughs() -> None:
    game = Standard()
    cases = [  # (moves by name, expected outcome)
        ("b2 a1 c1 a3 a2 c2 b1 b3 c3", "draw"),
        ("a1 b1 a2 b2 a3", "x"),
        ("b2 a1 c3 a3 a2 c1 b3 b1", "o"),  # o completes the top row a1 b1 c1
        ("c1 b2 a3 a1 c3 c2 b3", "x"),  # x completes the bottom row a3 b3 c3
    ]
    for moves, expected in cases:
        s = game.new()
        for name in moves.split():
            assert game.outcome(s) is None
            s = game.play(s, game.parse_cell(name))
        assert game.outcome(s) == expected, moves


@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_hand_made_ultimate_playthrough(free_move: str) -> None:
    """x wins the centre subgrid by bouncing o to the corners, then is sent back to it (a decided subgrid)."""
    game = Ultimate(free_move)
    s = game.new()
    script = [
        # (cell, the subgrid the NEXT player is forced into or None, owners after the move)
        ("d4", 0), ("b2", 4),  # x d4 = top-left of the centre -> o to subgrid 0; o b2 -> x to the centre
        ("e4", 1), ("e2", 4),
        ("f4", 2),  # x completes the centre's top row -> owns subgrid 4; o goes to subgrid 2
        ("h2", None),  # o in the middle of subgrid 2 sends x to the centre, which x owns: a free move
    ]
    for name, forced in script:
        s = game.play(s, game.parse_cell(name))
        assert game.forced_subgrid(s) == forced, name
    assert game.subgrid_owner(s, 4) == "x" and game.outcome(s) is None
    centre_square = game.parse_cell("e5")
    assert (centre_square in game.legal(s)) == (free_move == "anywhere")
    assert len(game.legal(s)) == (81 - 6 if free_move == "anywhere" else 81 - 9 - 3)


# ------------------------------------------------------------------------------------------------ random agreement
@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_ultimate_agrees_with_the_reference_on_random_games(free_move: str) -> None:
    game = Ultimate(free_move)
    rng = random.Random(2019)
    outcomes = set()
    for _ in range(300):
        ref = ReferenceUltimate(free_move)
        s = game.new()
        while True:
            ref_moves = sorted(r * 9 + c for r, c in ref.moves())
            assert game.legal(s) == ref_moves
            assert game.outcome(s) == ref.winner
            for k in range(9):
                assert game.subgrid_owner(s, k) == ref.owner.get((k // 3, k % 3))
            if not ref_moves:
                break
            cell = rng.choice(ref_moves)
            ref.move(cell // 9, cell % 9)
            s = game.play(s, cell)
            assert game.to_move(s) == ref.player
        outcomes.add(ref.winner)
    assert outcomes == {"x", "o", "draw"}
