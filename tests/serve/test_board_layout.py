"""The page's board, derived from a game's rules (pipelines/serve/board.py): sizes, names, heading, column drops."""
from __future__ import annotations

import json

import pytest

from ncbot.pipelines.serve.board import board_layout, column_drop, layout_script


@pytest.mark.parametrize("game, rows, cols, gravity, title", [
    ("standard", 3, 3, False, "noughts and crosses"), ("ultimate", 9, 9, False, "ultimate noughts and crosses"),
    ("four", 4, 4, False, "four"), ("connect_four", 6, 7, True, "connect four")])
def test_layout_follows_the_rules(game: str, rows: int, cols: int, gravity: bool, title: str) -> None:
    layout = board_layout(game)
    assert (layout["rows"], layout["cols"], layout["gravity"], layout["title"]) == (rows, cols, gravity, title)
    assert len(layout["names"]) == rows * cols == len(set(layout["names"]))  # every square has its own name
    assert json.loads(layout_script(game)) == layout


def test_a_column_click_plays_the_lowest_empty_square_or_none_when_full() -> None:
    cols = 7
    legal = [35, 29, 37]  # column 0's lowest empty square is 35 (row 5), column 1's is 29 (row 4), column 2's 37
    assert column_drop(1, legal, cols) == 29 and column_drop(8, legal, cols) == 29  # anywhere in column 1
    assert column_drop(0, legal, cols) == 35 and column_drop(3, legal, cols) is None  # column 3 is full


def test_the_layout_script_cannot_close_the_script_element(tmp_path) -> None:
    declared = tmp_path / "tag.yaml"
    declared.write_text("name: x</script>\nrows: 3\ncols: 4\nk: 3\ngravity: false\n")
    with pytest.raises(ValueError):  # a declaration's name is checked before it reaches the page
        board_layout(str(declared))
