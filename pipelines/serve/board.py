"""What the page needs to draw and play a game's board, derived from the game's rules (never per-game page code).

Why the server hands this over instead of the page knowing the games: a declared game (`ncbot.envs.declaration`)
has any rows x cols, may drop marks into columns, and names its squares as its rules do (`b3`, as the dialogue
and every error message write them); the page reads it all from one JSON object.
"""
from __future__ import annotations

import json
from typing import Any


BUILT_IN_TITLES = {"standard": "noughts and crosses", "ultimate": "ultimate noughts and crosses"}


def board_layout(game: str) -> dict[str, Any]:
    """{kind, name, title, rows, cols, gravity, names, rules} of `game` (standard, ultimate or a declared game's
    id); title: what the page's heading calls it."""
    from ncbot.envs.rules import make_game

    rules = make_game(game)
    declaration = getattr(rules, "declaration", None)
    if declaration is None:
        rows = cols = rules.size
        kind, gravity = rules.name, False
        text = ("Noughts and crosses: three in a row, column or diagonal wins" if kind == "standard" else
                "Ultimate: win three small boards in a row; your move sends the robot to the matching small board")
    else:
        rows, cols, kind, gravity = declaration.rows, declaration.cols, "declared", declaration.gravity
        text = declaration.describe()
        if gravity:
            text += ": click anywhere in a column"
    title = BUILT_IN_TITLES.get(kind, rules.name.replace("_", " "))
    return {"kind": kind, "name": rules.name, "title": title, "rows": rows, "cols": cols, "gravity": gravity,
            "names": [rules.cell_name(cell) for cell in range(rows * cols)], "rules": text + "."}


def layout_script(game: str) -> str:
    """The layout as a JavaScript literal safe inside a <script> element."""
    return json.dumps(board_layout(game)).replace("<", "\\u003c")


def column_drop(cell: int, legal: list[int], cols: int) -> int | None:
    """Gravity: the cell a click anywhere in `cell`'s column plays (its lowest empty square), None when full."""
    return next((c for c in legal if c % cols == cell % cols), None)
