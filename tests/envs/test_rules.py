"""The exact rules (`ncbot.envs.rules`): lines, redirects, drawn subgrids, draws, illegal moves, immutability."""
from __future__ import annotations

import dataclasses
import random

import pytest

from ncbot.envs.rules import (
    DRAWN,
    EMPTY,
    LINES_3X3,
    O,
    SUBGRID_CELLS,
    TARGET_OF_CELL,
    X,
    Standard,
    State,
    Ultimate,
)
from ncbot.envs.games import make_game

VARIANTS = ("anywhere", "open_subgrids")


def _board_with(marks: dict[int, int], n_cells: int) -> tuple[int, ...]:
    board = [EMPTY] * n_cells
    for cell, mark in marks.items():
        board[cell] = mark
    return tuple(board)


# ---------------------------------------------------------------------------------------------------- 3x3
@pytest.mark.parametrize("line", LINES_3X3)
@pytest.mark.parametrize("winner", [X, O])
def test_every_3x3_line_wins(line: tuple[int, int, int], winner: int) -> None:
    """Fill the line with the winner's mark, filling in the loser's marks elsewhere without a line."""
    game = Standard()
    others = [c for c in range(9) if c not in line]
    rng = random.Random(hash(line) + winner)
    for _ in range(200):  # find loser squares that do not form a line themselves
        rng.shuffle(others)
        loser_cells = others[:3] if winner == O else others[:2]
        if not any(set(l) <= set(loser_cells) for l in LINES_3X3):
            break
    winner_cells = list(line)
    moves: list[int] = []
    first, second = (winner_cells, loser_cells) if winner == X else (loser_cells, winner_cells)
    for i in range(3):
        moves.append(first[i])
        if i < len(second) and (winner == O or i < 2):
            moves.append(second[i])
    state = game.play_many(moves)
    assert game.outcome(state) == ("x" if winner == X else "o")
    assert game.legal(state) == []


def test_3x3_turn_order_and_legal() -> None:
    game = Standard()
    s = game.new()
    assert game.to_move(s) == "x" and game.legal(s) == list(range(9)) and game.outcome(s) is None
    s = game.play(s, 4)
    assert game.to_move(s) == "o" and 4 not in game.legal(s) and s.last_move == 4


def test_3x3_draw() -> None:
    game = Standard()
    # x o x / x o o / o x x : full board, no line
    s = game.play_many([0, 1, 2, 4, 3, 5, 7, 6, 8])
    assert game.outcome(s) == "draw" and game.legal(s) == []


def test_3x3_win_on_last_square_is_a_win_not_a_draw() -> None:
    game = Standard()
    s = game.play_many([0, 1, 4, 2, 5, 3, 6, 7])  # x: 0 4 5 6, o: 1 2 3 7, no line yet
    assert game.outcome(s) is None and game.legal(s) == [8]
    s = game.play(s, 8)  # full board and the diagonal 0-4-8
    assert game.outcome(s) == "x"


# ---------------------------------------------------------------------------------------------------- illegal moves
@pytest.mark.parametrize("game", [Standard(), Ultimate("anywhere"), Ultimate("open_subgrids")], ids=repr)
def test_illegal_moves_raise_clear_errors(game) -> None:
    s = game.play(game.new(), 4)
    with pytest.raises(ValueError, match="already taken"):
        game.play(s, 4)
    with pytest.raises(ValueError, match="out of range"):
        game.play(s, game.n_cells)
    with pytest.raises(ValueError, match="out of range"):
        game.play(s, -1)
    with pytest.raises(ValueError, match="must be an int"):
        game.play(s, "b2")  # type: ignore[arg-type]


def test_no_move_after_game_end() -> None:
    game = Standard()
    s = game.play_many([0, 3, 1, 4, 2])
    assert game.outcome(s) == "x"
    with pytest.raises(ValueError, match="game is over"):
        game.play(s, 8)


def test_ultimate_wrong_subgrid_is_illegal() -> None:
    game = Ultimate()
    s = game.play(game.new(), 40)  # centre of centre -> o must play in the centre subgrid
    assert game.forced_subgrid(s) == 4
    with pytest.raises(ValueError, match="outside the subgrid you were sent to"):
        game.play(s, 0)


def test_open_subgrids_rejects_decided_subgrid_squares() -> None:
    game = Ultimate("open_subgrids")
    s = _x_owns_subgrid_zero_state(game)  # o to move, sent to subgrid 0, which x owns
    assert game.forced_subgrid(s) is None
    free_square_in_owned = next(c for c in SUBGRID_CELLS[0] if s.board[c] == EMPTY)
    with pytest.raises(ValueError, match="decided subgrid"):
        game.play(s, free_square_in_owned)


def test_bad_constructor_arguments_name_the_choices() -> None:
    with pytest.raises(ValueError, match="free_move.*anywhere.*open_subgrids"):
        Ultimate("everywhere")
    with pytest.raises(ValueError, match="game.*standard.*ultimate"):
        make_game("chess")


# ---------------------------------------------------------------------------------------------------- immutability
def test_states_are_immutable_and_hashable() -> None:
    for game in (Standard(), Ultimate()):
        s0 = game.new()
        s1 = game.play(s0, 0)
        assert s0 == game.new() and s0.board[0] == EMPTY and s0.last_move == -1
        assert s1.board[0] == X and s1 != s0
        with pytest.raises(dataclasses.FrozenInstanceError):
            s1.last_move = 3  # type: ignore[misc]
        assert isinstance(s1.board, tuple)
        assert hash(game.play(game.new(), 0)) == hash(s1)
        assert len({s0, s1, game.play(game.new(), 0)}) == 2


# ---------------------------------------------------------------------------------------------------- ultimate
def _x_owns_subgrid_zero_state(game: Ultimate) -> State:
    """x owns subgrid 0 (top row a1 b1 c1); o has just played at the top-left of its subgrid -> sent to 0."""
    # x: a1 b1 c1 (cells 0, 1, 2); o: d1 (3, position 0 of subgrid 1), d4 (27), g1 (6)
    board = _board_with({0: X, 1: X, 2: X, 27: O, 6: O, 3: O}, 81)
    s = State(board=board, last_move=3, subgrids=(X, 0, 0, 0, 0, 0, 0, 0, 0))
    game.validate(s)
    return s


@pytest.mark.parametrize("free_move", VARIANTS)
def test_redirect_to_open_subgrid_for_every_cell(free_move: str) -> None:
    """After any first move, the reply must lie in the subgrid mirroring that cell."""
    game = Ultimate(free_move)
    for cell in range(81):
        s = game.play(game.new(), cell)
        target = TARGET_OF_CELL[cell]
        assert game.forced_subgrid(s) == target
        expected = [c for c in SUBGRID_CELLS[target] if c != cell]
        assert game.legal(s) == sorted(expected), (cell, target)


def test_first_ultimate_move_is_free() -> None:
    for free_move in VARIANTS:
        game = Ultimate(free_move)
        assert game.legal(game.new()) == list(range(81))
        assert game.forced_subgrid(game.new()) is None


@pytest.mark.parametrize("free_move", VARIANTS)
@pytest.mark.parametrize("decided_as", [X, O, DRAWN])
@pytest.mark.parametrize("target", range(9))
def test_redirect_to_decided_subgrid(free_move: str, decided_as: int, target: int) -> None:
    """Sent to a won/lost/drawn subgrid: anywhere -> every empty square; open_subgrids -> open subgrids only."""
    game = Ultimate(free_move)
    subgrids = [0] * 9
    subgrids[target] = decided_as
    marks: dict[int, int] = {}
    inner = SUBGRID_CELLS[target]
    if decided_as == DRAWN:  # x o x / x o o / o x x
        pattern = [X, O, X, X, O, O, O, X, X]
    else:  # top row of the owner, one mark of the other side below it
        winner, other = decided_as, (O if decided_as == X else X)
        pattern = [winner, winner, winner, other, EMPTY, EMPTY, EMPTY, EMPTY, EMPTY]
    for cell, mark in zip(inner, pattern):
        if mark != EMPTY:
            marks[cell] = mark
    # balance the counts with marks elsewhere so that x is to move, the last move (by o) sent x to `target`
    n_x = sum(1 for m in marks.values() if m == X)
    n_o = sum(1 for m in marks.values() if m == O)
    spare = [k for k in range(9) if k != target]
    last_cell = SUBGRID_CELLS[spare[0]][target]  # position `target` inside another subgrid
    marks[last_cell] = O
    n_o += 1
    fill = [SUBGRID_CELLS[k][p] for k in spare[1:] for p in (0, 8)]  # two marks per subgrid: never a line
    while n_x != n_o:
        cell = fill.pop()
        if n_x < n_o:
            marks[cell], n_x = X, n_x + 1
        else:
            marks[cell], n_o = O, n_o + 1
    s = State(board=_board_with(marks, 81), last_move=last_cell, subgrids=tuple(subgrids))
    game.validate(s)
    assert game.to_move(s) == "x"
    assert game.forced_subgrid(s) is None
    empties = [c for c in range(81) if s.board[c] == EMPTY]
    if free_move == "anywhere":
        assert game.legal(s) == empties
    else:
        assert game.legal(s) == [c for c in empties if c not in inner]


def test_subgrid_full_without_line_is_drawn_and_counts_for_nobody() -> None:
    game = Ultimate()
    # The drawn pattern of subgrid 0 with its last square still empty; x is sent there and fills it.
    pattern = [X, O, X, X, O, O, O, X, EMPTY]  # x to fill the last square (bottom right): no line
    marks = {c: m for c, m in zip(SUBGRID_CELLS[0], pattern) if m != EMPTY}
    marks[SUBGRID_CELLS[1][0]] = O  # o's last move: position 0 of subgrid 1 -> x sent to subgrid 0
    marks[SUBGRID_CELLS[5][8]] = X  # balances the counts: x to move
    s = State(board=_board_with(marks, 81), last_move=SUBGRID_CELLS[1][0], subgrids=(0,) * 9)
    game.validate(s)
    assert game.legal(s) == [SUBGRID_CELLS[0][8]]
    s = game.play(s, SUBGRID_CELLS[0][8])
    assert game.subgrid_owner(s, 0) == "draw"
    assert game.outcome(s) is None


def test_anywhere_play_in_decided_subgrid_keeps_owner() -> None:
    """With free_move="anywhere" o may complete its own line inside x's subgrid: x still owns it."""
    game = Ultimate("anywhere")
    # subgrid 0: x owns the top row, o holds two of the middle row; o to move and sent to subgrid 0
    # x: 4 marks, o: 3 -> o to move; x's last mark is at position 0 of subgrid 8 -> o is sent to subgrid 0
    marks = {0: X, 1: X, 2: X, 9: O, 10: O, SUBGRID_CELLS[4][0]: O, SUBGRID_CELLS[8][0]: X}
    s = State(board=_board_with(marks, 81), last_move=SUBGRID_CELLS[8][0], subgrids=(X,) + (0,) * 8)
    game.validate(s)
    assert game.to_move(s) == "o" and game.forced_subgrid(s) is None
    s2 = game.play(s, 11)  # completes o's middle row of subgrid 0
    assert all(s2.board[c] == O for c in (9, 10, 11))
    assert game.subgrid_owner(s2, 0) == "x"
    with pytest.raises(ValueError):
        Ultimate("open_subgrids").play(s, 11)


MACRO_LINES = LINES_3X3


@pytest.mark.parametrize("free_move", VARIANTS)
@pytest.mark.parametrize("line", MACRO_LINES)
@pytest.mark.parametrize("winner", [X, O])
def test_every_macro_line_wins(free_move: str, line: tuple[int, int, int], winner: int) -> None:
    """The winner owns two subgrids of the line and completes a small line in the third."""
    game = Ultimate(free_move)
    loser = O if winner == X else X
    a, b, c = line
    subgrids = [0] * 9
    subgrids[a] = subgrids[b] = winner
    marks: dict[int, int] = {}
    for k in (a, b):
        for p in (0, 1, 2):
            marks[SUBGRID_CELLS[k][p]] = winner
    marks[SUBGRID_CELLS[c][3]] = winner
    marks[SUBGRID_CELLS[c][4]] = winner  # position 5 of subgrid c completes the middle row
    # the loser's last move sends the winner to subgrid c; the loser's marks: two per other subgrid
    spare = [k for k in range(9) if k not in line]
    last_cell = SUBGRID_CELLS[spare[0]][c]
    marks[last_cell] = loser
    n_winner = 8
    n_loser = 1
    fill = [SUBGRID_CELLS[k][p] for k in spare for p in (0, 8, 4) if SUBGRID_CELLS[k][p] != last_cell]
    need_loser = n_winner if winner == X else n_winner + 1  # winner to move: x needs #x == #o
    while n_loser < need_loser:
        marks[fill.pop(0)] = loser
        n_loser += 1
    s = State(board=_board_with(marks, 81), last_move=last_cell, subgrids=tuple(subgrids))
    game.validate(s)
    assert game.mark_to_move(s) == winner
    assert game.forced_subgrid(s) == c and game.outcome(s) is None
    s = game.play(s, SUBGRID_CELLS[c][5])
    assert game.subgrid_owner(s, c) == ("x" if winner == X else "o")
    assert game.outcome(s) == ("x" if winner == X else "o")
    assert game.legal(s) == []


@pytest.mark.parametrize("free_move", VARIANTS)
def test_random_games_end_consistently(free_move: str) -> None:
    """Random games end with a win exactly when a player has a line of subgrids, else with no legal move."""
    game = Ultimate(free_move)
    rng = random.Random(7)
    seen = set()
    for _ in range(150):
        s = game.new()
        while game.outcome(s) is None:
            s = game.play(s, rng.choice(game.legal(s)))
        result = game.outcome(s)
        seen.add(result)
        owners = s.subgrids
        lines = {m for m in (X, O) for l in LINES_3X3 if all(owners[k] == m for k in l)}
        if result == "draw":
            assert not lines
            empties = [cell for cell in range(81) if s.board[cell] == EMPTY]
            if free_move == "anywhere":
                assert empties == []  # anywhere: a draw only when the board is full
            else:
                assert all(owners[k] != 0 for k in range(9))
        else:
            assert lines == {X if result == "x" else O}
    assert seen == {"x", "o", "draw"}


def test_open_subgrids_draws_when_all_subgrids_decided() -> None:
    """open_subgrids: when the last open subgrid is decided without a line of subgrids, the game is drawn."""
    game = Ultimate("open_subgrids")
    rng = random.Random(3)
    for _ in range(300):
        s = game.new()
        while game.outcome(s) is None:
            s = game.play(s, rng.choice(game.legal(s)))
        if game.outcome(s) == "draw" and EMPTY in s.board:
            assert all(v != 0 for v in s.subgrids)
            return
    pytest.fail("no early draw found in 300 random open_subgrids games")


# ---------------------------------------------------------------------------------------------------- naming
def test_cell_names_round_trip_and_bad_names() -> None:
    for game in (Standard(), Ultimate()):
        for cell in range(game.n_cells):
            assert game.parse_cell(game.cell_name(cell)) == cell
    assert Standard().cell_name(4) == "b2" and Ultimate().cell_name(40) == "e5"
    assert Standard().parse_cell(" B2 ") == 4
    for text in ("d1", "a4", "zz", "", "a0", "2b", "4", "x4", "gridloc=4"):  # one notation: column then row
        with pytest.raises(ValueError, match="not a cell"):
            Standard().parse_cell(text)


def test_render_shows_coordinates_and_marks() -> None:
    game = Ultimate()
    s = game.play_many([40, 41])
    text = game.render(s)
    assert text.splitlines()[0].split() == list("abcdefghi")
    assert "x" in text and "o" in text
    legal_view = game.render(s, mark_legal=True)
    assert legal_view.count("·") == len(game.legal(s))
    assert "a   b   c" in Standard().render(Standard().new())
