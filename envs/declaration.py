"""A game declared once in a small YAML file: ``name``, ``rows``, ``cols``, ``k`` (marks in a line to win), ``gravity``.

Why a declaration: the paper claims its approach "can be easily extended to new games". Everything that depends on
the board -- exact rules, the batched engine, the dialogue env's features and actions, the example dialogues, the
opponents, the grid reader and the robot's drawing positions -- is derived from these five fields, so a new game is
a new file, not new code. 3x3 ("standard") and Ultimate stay built-ins; the game object of a declaration is
``ncbot.envs.games.declared.DeclaredGame``, resolved by the registry (``ncbot.envs.games``).

Plain Python (no torch).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import yaml

SHIPPED_DIR = Path(__file__).with_name("games")
BUILT_IN = ("standard", "ultimate")
MIN_SIDE, MAX_SIDE = 3, 9  # column letters a-i and one-digit row numbers name every cell
FIELDS = ("name", "rows", "cols", "k", "gravity")
_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")
DIRECTIONS = ((0, 1), (1, 0), (1, 1), (1, -1))  # horizontal, vertical, diagonal, anti-diagonal


@dataclass(frozen=True)
class Declaration:
    """One declared game. ``game`` is how the rest of ncbot names it: the shipped name, or the file's absolute path."""

    name: str
    rows: int
    cols: int
    k: int
    gravity: bool
    game: str

    @property
    def cells(self) -> int:
        return self.rows * self.cols

    @property
    def shape(self) -> str:
        """"ROWSxCOLS", as ``ncbot vision read --grid`` takes it."""
        return f"{self.rows}x{self.cols}"

    @property
    def lines(self) -> tuple[tuple[int, ...], ...]:
        """Every run of ``k`` cells (row-major indices) in the four directions: the lines that win."""
        return game_lines(self.rows, self.cols, self.k)

    def describe(self) -> str:
        drop = ", a mark drops to the lowest empty square of its column" if self.gravity else ""
        return f"{self.name}: {self.rows} rows x {self.cols} columns, {self.k} in a line wins{drop}"


@lru_cache(maxsize=None)
def game_lines(rows: int, cols: int, k: int) -> tuple[tuple[int, ...], ...]:
    """The winning lines of a rows x cols board with ``k`` in a line, horizontal first, then vertical, diagonals."""
    lines = []
    for dr, dc in DIRECTIONS:
        for r in range(rows):
            for c in range(cols):
                end_r, end_c = r + dr * (k - 1), c + dc * (k - 1)
                if 0 <= end_r < rows and 0 <= end_c < cols:
                    lines.append(tuple((r + dr * i) * cols + c + dc * i for i in range(k)))
    return tuple(lines)


def shipped_games() -> tuple[str, ...]:
    """Names of the declarations shipped in ``envs/games`` (sorted)."""
    return tuple(sorted(p.stem for p in SHIPPED_DIR.glob("*.yaml")))


def game_choices_text() -> str:
    """Every way to name a game, as error messages list them (``ncbot.envs.games``)."""
    return f"{', '.join(BUILT_IN + shipped_games())}, a game YAML file or an import path MODULE:CLASS / FILE.py:CLASS"


def _int_field(data: dict, field: str, low: int, high: int, where: str) -> int:
    value = data.get(field)
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise ValueError(f"{where}: {field} must be an integer {low}..{high}; got {value!r}")
    return value


def parse_declaration(data: object, where: str, game: str) -> Declaration:
    """The declaration in ``data`` (a YAML mapping); one-line ValueError naming the field and what is allowed."""
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a mapping with the fields {', '.join(FIELDS)}")
    unknown = sorted(str(key) for key in data if key not in FIELDS)
    if unknown:
        raise ValueError(f"{where}: unknown field {unknown[0]!r}; the fields are {', '.join(FIELDS)}")
    name = data.get("name")
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(f"{where}: name must be lower-case letters, digits and _ (a letter first, at most 32); got {name!r}")
    if name in BUILT_IN:
        raise ValueError(f"{where}: name {name!r} is a built-in game; choose another name")
    rows = _int_field(data, "rows", MIN_SIDE, MAX_SIDE, where)
    cols = _int_field(data, "cols", MIN_SIDE, MAX_SIDE, where)
    k = _int_field(data, "k", 3, max(rows, cols), where)
    gravity = data.get("gravity", False)
    if not isinstance(gravity, bool):
        raise ValueError(f"{where}: gravity must be true or false; got {gravity!r}")
    return Declaration(name, rows, cols, k, gravity, game)


def load_declaration(path: str | Path, game: str | None = None) -> Declaration:
    """The declaration in the YAML file ``path``; FileNotFoundError / ValueError (one line) if unusable."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"game file {path} not found: expected a YAML declaration (docs/games.md)")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise ValueError(f"{path}: not valid YAML ({str(error).splitlines()[0]})") from None
    return parse_declaration(data, str(path), game or str(path.resolve()))


def declared_game(game: object) -> Declaration:
    """The declaration of ``game``: a shipped name (``four``) or the path of a YAML file; ValueError otherwise."""
    if isinstance(game, str) and _NAME.fullmatch(game) and (SHIPPED_DIR / f"{game}.yaml").is_file():
        return _load_cached(str(SHIPPED_DIR / f"{game}.yaml"), game)
    if isinstance(game, (str, Path)) and str(game).endswith((".yaml", ".yml")):
        path = Path(game).resolve()
        if not path.is_file():
            raise ValueError(f"game file {game} not found: expected {game_choices_text()}")
        return _load_cached(str(path), str(path))
    raise ValueError(f"game must be one of {game_choices_text()}; got {game!r}")


@lru_cache(maxsize=64)
def _load_cached(path: str, game: str) -> Declaration:
    return load_declaration(path, game)
