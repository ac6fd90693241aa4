"""What the page needs to draw and play a game's board, derived from the game's rules (never per-game page code).

Why the server hands this over instead of the page knowing the games: a game (`ncbot.envs.games`) has any rows x cols, may drop marks into columns, and names its squares as its rules do (`b3`, as the dialogue
and every error message write them); the page reads it all from one JSON object.
"""
from __future__ import annotations

import json
from typing import Any


KINDS = {3: "standard", 9: "ultimate"}  # how the page draws a grid: 3x3, Ultimate's subgrids, else a labelled grid


def board_layout(game: str) -> dict[str, Any]:
    """{kind, name, title, rows, cols, gravity, names, rules} of `game` (its id); kind: how the page draws the grid
    (standard, ultimate, declared: a plain labelled grid); title: what the page's heading calls it."""
    from ncbot.envs.games import make_game

    rules = make_game(game)
    kind = KINDS.get(rules.sheet_grid, "declared")
    text = rules.describe() + (": click anywhere in a column" if rules.gravity else "")
    return {"kind": kind, "name": rules.name, "title": rules.title, "rows": rules.rows, "cols": rules.cols,
            "gravity": rules.gravity, "names": [rules.cell_name(cell) for cell in range(rules.n_cells)],
            "rules": text + "."}


def layout_script(game: str) -> str:
    """The layout as a JavaScript literal safe inside a <script> element."""
    return json.dumps(board_layout(game)).replace("<", "\\u003c")


def column_drop(cell: int, legal: list[int], cols: int) -> int | None:
    """Gravity: the cell a click anywhere in `cell`'s column plays (its lowest empty square), None when full."""
    return next((c for c in legal if c % cols == cell % cols), None)
