"""OpenSpiel's own bots as opponents (``openspiel-mcts:N``), refereed by our rules.

Why: a strength figure against someone else's search is only worth something if it is *their* search on *their*
game, not our re-implementation. So the bot plays OpenSpiel's ``tic_tac_toe`` / ``ultimate_tic_tac_toe`` with
OpenSpiel's ``MCTSBot`` (random-rollout evaluator, one rollout, ``uct_c`` = 2 as in OpenSpiel's
``examples/mcts.py``, MCTS-Solver on), and every move crosses the border twice:

- the other side's move (from the caller's board) is applied to the bot's OpenSpiel state and must be legal
  there; the set of legal squares OpenSpiel sees must equal the caller's legal mask (our rules) before every
  decision; the bot's square must be legal in our rules. Any disagreement raises ValueError at once.
- OpenSpiel's Ultimate splits a free move in two decisions of the same player (choose a subgrid, then a square;
  9 distinct actions); the bot searches both with N simulations each. A forced move is one decision.

OpenSpiel's Ultimate lets a player sent to a decided subgrid choose any *undecided* subgrid: our
``free_move="open_subgrids"``. Under our paper rule (``anywhere``) it is refused with one line. The equivalence
of the rules is tested by playing random games through both engines (tests/envs/test_openspiel.py).

The bot only sees boards, so it follows each game move by move: after its own move it remembers the OpenSpiel
history under the resulting board, and the next call finds it by removing the other side's last mark. A position
it did not see arise raises ValueError. ``open_spiel`` is an optional dependency (``pip install 'ncbot[openspiel]'``).
"""
from __future__ import annotations

from typing import Any

import torch

from ncbot.envs.core import SUBGRID_CELLS, SUBGRID_OF_CELL, TARGET_OF_CELL
from ncbot.envs.games import make_game
from ncbot.envs.opponents.base import Opponent, register_opponent, simulation_count

OPENSPIEL_FREE_MOVE = "open_subgrids"  # OpenSpiel's Ultimate: sent to a decided subgrid -> any undecided one
DEFAULT_UCT_C = 2.0  # OpenSpiel's examples/mcts.py --uct_c default (MCTSBot itself requires the argument)
_ULTIMATE_FREE_CHOICE = 253  # observation tensor: 243 board planes, current player, 9 forced boards, free choice
_MAX_REMEMBERED = 200_000  # positions remembered across games before the memory is cleared


def import_pyspiel() -> Any:
    """The ``pyspiel`` module, or ValueError saying how to install the optional dependency."""
    try:
        import pyspiel
    except ImportError:
        raise ValueError("OpenSpiel opponents need the optional package open_spiel: "
                         "pip install 'ncbot[openspiel]' (or pip install open_spiel)") from None
    return pyspiel


def openspiel_name(game: str) -> str:
    """The name of OpenSpiel's version of ``game`` (``Game.openspiel_name``); ValueError when it has none."""
    name = getattr(make_game(game), "openspiel_name", None)
    if name is None:
        raise ValueError(f"OpenSpiel has no version of the game {game!r}: use 'mcts:N'")
    return name


def load_openspiel_game(game: str, free_move: str) -> Any:
    """OpenSpiel's version of our game, or ValueError when its rule is not ours (Ultimate under ``anywhere``) or it
    has none (a declared game)."""
    name = openspiel_name(game)
    if getattr(make_game(game, free_move), "free_move", OPENSPIEL_FREE_MOVE) != OPENSPIEL_FREE_MOVE:
        raise ValueError(f"OpenSpiel's {name} uses the '{OPENSPIEL_FREE_MOVE}' rule, not '{free_move}': "
                         f"play it with --free-move {OPENSPIEL_FREE_MOVE} (an agent trained on that rule)")
    return import_pyspiel().load_game(name)


def _split(game: str) -> bool:
    """OpenSpiel plays a move of a game with subgrids (Ultimate) as a subgrid, then a square inside it."""
    return make_game(game).subgrids > 0


def choosing_subgrid(state: Any) -> bool:
    """Ultimate: True when the player to move first chooses a subgrid (a free move), False when it is forced."""
    return state.observation_tensor(state.current_player())[_ULTIMATE_FREE_CHOICE] == 1.0


def cell_of(game: str, subgrid: int, square: int) -> int:
    """Our cell of OpenSpiel's (local board, local cell) pair on Ultimate."""
    return SUBGRID_CELLS[subgrid][square] if _split(game) else square


def legal_cells(state: Any, game: str) -> list[int]:
    """Our cells the player to move may take in an OpenSpiel state (a free Ultimate move: over every subgrid)."""
    if state.is_terminal():
        return []
    if not _split(game):
        return sorted(state.legal_actions())
    if choosing_subgrid(state):
        return sorted(cell_of(game, k, p) for k in state.legal_actions() for p in state.child(k).legal_actions())
    subgrid = forced_subgrid(state)
    return sorted(cell_of(game, subgrid, p) for p in state.legal_actions())


def forced_subgrid(state: Any) -> int:
    """Ultimate: the subgrid a forced move is played in (the observation's forced-board one-hot)."""
    observation = state.observation_tensor(state.current_player())
    return observation[244:253].index(1.0)


def apply_cell(state: Any, game: str, cell: int) -> list[int]:
    """Play our ``cell`` in an OpenSpiel state (in place); the OpenSpiel actions taken. ValueError if OpenSpiel refuses."""
    if not _split(game):
        actions = [cell]
    elif choosing_subgrid(state):
        actions = [SUBGRID_OF_CELL[cell], TARGET_OF_CELL[cell]]
    else:
        actions = [TARGET_OF_CELL[cell]] if forced_subgrid(state) == SUBGRID_OF_CELL[cell] else [-1]
    for action in actions:
        if state.is_terminal() or action not in state.legal_actions():
            raise ValueError(f"OpenSpiel's {openspiel_name(game)} refuses cell {cell}, which our rules allow: the rules differ")
        state.apply_action(action)
    return actions


class OpenSpielOpponent(Opponent):
    """An OpenSpiel decision maker in our batched interface; subclasses implement ``decide`` (one OpenSpiel action)."""

    name = "openspiel"

    def __init__(self, game: str = "standard", free_move: str = "anywhere", seed: int = 0) -> None:
        super().__init__(game, free_move, seed)
        self.pyspiel = import_pyspiel()
        self.os_game = load_openspiel_game(self.game, self.free_move)
        self._histories: dict[tuple[int, ...], list[list[int]]] = {}  # board after its own move -> OpenSpiel histories

    def decide(self, state: Any, seed: int) -> int:
        """One OpenSpiel action for the player to move in ``state`` (chance: ``seed`` alone)."""
        raise NotImplementedError

    def _select(self, boards, last_move, legal, player, generator, owners):
        cells = torch.zeros(boards.shape[0], dtype=torch.long)
        seeds = torch.randint(0, 2**31 - 1, (boards.shape[0],), generator=generator).tolist()
        board_rows, last_moves, legal_rows = boards.tolist(), last_move.tolist(), legal.tolist()
        if len(self._histories) > _MAX_REMEMBERED:
            self._histories.clear()
        for row in torch.nonzero(legal.any(dim=1)).flatten().tolist():
            state = self._follow(board_rows[row], last_moves[row])
            ours = [cell for cell, ok in enumerate(legal_rows[row]) if ok]
            if legal_cells(state, self.game) != ours:
                raise ValueError(f"{self.name}: OpenSpiel's legal cells {legal_cells(state, self.game)} differ from ours "
                                 f"{ours} on this position: the rules differ")
            cell = self._play_one_move(state, seeds[row])
            if not legal_rows[row][cell]:
                raise ValueError(f"{self.name} chose cell {cell}, which our rules forbid here: the rules differ")
            after = list(board_rows[row])
            after[cell] = player
            self._histories.setdefault(tuple(after), []).append(list(state.history()))
            cells[row] = cell
        return cells

    def _play_one_move(self, state: Any, seed: int) -> int:
        """Decide and play one move of ours in ``state`` (Ultimate, free: a subgrid, then a square); our cell."""
        if not _split(self.game):
            action = self.decide(state, seed)
            state.apply_action(action)
            return action
        if choosing_subgrid(state):
            subgrid = self.decide(state, seed)
            state.apply_action(subgrid)
            seed += 1
        else:
            subgrid = forced_subgrid(state)
        square = self.decide(state, seed)
        state.apply_action(square)
        return cell_of(self.game, subgrid, square)

    def _follow(self, board: list[int], last_move: int) -> Any:
        """The OpenSpiel state of ``board``: a remembered history plus the other side's last move."""
        state = self.os_game.new_initial_state()
        if last_move < 0:
            if any(board):
                raise ValueError(f"{self.name}: a board with marks but no last move cannot be followed")
            return state
        before = list(board)
        before[last_move] = 0
        if not any(before):
            apply_cell(state, self.game, last_move)
            return state
        candidates = self._histories.get(tuple(before), [])
        for index, history in enumerate(candidates):
            state = self.os_game.new_initial_state()
            for action in history:
                state.apply_action(action)
            try:
                apply_cell(state, self.game, last_move)
            except ValueError:
                continue
            candidates.pop(index)
            return state
        raise ValueError(f"{self.name} was handed a position it did not see arise (last move {last_move}): "
                         "an OpenSpiel opponent follows its games move by move")


class OpenSpielMCTSOpponent(OpenSpielOpponent):
    """``openspiel-mcts:N``: OpenSpiel's ``MCTSBot`` with N simulations per decision and random rollouts."""

    def __init__(self, simulations: int, game: str = "standard", free_move: str = "anywhere", seed: int = 0,
                 uct_c: float = DEFAULT_UCT_C) -> None:
        super().__init__(game, free_move, seed)
        if simulations < 1:
            raise ValueError(f"openspiel-mcts needs at least 1 simulation, got {simulations}")
        self.simulations = int(simulations)
        self.uct_c = float(uct_c)
        self.name = f"openspiel-mcts:{self.simulations}"

    def decide(self, state: Any, seed: int) -> int:
        import numpy as np
        from open_spiel.python.algorithms import mcts

        rng = np.random.RandomState(seed % 2**32)
        bot = mcts.MCTSBot(self.os_game, self.uct_c, self.simulations, mcts.RandomRolloutEvaluator(1, rng),
                           solve=True, random_state=rng)
        return int(bot.step(state))


def _openspiel_mcts_factory(arg, *, game, free_move, seed):
    return OpenSpielMCTSOpponent(simulation_count("openspiel-mcts", arg, 1000), game, free_move, seed)


register_opponent("openspiel-mcts", _openspiel_mcts_factory, usage="openspiel-mcts:N")
