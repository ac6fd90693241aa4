"""The one registry of games: every name a game is given by resolves here to one ``Game`` object (``protocol.py``).

A game is named by
- a built-in name: ``standard`` (3x3), ``ultimate``;
- a declaration: a shipped name (``four``, ``connect_four``: the YAML files beside this module) or a YAML file;
- an import path of a class: ``my_pkg.games:Misere`` or ``path/to/file.py:Misere`` (docs/games.md "Write your own
  game"). Such a class is code, so it is imported only where the user names it (``load_game``: the config or command
  line of the command they run); a run folder, checkpoint or log that records it names it by this path, and loading
  one never imports it: ``make_game`` asks for the path to be named again with one line.

Why one registry: every part of the stack asks its game object, never the game's name, so a new game is one class
(or one YAML file) and these functions are the only place that knows the names.
"""
from __future__ import annotations

import inspect
from typing import Any

from ncbot.envs.core import check_free_move
from ncbot.fileio.import_path import absolute_import_path, import_object
from ncbot.envs.declaration import BUILT_IN, declared_game, game_choices_text  # noqa: F401  (re-exported)
from ncbot.envs.games.protocol import Game, PROTOCOL_ATTRIBUTES, PROTOCOL_METHODS

_GAMES: dict[tuple[str, str], Game] = {}  # (id, free_move) -> the game object
_NAMED: dict[str, type] = {}  # import paths the user named in this process -> the class they import


def is_import_path(game: object) -> bool:
    """``MODULE:CLASS`` or ``PATH.py:CLASS``: a game given as code."""
    return isinstance(game, str) and ":" in game and not game.endswith((".yaml", ".yml"))


def check_game(game: object) -> str:
    """The id of ``game`` (how configs and checkpoints name it) without importing any code: a built-in or shipped
    name as it is, a YAML file's or a Python file's absolute path. One-line ValueError naming the choices otherwise."""
    if isinstance(game, str) and game in BUILT_IN:
        return game
    if is_import_path(game):
        return _plugin_id(game)
    return declared_game(game).game  # a shipped name or a YAML file; ValueError naming the choices otherwise


def make_game(game: Any = "standard", free_move: str = "anywhere") -> Game:
    """The game object of ``game`` (an id, or a ``Game`` object: registered under its id and returned); one per id
    and rule. An import path the user did not name in this process is a one-line ValueError saying to name it."""
    free_move = check_free_move(free_move)
    if not isinstance(game, str):
        return _register_object(game)
    game = check_game(game)
    key = (game, free_move)
    if key not in _GAMES:
        _GAMES[key] = _build(game, free_move)
    return _GAMES[key]


def load_game(game: Any, free_move: str = "anywhere") -> Game:
    """``make_game`` for a game the user named (their config or command line): an import path is imported here, and
    its class checked against the protocol (one line naming what is wrong); nothing is imported for other names."""
    if is_import_path(game):
        game_id = check_game(game)
        if game_id not in _NAMED:
            _NAMED[game_id] = _import_class(game_id)
    return make_game(game, free_move)


def built_in_of_cells(cells: int) -> str:
    """The built-in game with ``cells`` squares ("" if none): what a board of unknown origin most likely shows."""
    return next((name for name in BUILT_IN if make_game(name).n_cells == cells), "")


def named_games() -> tuple[str, ...]:
    """The import paths the user named in this process: what a worker process it starts names again."""
    return tuple(_NAMED)


def _build(game: str, free_move: str) -> Game:
    if game in BUILT_IN:
        from ncbot.envs.games.builtin import StandardGame, UltimateGame

        built = StandardGame() if game == BUILT_IN[0] else UltimateGame(free_move)
    elif is_import_path(game):
        if game not in _NAMED:
            raise ValueError(f"game {game} is code ncbot imports only when you name it: pass --game {game} (or "
                             f"env.game={game}) to the command; in Python, ncbot.envs.games.load_game({game!r})")
        built = _instantiate(_NAMED[game], free_move)
    else:
        from ncbot.envs.games.declared import DeclaredGame

        return DeclaredGame(declared_game(game))
    built.id = game
    return built


def _register_object(game: Any) -> Game:
    """A game object handed in (the Python API): checked, registered under its id, returned."""
    _check_class(type(game), f"{type(game).__module__}:{type(game).__qualname__}")
    game_id = getattr(game, "id", None) or f"{type(game).__module__}:{type(game).__qualname__}"
    _NAMED.setdefault(game_id, type(game))
    _GAMES[(game_id, getattr(game, "free_move", "anywhere"))] = game
    return game


def _plugin_id(game: str) -> str:
    """``MODULE:CLASS`` as it is; ``PATH.py:CLASS`` with the file's absolute path."""
    return absolute_import_path(game, "game")


def _import_class(game: str) -> type:
    """The class an import path names, imported now; one-line ValueError for a module or file that does not import,
    a missing class, or a class that lacks part of the protocol."""
    cls = import_object(game, "game")
    _check_class(cls, game)
    return cls


def _check_class(cls: Any, game: str) -> None:
    if not inspect.isclass(cls):
        raise ValueError(f"game {game}: {cls!r} is not a class")
    for method in PROTOCOL_METHODS:
        if not callable(getattr(cls, method, None)):
            raise ValueError(f"game class {cls.__name__} ({game}) lacks the protocol method {method!r} "
                             "(subclass ncbot.envs.games.BoardGame, docs/games.md \"Write your own game\")")


def _instantiate(cls: type, free_move: str) -> Game:
    """``cls()`` (or ``cls(free_move=...)`` when it takes the rule variant), its attributes checked."""
    try:
        game = cls(free_move=free_move) if "free_move" in inspect.signature(cls).parameters else cls()
    except Exception as error:  # noqa: BLE001 - a user's constructor may raise anything
        raise ValueError(f"game class {cls.__name__}() failed: {type(error).__name__}: {error}") from None
    for attribute in PROTOCOL_ATTRIBUTES:
        if not hasattr(game, attribute):
            raise ValueError(f"game class {cls.__name__} lacks the protocol attribute {attribute!r} (docs/games.md)")
    if not isinstance(game.name, str) or not game.name:
        raise ValueError(f"game class {cls.__name__}: name must be a non-empty string, got {game.name!r}")
    for side in ("rows", "cols"):
        value = getattr(game, side)
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"game class {cls.__name__}: {side} must be a positive integer, got {value!r}")
    return game


from ncbot.envs.games.board_game import BoardGame  # noqa: E402  (the base class users subclass)

__all__ = ["BUILT_IN", "BoardGame", "Game", "built_in_of_cells", "check_game", "game_choices_text", "is_import_path", "load_game", "make_game",
           "named_games"]
