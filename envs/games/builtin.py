"""The two built-in games, Noughts & Crosses (``standard``) and Ultimate (``ultimate``): their exact rules
(``ncbot.envs.rules``) with the fast parts behind the ``Game`` protocol.

Why their own parts: 3x3 answers every question with one gather from the 3^9 board codes, and Ultimate's look-ahead of
81 moves works on bitmasks of subgrids; both search on bitboards and read threats from line tables. These are the
parts that make the paper's training runs fast, and they give the numbers ``bench/env_fingerprint.py`` records.
"""
from __future__ import annotations

from pathlib import Path

import torch
import yaml

from ncbot.envs.games.board_game import BoardGame
from ncbot.envs.games.symmetries import square_symmetries
from ncbot.envs.opponents.lines import subgrid_owners, subgrid_taking_cells, winning_cells
from ncbot.envs.readings import Readings
from ncbot.envs.rules import Standard, Ultimate

DATA_DIR = Path(__file__).resolve().parents[1] / "data"


class BuiltInGame(BoardGame):
    """What both built-ins share: their example dialogues are hand-made data (``envs/data``), not generated."""

    def example_dialogues(self, file_name: str) -> list[dict]:
        """This game's dialogues in the set's file (FileNotFoundError / ValueError if unusable)."""
        path = DATA_DIR / file_name
        if not path.is_file():
            raise FileNotFoundError(f"example dialogue file {path} not found: expected the YAML shipped in envs/data")
        data = yaml.safe_load(path.read_text())
        if not isinstance(data, dict) or not isinstance(data.get("dialogues"), list):
            raise ValueError(f"{path}: expected a mapping with a 'dialogues' list")
        chosen = [d for d in data["dialogues"] if d.get("game") == self.name]
        if not chosen:
            raise ValueError(f"{path}: no dialogues for game {self.name!r}")
        return chosen

    def symmetries(self) -> torch.Tensor:
        return square_symmetries(self.rows)

    def threat_names(self) -> list[str]:
        from ncbot.envs.threat_features import threat_names

        return threat_names(self.n_cells)


class StandardGame(BuiltInGame, Standard):
    """Noughts and crosses: three in a row, column or diagonal wins."""

    sheet_grid = 3
    title = "noughts and crosses"
    openspiel_name = "tic_tac_toe"

    def engine(self, readings: Readings = Readings()):
        from ncbot.envs.engine.standard import StandardEngine

        return StandardEngine(readings)

    def search_engine(self):
        from ncbot.envs.opponents.bitboards import StandardBits

        return StandardBits()

    def solver(self):
        from ncbot.envs.opponents.minimax_table import NoughtsCrossesSolver

        return NoughtsCrossesSolver()

    def winning_cells(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        return winning_cells(boards, player)

    def rule_scores(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        """2 a cell that wins, 1 a cell that blocks the other side's line."""
        return 2 * winning_cells(boards, player).long() + winning_cells(boards, 3 - player).long()

    def threat_planes(self, board: torch.Tensor, owners: torch.Tensor | None = None) -> torch.Tensor:
        from ncbot.envs.threat_features import threat_planes

        return threat_planes(board)


class UltimateGame(BuiltInGame, Ultimate):
    """Ultimate: win three small boards in a row; your move sends the robot to the matching small board."""

    sheet_grid = 9
    subgrids = 9
    title = "ultimate noughts and crosses"
    openspiel_name = "ultimate_tic_tac_toe"

    def engine(self, readings: Readings = Readings()):
        from ncbot.envs.engine.ultimate import UltimateEngine

        return UltimateEngine(self.free_move, readings)

    def search_engine(self):
        from ncbot.envs.opponents.bitboards import UltimateBits

        return UltimateBits(self.free_move)

    def solver(self) -> None:
        return None  # 3^81 boards: too large to solve

    def winning_cells(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        return winning_cells(boards, player, owners)

    def rule_scores(self, boards: torch.Tensor, player: int, owners: torch.Tensor | None = None) -> torch.Tensor:
        """The rule at two levels, in this order: win the game, block a game-winning cell of the other side, take a
        subgrid, block the other side taking a subgrid."""
        other = 3 - player
        owners = subgrid_owners(boards) if owners is None else owners
        takes_mine = subgrid_taking_cells(boards, player, owners)
        takes_theirs = subgrid_taking_cells(boards, other, owners)
        return (8 * winning_cells(boards, player, owners, takes_mine).long()
                + 4 * winning_cells(boards, other, owners, takes_theirs).long()
                + 2 * takes_mine.long() + takes_theirs.long())

    def threat_planes(self, board: torch.Tensor, owners: torch.Tensor | None = None) -> torch.Tensor:
        from ncbot.envs.threat_features import threat_planes

        return threat_planes(board, owners)

    def __repr__(self) -> str:
        return f"UltimateGame(free_move={self.free_move!r})"
