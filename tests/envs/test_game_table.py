"""A game given by its rules alone (``BoardGame``): its position table, engine, look-ahead, search, solver and symmetries
agree with a replay of the rules. Misère Noughts & Crosses (docs/examples/misere.py) is the game under test; the
3x3 rules tabulated the same way are checked against the 3x3 table engine where the two definitions coincide."""
from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import torch

from ncbot.envs.core import DRAWN, O, X
from ncbot.envs.engine.standard import StandardEngine
from ncbot.envs.engine.tabulated import TabulatedEngine
from ncbot.envs.games import load_game
from ncbot.envs.games.table import GameTable
from ncbot.envs.opponents import make_opponent
from ncbot.envs.opponents.arena import play_match
from ncbot.envs.readings import Readings
from ncbot.envs.rules import Standard

MISERE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "misere.py"


def _misere():
    return load_game(f"{MISERE}:Misere")


def _result(game, state, seat: int, x_seat: int) -> str | None:
    """The outcome of ``state`` for ``seat`` ("win", "loss", "draw") when seat ``x_seat`` holds x; None while on."""
    outcome = game.outcome(state)
    if outcome is None:
        return None
    if outcome == "draw":
        return "draw"
    return "win" if (outcome == "x") == (seat == x_seat) else "loss"


def _brute_reward(game, state, x_seat: int, cell: int, about_to: str) -> float:
    """The paper's one-step reward of the seat to move taking ``cell``, by replaying the rules (module doc of table)."""
    mover = x_seat if game.mark_to_move(state) == X else 3 - x_seat
    after = game.play(state, cell)
    result = _result(game, after, mover, x_seat)
    if result is not None:
        return {"win": 5.0, "draw": 1.0, "loss": -5.0}[result]

    def wins_now(s, seat) -> bool:
        return any(_result(game, game.play(s, c), seat, x_seat) == "win" for c in game.legal(s))

    def can_win(s) -> bool:
        outcome = game.outcome(s)
        return outcome in ("x", "o") or (outcome is None and any(can_win(game.play(s, c)) for c in game.legal(s)))

    def squeezed(s, seat) -> bool:  # every move of ``seat`` (to move) loses at once
        moves = game.legal(s)
        return bool(moves) and all(_result(game, game.play(s, c), seat, x_seat) == "loss" for c in moves)

    replies = [game.play(after, c) for c in game.legal(after)]
    if any(_result(game, r, 3 - mover, x_seat) == "win" or (game.outcome(r) is None and squeezed(r, mover))
           for r in replies):
        return -5.0
    if not can_win(after) and can_win(state):
        return 1.0
    threat = any(game.outcome(r) is None and wins_now(r, mover) for r in replies)
    squeeze = squeezed(after, 3 - mover)
    if (threat or squeeze) and not (about_to == "created" and wins_now(state, mover)):
        return 5.0
    return 0.0


def test_the_table_holds_every_position_and_its_rewards_agree_with_the_rules() -> None:
    game, rng = _misere(), random.Random(0)
    table = game.table
    assert table.to_move[0] == 0 and not table.boards[0].any()  # the empty start, either seat may open
    checked = 0
    for position in rng.sample(range(len(table.states)), 300):
        state, x_seat = table.states[position]
        if game.outcome(state) is not None or x_seat == 0:
            continue
        seat = int(table.to_move[position])
        assert sorted(np.flatnonzero(table.legal[position])) == game.legal(state)
        for about_to in ("standing", "created"):
            rows = table.reward_rows(seat, about_to)
            for cell in game.legal(state):
                assert rows[position, cell] == _brute_reward(game, state, x_seat, cell, about_to), (state, cell, about_to)
                checked += 1
    assert checked > 1000


def test_the_batched_engine_plays_like_the_rules_from_both_seats() -> None:
    game, generator = _misere(), torch.Generator().manual_seed(3)
    engine = game.engine(Readings())
    state = engine.new(64)
    for ply in range(9):
        legal = engine.legal(state)
        playing = state.outcome == 0
        cells = engine.random_legal(state, generator)
        seat = torch.where(torch.arange(64) % 2 == 0, 1 + ply % 2, 2 - ply % 2)  # half the games opened by seat 2
        engine.play(state, cells, seat, playing)
        for row in range(64):
            marks = state.board[row].tolist()
            if not bool(playing[row]):
                continue
            assert bool(legal[row, cells[row]])
            opener = 1 if row % 2 == 0 else 2
            rules_board = tuple(X if m == opener else O if m else 0 for m in marks)
            x_wins = any(all(rules_board[c] == X for c in line) for line in ((0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6),
                                                                            (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6)))
            o_wins = any(all(rules_board[c] == O for c in line) for line in ((0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6),
                                                                            (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6)))
            expected = (3 - opener if x_wins else opener if o_wins else DRAWN if all(marks) else 0)  # misère: a line loses
            assert int(state.outcome[row]) == expected, (row, marks)


def test_tabulating_the_3x3_rules_gives_the_3x3_engine_where_the_definitions_coincide() -> None:
    """Legal squares, the moves that win now and "about to lose" are the same definitions in both; "about to win"
    and "about to draw" are read through the rules here (a reply, then a winning move; no win reachable any more)
    and through the lines in the 3x3 engine, which differ on few positions."""
    table = GameTable(Standard(), 300_000)
    engine = StandardEngine(Readings(win_set="wins"))
    robot = np.flatnonzero(table.to_move != 2)  # positions where seat 1 moves (the start: either seat)
    codes = torch.from_numpy((table.boards[robot].astype(np.int64) * 3 ** np.arange(9)).sum(1))
    legal, rewards = (rows.index_select(0, codes) for rows in engine.rows_by_code(1))
    assert torch.equal(torch.from_numpy(table.legal[robot]), legal)
    assert torch.equal(torch.from_numpy(table.wins[1][robot]), engine.winning_rows_by_code(1).index_select(0, codes) & legal)
    ours = torch.from_numpy(table.rewards[1][robot])
    assert torch.equal((ours == -5.0) & legal, (rewards == -5.0) & legal)
    assert float((ours == rewards)[legal].float().mean()) > 0.95


def test_search_solver_and_symmetries_follow_from_the_rules() -> None:
    game = _misere()
    assert game.solver().value[0, 1] == 0  # perfect misère play draws, whoever opens
    assert game.symmetries().shape == (8, 9)  # the rules keep all 8 turns and mirrors of the square
    minimax = make_opponent("minimax", game=game.id, seed=0)
    rand = make_opponent("random", game=game.id, seed=1)
    as_first, as_second = play_match(minimax, rand, 60, seed=2), play_match(rand, minimax, 60, seed=3)
    assert as_first.second_wins == 0 and as_second.first_wins == 0  # never loses
    mcts = make_opponent("mcts:30", game=game.id, seed=4)
    assert play_match(mcts, rand, 20, seed=5).first_score > 0.6
    assert TabulatedEngine(game.table).cells == 9
