"""The batched engine agrees with the scalar rules on >= 100,000 random positions per game/variant, and its
one-step rewards agree with a brute-force reading of the reward definitions that shares no code with it."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from ncbot.envs.engine import grid_tables
from tests.envs.helpers import engine_of as make_engine
from ncbot.envs.rules import LINES_3X3, SUBGRID_CELLS, Standard, Ultimate

torch.set_num_threads(1)
VARIANTS = [("standard", "anywhere"), ("ultimate", "anywhere"), ("ultimate", "open_subgrids")]
OUTCOME_CODE = {None: 0, "x": 1, "o": 2, "draw": 3}


def rules_of(game: str, free_move: str):
    return Standard() if game == "standard" else Ultimate(free_move)


def random_games(game: str, free_move: str, n_games: int, seed: int):
    """Play ``n_games`` random games in lockstep with the engine and the rules; yield per ply both views."""
    engine, rules = make_engine(game, free_move), rules_of(game, free_move)
    generator = torch.Generator().manual_seed(seed)
    state = engine.new(n_games)
    states = [rules.new() for _ in range(n_games)]
    for _ in range(engine.cells + 1):
        legal = engine.legal(state)
        yield engine, rules, state, states, legal
        active = legal.any(1)
        if not bool(active.any()):
            return
        cells = (torch.rand(legal.shape, generator=generator) + legal).argmax(1)
        engine.play(state, cells, 1 + state.n_marks % 2, active)
        for i in active.nonzero().flatten().tolist():
            states[i] = rules.play(states[i], int(cells[i]))


@pytest.mark.parametrize("game,free_move", VARIANTS)
def test_engine_agrees_with_rules_on_100k_positions(game: str, free_move: str) -> None:
    n_games = 13_500 if game == "standard" else 1_900
    checked = 0
    for engine, rules, state, states, legal in random_games(game, free_move, n_games, seed=7):
        expected = np.zeros(tuple(legal.shape), dtype=bool)
        for i, s in enumerate(states):
            expected[i, rules.legal(s)] = True
        assert np.array_equal(legal.numpy(), expected)
        outcomes = [OUTCOME_CODE[rules.outcome(s)] for s in states]
        assert state.outcome.tolist() == outcomes
        if game == "ultimate":
            assert state.owners.tolist() == [list(s.subgrids) for s in states]
        assert state.board.tolist() == [list(s.board) for s in states]
        checked += int(legal.any(1).sum())  # positions of games still in progress
    assert checked >= 100_000


def test_tables_match_direct_line_checks() -> None:
    tables = grid_tables(3)
    rng = np.random.default_rng(0)
    for code in rng.integers(0, 3**9, size=2000):
        grid = [(int(code) // 3**i) % 3 for i in range(9)]
        for p in (1, 2):
            line = any(all(grid[c] == p for c in ln) for ln in LINES_3X3)
            assert bool(tables.has_line[p, code]) == line
            wins = {c for c in range(9) if grid[c] == 0 and any(c in ln and sum(grid[d] == p for d in ln) == 2 for ln in LINES_3X3)}
            bits = int(tables.win_bits[p, code])
            assert {c for c in range(9) if bits >> c & 1} == wins
        assert bool(tables.full[code]) == (0 not in grid)


# ---------------------------------------------------------------- independent reading of the rewards
def _line_done(marks, p) -> bool:
    return any(all(marks[c] == p for c in ln) for ln in LINES_3X3)


def _dead(values) -> bool:
    """No line of ``values`` (3x3 grid; 3 = drawn subgrid) can still be completed by either player."""
    return all(3 in [values[c] for c in ln] or {1, 2} <= {values[c] for c in ln} for ln in LINES_3X3)


def _meta(rules, s):
    return list(s.board) if isinstance(rules, Standard) else list(s.subgrids)


def _threat(rules, s, p) -> bool:
    """Would ``p`` win the game by taking some empty square (ignoring turn and redirect)?"""
    if isinstance(rules, Standard):
        return any(s.board[c] == 0 and _line_done([p if i == c else v for i, v in enumerate(s.board)], p) for c in range(9))
    for k, cells in enumerate(SUBGRID_CELLS):
        if s.subgrids[k] != 0:
            continue
        for c in cells:
            if s.board[c] == 0:
                marks = [p if d == c else s.board[d] for d in cells]
                if _line_done(marks, p) and _line_done([p if i == k else v for i, v in enumerate(s.subgrids)], p):
                    return True
    return False


def brute_force_reward(rules, s, cell, about_to: str = "standing") -> float:
    """The reward definitions read literally; ``about_to="created"``: "about to win" pays only when the mover had
    no winning square before its move (same definition of a winning square, before and after)."""
    p = rules.mark_to_move(s)
    after = rules.play(s, cell)
    result = rules.outcome(after)
    if result == "draw":
        return 1.0
    if result is not None:
        return 5.0
    if any(rules.outcome(rules.play(after, reply)) not in (None, "draw") for reply in rules.legal(after)):
        return -5.0
    if _dead(_meta(rules, after)) and not _dead(_meta(rules, s)):
        return 1.0
    if _threat(rules, after, p) and not (about_to == "created" and _threat(rules, s, p)):
        return 5.0
    return 0.0


@pytest.mark.parametrize("about_to", ["standing", "created"])
@pytest.mark.parametrize("game,free_move", VARIANTS)
def test_move_rewards_match_brute_force(game: str, free_move: str, about_to: str) -> None:
    n_games, every = (300, 1) if game == "standard" else (24, 3)
    compared = kept_threats = 0
    for ply, (engine, rules, state, states, legal) in enumerate(random_games(game, free_move, n_games, seed=3)):
        if ply % every:
            continue
        engine = make_engine(game, free_move, about_to=about_to)  # same state, the reading under test
        player = 1 + state.n_marks % 2
        for p in (1, 2):
            rows = (player == p) & legal.any(1)
            if not bool(rows.any()):
                continue
            rewards = engine.move_rewards(state, p)
            for i in rows.nonzero().flatten().tolist():
                had = _threat(rules, states[i], p)
                for cell in legal[i].nonzero().flatten().tolist():
                    expected = brute_force_reward(rules, states[i], cell, about_to)
                    assert float(rewards[i, cell]) == expected, (i, cell, about_to, rules.render(states[i]))
                    compared += 1
                    kept_threats += had and expected == 0.0 and brute_force_reward(rules, states[i], cell) == 5.0
    assert compared > 1000
    assert (kept_threats > 0) == (about_to == "created")  # the readings differ on these positions


def _wins_now(rules, s, cell) -> bool:
    after = rules.play(s, cell)
    return rules.outcome(after) == ("x" if rules.mark_to_move(s) == 1 else "o")


@pytest.mark.parametrize("game,free_move", VARIANTS)
def test_win_set_wins_holds_exactly_the_moves_that_win_now(game: str, free_move: str) -> None:
    """win_set="wins": Algorithm 2's "action(s) leading to win (legally) the game"; wins_and_threats: every +5."""
    n_games = 300 if game == "standard" else 40
    wins_seen = threats_seen = 0
    for engine, rules, state, states, legal in random_games(game, free_move, n_games, seed=5):
        player = 1 + state.n_marks % 2
        for p in (1, 2):
            rows = (player == p) & legal.any(1)
            if not bool(rows.any()):
                continue
            sets = {}
            for win_set in ("wins", "wins_and_threats"):
                reading = make_engine(game, free_move, win_set=win_set)
                if game == "standard":
                    sets[win_set] = reading.winning_rows_by_code(p).index_select(0, state.codes[:, 0]) & legal
                else:
                    rewards = torch.full((legal.shape[0], 81), -5.0)
                    wins = torch.zeros(legal.shape[0], 81, dtype=torch.bool)
                    reading.write_move_rewards(rewards, state, p, rows, wins)
                    sets[win_set] = wins & legal
            plus5 = engine.move_rewards(state, p) == 5.0
            for i in rows.nonzero().flatten().tolist():
                cells = legal[i].nonzero().flatten().tolist()
                expected = {c for c in cells if _wins_now(rules, states[i], c)}
                assert set(sets["wins"][i].nonzero().flatten().tolist()) == expected, (i, rules.render(states[i]))
                assert torch.equal(sets["wins_and_threats"][i], plus5[i] & legal[i])
                wins_seen += len(expected)
                threats_seen += int(sets["wins_and_threats"][i].sum()) - len(expected)
    assert wins_seen > 50 and threats_seen > wins_seen  # threats outnumber wins: the readings differ


def test_engine_rejects_unknown_game_and_variant() -> None:
    with pytest.raises(ValueError, match="game must be one of standard, ultimate"):
        make_engine("chess")
    with pytest.raises(ValueError, match="free_move must be one of anywhere, open_subgrids"):
        make_engine("ultimate", "sometimes")
    with pytest.raises(ValueError, match="win_set must be one of wins_and_threats, wins; got 'all'"):
        make_engine("standard", win_set="all")
    with pytest.raises(ValueError, match="about_to must be one of standing, created; got 'once'"):
        make_engine("ultimate", about_to="once")


def test_from_boards_reads_hand_made_3x3_positions() -> None:
    engine = make_engine("standard")
    boards = torch.tensor([[1, 1, 1, 2, 2, 0, 0, 0, 0], [1, 2, 1, 1, 2, 2, 2, 1, 1], [1, 0, 0, 0, 2, 0, 0, 0, 0]])
    state = engine.from_boards(boards)
    assert state.outcome.tolist() == [1, 3, 0]
    assert engine.legal(state)[2].nonzero().flatten().tolist() == [1, 2, 3, 5, 6, 7, 8]
    # x (1) to move on the third board (x a1, o b2): b1 makes a1-b1 with c1 open and o has no threat -> +5
    rewards = engine.move_rewards(state, 1)[2]
    assert float(rewards[1]) == 5.0 and float(rewards[8]) == 0.0
    with pytest.raises(ValueError, match="order of play"):
        make_engine("ultimate").from_boards(torch.zeros(1, 81))
