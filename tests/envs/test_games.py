"""The one registry of games (``ncbot.envs.games``): names resolve to one game object, a game class loads by its import
path only where the user names it, and a bad class is one line naming what is wrong."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ncbot.envs import make_env
from ncbot.envs.games import BoardGame, check_game, load_game, make_game
from ncbot.envs.games.protocol import PROTOCOL_METHODS, Game

ROOT = Path(__file__).resolve().parents[2]
MISERE = ROOT / "docs" / "examples" / "misere.py"


def _ncbot(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True, timeout=300, cwd=cwd)


def _plugin(folder: Path, text: str, name: str = "game.py") -> Path:
    path = folder / name
    path.write_text("from ncbot.envs.games import BoardGame\nfrom ncbot.envs.core import DRAWN, EMPTY\n\n" + text)
    return path


def test_every_kind_of_name_resolves_to_one_game_object_with_the_whole_protocol() -> None:
    games = [make_game("standard"), make_game("ultimate", "open_subgrids"), make_game("four"),
             load_game(f"{MISERE}:Misere")]
    for game in games:
        assert isinstance(game, Game), game
        assert all(callable(getattr(game, method)) for method in PROTOCOL_METHODS)
        assert make_game(game.id, getattr(game, "free_move", "anywhere")) is game  # one object per id and rule
    assert [g.id for g in games[:3]] == ["standard", "ultimate", "four"]
    assert games[1].free_move == "open_subgrids" and games[1].subgrids == 9 and games[0].subgrids == 0
    assert [g.sheet_grid for g in games] == [3, 9, (4, 4), (3, 3)]


def test_an_import_path_is_canonical_and_imported_only_when_named(tmp_path: Path) -> None:
    path = _plugin(tmp_path, "class Tiny(BoardGame):\n    name = 'tiny'\n    rows = cols = 3\n"
                   "    def result(self, board, cell, mark):\n        return DRAWN if EMPTY not in board else 0\n")
    relative = Path("game.py")
    import os

    here = os.getcwd()
    try:
        os.chdir(tmp_path)
        assert check_game(f"{relative}:Tiny") == f"{path.resolve()}:Tiny"  # a file becomes its absolute path
    finally:
        os.chdir(here)
    assert check_game("my_pkg.games:Misere") == "my_pkg.games:Misere"  # a module path stays; nothing is imported
    with pytest.raises(ValueError, match=rf"^game {path.resolve()}:Tiny is code ncbot imports only when you name it: "
                                         rf"pass --game {path.resolve()}:Tiny"):
        make_game(f"{path}:Tiny")
    game = load_game(f"{path}:Tiny")
    assert make_game(f"{path}:Tiny") is game and game.id == f"{path.resolve()}:Tiny"
    env = make_env(game.id, batch_size=(4,), seed=0)  # named once in this process: every part finds it
    assert env.rules is game and env.n_actions == 18


@pytest.mark.parametrize("text, attribute, message", [
    ("raise RuntimeError('broken on purpose')\n", "Tiny", r"does not import: RuntimeError: broken on purpose"),
    ("def oops(:\n", "Tiny", r"does not import: SyntaxError"),
    ("x = 1\n", "Tiny", r"defines no 'Tiny'"),
    ("Tiny = 3\n", "Tiny", r"3 is not a class"),
    ("class Tiny:\n    name = 'tiny'\n    def new(self): pass\n", "Tiny", r"lacks the protocol method 'legal'"),
    ("class Tiny(BoardGame):\n    name = 'tiny'\n    rows, cols = 0, 3\n", "Tiny", r"rows must be a positive integer"),
    ("class Tiny(BoardGame):\n    def __init__(self):\n        raise KeyError('x')\n", "Tiny", r"Tiny\(\) failed: KeyError"),
])
def test_a_bad_game_class_is_one_line_naming_what_is_wrong(tmp_path: Path, text: str, attribute: str, message: str) -> None:
    path = _plugin(tmp_path, text)
    with pytest.raises(ValueError, match=message):
        load_game(f"{path}:{attribute}")


def test_bad_import_paths_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"game file .*missing\.py not found"):
        load_game(f"{tmp_path}/missing.py:Game")
    with pytest.raises(ValueError, match=r"does not import: ModuleNotFoundError: No module named 'no_such_pkg'"):
        load_game("no_such_pkg.games:Game")
    with pytest.raises(ValueError, match=r"an import path is MODULE:CLASS or PATH\.py:CLASS"):
        load_game("games.py:1abc")


def test_the_cli_refuses_a_bad_game_in_one_line_with_exit_2(tmp_path: Path) -> None:
    path = _plugin(tmp_path, "class Half(BoardGame):\n    name = 'half'\n    rows = cols = 3\n    engine = None\n")
    for args, message in (
        (["env", "describe", "--game", f"{path}:Half"], "lacks the protocol method 'engine'"),
        (["env", "describe", "--game", f"{tmp_path}/gone.py:Game"], "gone.py not found"),
        (["train", "default", f"env.game={path}:Half", "--out", str(tmp_path / "run")], "lacks the protocol method 'engine'"),
    ):
        result = _ncbot(*args)
        assert result.returncode == 2, (args, result.stderr[-500:])
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("ncbot: error: ") and message in lines[0], (args, lines)


def test_a_board_the_sheet_cannot_draw_is_one_line(tmp_path: Path) -> None:
    path = _plugin(tmp_path, "class Wide(BoardGame):\n    name = 'wide'\n    rows, cols = 4, 12\n"
                   "    def result(self, board, cell, mark):\n        return DRAWN if EMPTY not in board else 0\n")
    result = _ncbot("vision", "generate", "frames", "--game", f"{path}:Wide", "--out", str(tmp_path / "frames"))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "ncbot: error: game 'wide' has a 4x12 board: the sheet, the reader and the robot draw 3x3, Ultimate's 9x9 or "
        "plain grids of 3..9 rows and columns"]
    from ncbot.robot_sim.scene import sheet_grid  # the robot's sheet refuses it in the same words

    load_game(f"{path}:Wide")
    with pytest.raises(ValueError, match="'wide' has a 4x12 board"):
        sheet_grid(f"{path.resolve()}:Wide")


def test_a_game_object_goes_where_a_name_goes() -> None:
    misere = load_game(f"{MISERE}:Misere")
    fresh = type(misere)()
    env = make_env(fresh, batch_size=(2,), seed=1)
    assert env.rules is fresh and env.game == f"{type(fresh).__module__}:Misere"
    assert isinstance(fresh, BoardGame) and fresh.describe().startswith("Misère noughts and crosses")
