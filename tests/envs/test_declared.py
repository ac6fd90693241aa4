"""Declared games: the YAML declaration, the exact rules and the batched engine's look-ahead, each checked against a
brute-force reference written here from the rule text with (row, col) coordinates and direction vectors."""
from __future__ import annotations

import random

import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ncbot.envs.declaration import Declaration, declared_game, load_declaration, shipped_games
from ncbot.envs.engine import StandardEngine
from ncbot.envs.games import make_game
from ncbot.envs.games.declared import DeclaredGame as Declared
from ncbot.envs.readings import Readings
from tests.envs.helpers import engine_of as make_engine
from ncbot.envs.engine.declared import DeclaredEngine

DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))


class Reference:
    """The declared game from its text: marks in a dict by (row, col); lines found by walking four directions."""

    def __init__(self, rows: int, cols: int, k: int, gravity: bool) -> None:
        self.rows, self.cols, self.k, self.gravity = rows, cols, k, gravity

    def grid(self, board) -> dict[tuple[int, int], int]:
        return {(i // self.cols, i % self.cols): v for i, v in enumerate(board) if v}

    def has_line(self, marks: dict, who: int) -> bool:
        for r in range(self.rows):
            for c in range(self.cols):
                for dr, dc in DIRECTIONS:
                    if all(marks.get((r + i * dr, c + i * dc)) == who for i in range(self.k)) and \
                            0 <= r + (self.k - 1) * dr < self.rows and 0 <= c + (self.k - 1) * dc < self.cols:
                        return True
        return False

    def moves(self, marks: dict) -> set[tuple[int, int]]:
        empty = {(r, c) for r in range(self.rows) for c in range(self.cols) if (r, c) not in marks}
        if not self.gravity:
            return empty
        return {(r, c) for r, c in empty if r == self.rows - 1 or (r + 1, c) in marks}

    def dead(self, marks: dict) -> bool:
        """No line can be completed by anyone: every run of k holds marks of both players."""
        for r in range(self.rows):
            for c in range(self.cols):
                for dr, dc in DIRECTIONS:
                    cells = [(r + i * dr, c + i * dc) for i in range(self.k)]
                    if all(0 <= a < self.rows and 0 <= b < self.cols for a, b in cells):
                        if not {1, 2} <= {marks.get(cell) for cell in cells}:
                            return False
        return True

    def wins_now(self, marks: dict, who: int) -> bool:
        return any(self.has_line({**marks, cell: who}, who) for cell in self.moves(marks))

    def reward(self, marks: dict, cell: tuple[int, int], who: int, about_to: str = "standing") -> float:
        after = {**marks, cell: who}
        if self.has_line(after, who):
            return 5.0
        if len(after) == self.rows * self.cols:
            return 1.0
        if self.wins_now(after, 3 - who):
            return -5.0
        if self.dead(after) and not self.dead(marks):
            return 1.0
        if self.wins_now(after, who) and not (about_to == "created" and self.wins_now(marks, who)):
            return 5.0
        return 0.0


def random_position(game: Declared, rng: random.Random, stop: float):
    s = game.new()
    while game.outcome(s) is None and rng.random() > stop:
        s = game.play(s, rng.choice(game.legal(s)))
    return s


declarations = st.builds(
    lambda rows, cols, k, gravity: (rows, cols, min(k, max(rows, cols)), gravity),
    st.integers(3, 7), st.integers(3, 7), st.integers(3, 5), st.booleans(),
)


def declared(rows: int, cols: int, k: int, gravity: bool) -> Declaration:
    return Declaration("test", rows, cols, k, gravity, "test")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(declarations, st.integers(0, 10**6))
def test_rules_agree_with_the_reference_on_random_games(shape, seed):
    rows, cols, k, gravity = shape
    game, ref, rng = Declared(declared(*shape)), Reference(*shape), random.Random(seed)
    s = game.new()
    while True:
        marks = ref.grid(s.board)
        winner = 1 if ref.has_line(marks, 1) else 2 if ref.has_line(marks, 2) else None
        full = len(marks) == rows * cols
        expected = {1: "x", 2: "o", None: "draw" if full else None}[winner]
        assert game.outcome(s) == expected
        legal = {(c // cols, c % cols) for c in game.legal(s)}
        assert legal == (set() if expected else ref.moves(marks))
        if expected:
            break
        s = game.play(s, rng.choice(game.legal(s)))


@settings(max_examples=20, deadline=None)
@given(declarations, st.integers(0, 10**6), st.sampled_from(["standing", "created"]))
def test_engine_rewards_agree_with_the_reference(shape, seed, about_to):
    rows, cols, k, gravity = shape
    game, ref, rng = Declared(declared(*shape)), Reference(*shape), random.Random(seed)
    positions = [random_position(game, rng, 0.08) for _ in range(4)]
    positions = [s for s in positions if game.outcome(s) is None] or [game.new()]
    engine = DeclaredEngine(declared(*shape), Readings(about_to=about_to))
    state = engine.from_boards(torch.tensor([s.board for s in positions]))
    for player in (1, 2):
        rewards = engine.move_rewards(state, player)
        legal = engine.legal(state)
        for row, s in enumerate(positions):
            marks = ref.grid(s.board)
            assert {(c // cols, c % cols) for c in legal[row].nonzero().flatten().tolist()} == ref.moves(marks)
            for cell in ref.moves(marks):
                expected = ref.reward(marks, cell, player, about_to)
                assert rewards[row, cell[0] * cols + cell[1]].item() == expected, (s.board, cell, player)


def test_engine_play_matches_the_rules_and_draws_a_full_board():
    shape = (4, 5, 3, True)
    game, engine, rng = Declared(declared(*shape)), DeclaredEngine(declared(*shape)), random.Random(3)
    for _ in range(20):
        s, state = game.new(), engine.new(1)
        while game.outcome(s) is None:
            cell = rng.choice(game.legal(s))
            engine.play(state, torch.tensor([cell]), 1 if s.n_marks % 2 == 0 else 2)
            s = game.play(s, cell)
            assert state.board[0].tolist() == list(s.board)
        assert int(state.outcome[0]) == {"x": 1, "o": 2, "draw": 3}[game.outcome(s)]


def test_declared_3x3_engine_gives_the_standard_engines_rewards():
    """The generic path on rows 3, cols 3, k 3 reproduces the 3x3 tables' look-ahead on every reachable position."""
    rng, game = random.Random(0), make_game("standard")
    states = [random_position(game, rng, 0.1) for _ in range(400)]
    boards = torch.tensor(sorted({s.board for s in states if game.outcome(s) is None}))
    for about_to in ("standing", "created"):
        generic = DeclaredEngine(declared(3, 3, 3, False), Readings(about_to=about_to))
        standard = StandardEngine(Readings(about_to=about_to))
        for player in (1, 2):
            mine = generic.move_rewards(generic.from_boards(boards), player)
            theirs = standard.move_rewards(standard.from_boards(boards), player)
            empty = boards == 0
            assert torch.equal(mine[empty], theirs[empty])


def test_shipped_declarations_load():
    assert {"four", "connect_four"} <= set(shipped_games())
    four, c4 = declared_game("four"), declared_game("connect_four")
    assert (four.rows, four.cols, four.k, four.gravity) == (4, 4, 4, False)
    assert (c4.rows, c4.cols, c4.k, c4.gravity, c4.cells) == (6, 7, 4, True, 42)
    assert len(c4.lines) == 69  # the known count of Connect Four's winning lines
    assert make_engine("connect_four").cells == 42


@pytest.mark.parametrize("text, message", [
    ("name: big\nrows: 10\ncols: 4\nk: 3\n", "rows must be an integer 3..9; got 10"),
    ("name: big\nrows: 4\ncols: 2\nk: 3\n", "cols must be an integer 3..9; got 2"),
    ("name: big\nrows: 4\ncols: 5\nk: 6\n", "k must be an integer 3..5; got 6"),
    ("name: big\nrows: 4\ncols: 5\nk: 3\ngravity: maybe\n", "gravity must be true or false; got 'maybe'"),
    ("name: Big Game\nrows: 4\ncols: 5\nk: 3\n", "name must be lower-case letters"),
    ("name: standard\nrows: 3\ncols: 3\nk: 3\n", "name 'standard' is a built-in game"),
    ("name: big\nrows: 4\ncols: 5\nk: 3\nsize: 4\n", "unknown field 'size'"),
    ("- 1\n- 2\n", "expected a mapping with the fields name, rows, cols, k, gravity"),
    ("name: [\n", "not valid YAML"),
])
def test_an_invalid_declaration_is_one_line_naming_the_field(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match="bad.yaml: .*" + message.replace("[", r"\[").replace("(", r"\(")) as error:
        load_declaration(path)
    assert "\n" not in str(error.value)


def test_a_game_is_a_built_in_a_shipped_name_or_a_file(tmp_path):
    path = tmp_path / "five_four.yaml"
    path.write_text("name: five_four\nrows: 5\ncols: 4\nk: 3\ngravity: true\n")
    game = make_game(str(path))
    assert (game.name, game.n_cells, game.gravity) == ("five_four", 20, True)
    with pytest.raises(ValueError, match=r"game must be one of standard, ultimate, connect_four, four, a game YAML file or an import path MODULE:CLASS / FILE\.py:CLASS; got 'chess'"):
        make_game("chess")
    with pytest.raises(ValueError, match="not found"):
        make_game(str(tmp_path / "missing.yaml"))


def test_cell_names_and_spoken_cells():
    game = make_game("connect_four")
    assert game.cell_name(0) == "a1" and game.cell_name(41) == "g6"
    for cell in range(42):
        assert game.parse_cell(game.cell_name(cell)) == cell
    for spoken in ("row two column three", "Row 2, column 3", "column three row two", "column c row 2"):
        assert game.parse_cell(spoken) == 9
    for bad in ("h1", "a7", "row seven column one", "row two row three", "column cat row 2"):
        with pytest.raises(ValueError, match="is not a cell of the connect_four board"):
            game.parse_cell(bad)


def test_gravity_refuses_a_floating_mark_with_the_square_it_drops_to():
    game = make_game("connect_four")
    s = game.play_many([38])
    with pytest.raises(ValueError, match="cell d1 .* is not the lowest empty square of column d: a mark drops to d5"):
        game.play(s, 3)
