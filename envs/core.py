"""The game's shared vocabulary, defined once: board geometry, mark and seat codes, outcome codes, rewards.

Why one module: four rule implementations (``ncbot.envs.rules`` the reference, ``ncbot.envs.engine`` the batched env engine,
``ncbot.envs.opponents.bitboards`` the search engine, ``ncbot.envs.opponents.lines`` the batched line arithmetic) and the
layers above (rewards, evaluation, logs) must agree on what cell 40 is, which subgrid it sends the opponent to
and what outcome code 2 means. Plain Python only (no torch), so every layer can import it for free.

Cells are numbered ``row * size + col`` on the full grid (size 3 or 9). Ultimate subgrids are numbered the same
way (``subgrid = (row // 3) * 3 + col // 3``); a move on position ``(row % 3) * 3 + col % 3`` of its subgrid sends
the opponent to the subgrid with that number.
"""
from __future__ import annotations

FREE_MOVE_CHOICES = ("anywhere", "open_subgrids")
COLUMN_LETTERS = "abcdefghijklmnopqrstuvwxyz"  # cell names: a column letter, then the row number

# Mark codes on a board. In the rules x / o (x moves first); in the env and the opponents the seats.
EMPTY, X, O = 0, 1, 2
ROBOT, HUMAN = 1, 2  # the env's board codes of the two seats, whoever opens
USER = HUMAN  # the dialogue env's simulated user sits in the human seat
SEATS = {ROBOT: "robot", HUMAN: "human"}
DRAWN = 3  # a drawn subgrid (Ultimate owner grid), and a drawn game in the outcome codes below

# The paper's ambiguous readings (taken_squares, win_set, about_to, ...) are ``ncbot.envs.readings``.

# Who opens a dialogue's game: the one name ``first`` (env option, config key, CLI option).
FIRST_CHOICES = ("robot", "human", "alternate", "random")

# Outcome codes of a game, from the robot's seat (the env's ``outcome`` key, the engines' ``outcome`` tensor).
OUTCOME_NONE, OUTCOME_ROBOT_WON, OUTCOME_HUMAN_WON, OUTCOME_DRAW = 0, ROBOT, HUMAN, DRAWN
OUTCOME_NAMES = ("none", "win", "loss", "draw")  # indexed by outcome code: the robot's view (logs, reports)

# The paper's one-step rewards (section 3): win / about to win, draw / about to draw, lose / about to lose,
# and a repeated (already taken) move, which the env applies to every refused act.
REWARD_WIN, REWARD_DRAW, REWARD_LOSE, REWARD_ILLEGAL = 5.0, 1.0, -5.0, -5.0

# The 8 lines of a 3x3 grid as cell indices 0..8 (rows, columns, diagonals).
LINES_3X3: tuple[tuple[int, int, int], ...] = (
    (0, 1, 2), (3, 4, 5), (6, 7, 8),
    (0, 3, 6), (1, 4, 7), (2, 5, 8),
    (0, 4, 8), (2, 4, 6),
)


def subgrid_cells(subgrid: int) -> tuple[int, ...]:
    """The 9 full-grid cells (row-major inside the subgrid) of Ultimate subgrid ``subgrid``."""
    top, left = (subgrid // 3) * 3, (subgrid % 3) * 3
    return tuple((top + r) * 9 + left + c for r in range(3) for c in range(3))


SUBGRID_CELLS: tuple[tuple[int, ...], ...] = tuple(subgrid_cells(k) for k in range(9))
# cell -> the subgrid it lies in, and cell -> its position inside that subgrid = the subgrid it sends the opponent to.
SUBGRID_OF_CELL: tuple[int, ...] = tuple((cell // 27) * 3 + (cell % 9) // 3 for cell in range(81))
TARGET_OF_CELL: tuple[int, ...] = tuple(((cell // 9) % 3) * 3 + (cell % 9) % 3 for cell in range(81))


def check_free_move(free_move: str) -> str:
    """``free_move`` if it is one of FREE_MOVE_CHOICES; ValueError naming the choices otherwise."""
    if free_move not in FREE_MOVE_CHOICES:
        raise ValueError(f"free_move must be one of {', '.join(FREE_MOVE_CHOICES)}; got {free_move!r}")
    return free_move
