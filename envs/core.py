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

GAME_CHOICES = ("standard", "ultimate")
FREE_MOVE_CHOICES = ("anywhere", "open_subgrids")
CELLS_OF_GAME = {"standard": 9, "ultimate": 81}
COLUMN_LETTERS = "abcdefghi"

# Mark codes on a board. In the rules x / o (x moves first); in the env and the opponents the seats.
EMPTY, X, O = 0, 1, 2
ROBOT, HUMAN = 1, 2  # the env's board codes of the two seats, whoever opens
USER = HUMAN  # the dialogue env's simulated user sits in the human seat
SEATS = {ROBOT: "robot", HUMAN: "human"}
DRAWN = 3  # a drawn subgrid (Ultimate owner grid), and a drawn game in the outcome codes below

# The paper's ambiguous readings, each a named option (first value = the default; docs/env.md "Readings").
# taken_squares: can the robot choose a square that is taken? Section 3: "all game moves were allowed from the
#   subset of those not taken yet (to the robot's knowledge)", yet the rewards price "a repeated (already taken)
#   action" at -5. never: only untaken squares are offered; refused: taken squares are offered too, refused at -5
#   with nothing changed; misread: the robot's knowledge of the board can be wrong (a misread user move), a square
#   really taken is refused at -5 and the refusal corrects the robot's knowledge; offered: misread, and every
#   square the robot knows is taken is offered too (the -5 payable to an agent without look-ahead masks).
TAKEN_SQUARES_CHOICES = ("never", "refused", "misread", "offered")
BELIEF_READINGS = ("misread", "offered")  # the readings that keep a believed board beside the true one
# win_set: what ``winning_actions`` (Algorithm 2's set A when non-empty) holds. wins_and_threats: every +5 move
#   (wins and "about to win" threats); wins: "action(s) leading to win (legally) the game", the moves that win now.
WIN_SET_CHOICES = ("wins_and_threats", "wins")
# about_to: when "+5 ... about to win" is paid. standing: on every move after which the robot has a winning
#   square; created: only on the move that creates it (the robot had no winning square before its move).
ABOUT_TO_CHOICES = ("standing", "created")

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


def check_game(game: str) -> str:
    """``game`` if it is one of GAME_CHOICES; else the id of a declared game (a shipped name, or a YAML file's
    absolute path: ``ncbot.envs.declaration``); one-line ValueError naming the choices otherwise."""
    if game in GAME_CHOICES:
        return game
    from ncbot.envs.declaration import declared_game

    return declared_game(game).game


def cells_of_game(game: str) -> int:
    """The number of squares of ``game`` (built-in or declared)."""
    if game in CELLS_OF_GAME:
        return CELLS_OF_GAME[game]
    from ncbot.envs.declaration import declared_game

    return declared_game(game).cells


def check_choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    """``value`` if it is one of ``choices``; one-line ValueError naming the option ``name`` and the choices."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(choices)}; got {value!r}")
    return value


def check_free_move(free_move: str) -> str:
    """``free_move`` if it is one of FREE_MOVE_CHOICES; ValueError naming the choices otherwise."""
    if free_move not in FREE_MOVE_CHOICES:
        raise ValueError(f"free_move must be one of {', '.join(FREE_MOVE_CHOICES)}; got {free_move!r}")
    return free_move
