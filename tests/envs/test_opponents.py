"""Opponents (`ncbot.envs.opponents`): legality, strength, determinism, names, and the bitboards behind MCTS."""
from __future__ import annotations

import random

import pytest
import torch

from ncbot.envs.opponents import make_opponent, opponent_choices, register_opponent
from ncbot.envs.opponents.arena import play_match
from ncbot.envs.opponents.base import Opponent
from ncbot.envs.opponents.bitboards import DRAW, ONGOING, StandardBits, UltimateBits
from ncbot.envs.opponents.minimax import position_values
from ncbot.envs.games import make_game
from ncbot.envs.rules import Standard, Ultimate

torch.set_num_threads(1)

SETTINGS = [("standard", "anywhere"), ("ultimate", "anywhere"), ("ultimate", "open_subgrids")]


def _random_positions(game: str, free_move: str, n: int, seed: int):
    """Unfinished positions from random play, as the caller of ``select`` would pass them."""
    rules = make_game(game, free_move)
    rng = random.Random(seed)
    states = []
    while len(states) < n:
        s = rules.new()
        stop = rng.randrange(rules.n_cells)
        while rules.outcome(s) is None and s.n_marks < stop:
            s = rules.play(s, rng.choice(rules.legal(s)))
        if rules.outcome(s) is None:
            states.append(s)
    return rules, states


def _batch(rules, states):
    boards = torch.tensor([s.board for s in states], dtype=torch.int8)
    last_move = torch.tensor([s.last_move for s in states])
    legal = torch.zeros(len(states), rules.n_cells, dtype=torch.bool)
    for row, s in enumerate(states):
        legal[row, rules.legal(s)] = True
    return boards, last_move, legal


def _names(game: str) -> list[str]:
    return ["random", "rule", "mcts:8", "winner:0.5"] + (["minimax"] if game == "standard" else [])


@pytest.mark.parametrize("game,free_move", SETTINGS)
def test_every_opponent_plays_legal_cells_and_ignores_empty_rows(game: str, free_move: str) -> None:
    rules, states = _random_positions(game, free_move, 60, seed=5)
    boards, last_move, legal = _batch(rules, states)
    legal[3] = False  # a row without legal cells (a finished game in the caller's batch)
    for name in _names(game):
        opponent = make_opponent(name, game=game, free_move=free_move, seed=0)
        for player in (1, 2):
            mover_boards = boards if player == 1 else torch.where(boards == 0, boards, 3 - boards)
            cells = opponent.select(mover_boards, last_move, legal, player, torch.Generator().manual_seed(1))
            assert cells.dtype == torch.int64 and cells.shape == (len(states),)
            rows = torch.arange(len(states))
            assert legal[rows, cells][legal.any(1)].all(), name
            assert cells[3] == 0


def test_minimax_never_loses_to_random_from_either_seat() -> None:
    minimax = make_opponent("minimax", seed=0)
    rnd = make_opponent("random", seed=1)
    as_first = play_match(minimax, rnd, 300, seed=3)
    as_second = play_match(rnd, minimax, 300, seed=4)
    assert as_first.second_wins == 0 and as_second.first_wins == 0
    assert as_first.first_wins > 250 and as_second.second_wins > 150  # and it wins most games


def test_minimax_draws_itself_and_knows_the_game_value() -> None:
    result = play_match(make_opponent("minimax", seed=0), make_opponent("minimax", seed=1), 50, seed=0)
    assert result.draws == 50
    empty = torch.zeros(1, 9, dtype=torch.int8)
    assert position_values(empty, 1).tolist() == [0]
    # robot (1) holds a1 b1, human (2) holds a2 b2, robot to move: a forced win
    board = torch.tensor([[1, 1, 0, 2, 2, 0, 0, 0, 0]], dtype=torch.int8)
    assert position_values(board, 1).tolist() == [1]


def _rule_choice(game: str, board: list[int], last_move: int, player: int, seed: int = 0) -> int:
    rules = make_game(game)
    boards = torch.tensor([board], dtype=torch.int8)
    legal = torch.tensor([[v == 0 for v in board]])
    if game == "ultimate":  # the caller's legal mask: the forced subgrid of the last move
        from ncbot.envs.rules import SUBGRID_CELLS, TARGET_OF_CELL

        target = SUBGRID_CELLS[TARGET_OF_CELL[last_move]]
        legal = torch.tensor([[v == 0 and c in target for c, v in enumerate(board)]])
    del rules
    opponent = make_opponent("rule", game=game, seed=seed)
    return int(opponent.select(boards, torch.tensor([last_move]), legal, player, torch.Generator().manual_seed(seed)))


@pytest.mark.parametrize("game,free_move", SETTINGS)
def test_winner_takes_a_winning_square_when_told_and_plays_at_random_otherwise(game: str, free_move: str) -> None:
    """``winner:1`` wins at once whenever the rules say it can; ``winner:0`` never looks (different picks)."""
    rules, states = _random_positions(game, free_move, 400, seed=9)
    # mark 1 / 2 as the rules have them; the player to move is rules.to_move(s)
    boards, last_move, legal = _batch(rules, states)
    always, never = (make_opponent(f"winner:{p}", game=game, free_move=free_move) for p in (1, 0))
    checked = 0
    for player in (1, 2):
        rows = [i for i, s in enumerate(states) if rules.to_move(s) == "xo"[player - 1]]
        winning = [[c for c in rules.legal(states[i]) if rules.outcome(rules.play(states[i], c)) == "xo"[player - 1]] for i in rows]
        pick = always.select(boards[rows], last_move[rows], legal[rows], player, torch.Generator().manual_seed(2))
        for k, cells in enumerate(winning):
            if cells:
                assert int(pick[k]) in cells
                checked += 1
    assert checked >= 10
    with pytest.raises(ValueError, match="winner:0.5"):
        make_opponent("winner:1.5", game=game, free_move=free_move)
    assert never.share == 0.0


def test_rule_takes_the_win_before_blocking_and_blocks_otherwise() -> None:
    # robot 1 on a1 b1, human 2 on a2 b2: whoever is to move wins at the end of its own row
    board = [1, 1, 0, 2, 2, 0, 0, 0, 0]
    for seed in range(10):
        assert _rule_choice("standard", board, 4, player=1, seed=seed) == 2
        assert _rule_choice("standard", board, 4, player=2, seed=seed) == 5
    # only the human threatens (a2 b2): the robot blocks at c2
    board = [1, 0, 0, 2, 2, 0, 0, 0, 1]
    for seed in range(10):
        assert _rule_choice("standard", board, 4, player=1, seed=seed) == 5


def test_rule_on_ultimate_takes_a_subgrid_and_blocks_one() -> None:
    from ncbot.envs.rules import SUBGRID_CELLS

    board = [0] * 81
    # in subgrid 4 (the centre) the robot holds squares 0 and 1, the human squares 3 and 4
    for square, code in ((0, 1), (1, 1), (3, 2), (4, 2)):
        board[SUBGRID_CELLS[4][square]] = code
    board[SUBGRID_CELLS[0][4]] = 2  # the human's last move: centre square of subgrid 0 -> sends to subgrid 4
    board[SUBGRID_CELLS[8][8]] = 1
    last = SUBGRID_CELLS[0][4]
    for seed in range(5):
        assert _rule_choice("ultimate", board, last, player=1, seed=seed) == SUBGRID_CELLS[4][2]
    board[SUBGRID_CELLS[4][1]] = 0  # no robot line any more: block the human's middle row instead
    board[SUBGRID_CELLS[8][7]] = 1
    for seed in range(5):
        assert _rule_choice("ultimate", board, last, player=1, seed=seed) == SUBGRID_CELLS[4][5]


def test_mcts_beats_random_clearly_on_3x3() -> None:
    mcts = make_opponent("mcts:50", seed=0)
    rnd = make_opponent("random", seed=1)
    as_first = play_match(mcts, rnd, 60, seed=1)
    as_second = play_match(rnd, mcts, 60, seed=2)
    assert as_first.first_score > 0.9 and as_second.second_score > 0.75
    assert as_first.second_wins <= 2


def test_mcts_wins_ultimate_against_random() -> None:
    for free_move in ("anywhere", "open_subgrids"):
        mcts = make_opponent("mcts:100", game="ultimate", free_move=free_move, seed=0)
        rnd = make_opponent("random", game="ultimate", free_move=free_move, seed=1)
        result = play_match(mcts, rnd, 6, seed=3)
        assert result.first_wins >= 5, (free_move, result)
        result = play_match(rnd, mcts, 6, seed=4)
        assert result.second_wins >= 5, (free_move, result)


def test_mcts_takes_an_immediate_3x3_win() -> None:
    board = torch.tensor([[1, 1, 0, 2, 2, 0, 0, 0, 2]], dtype=torch.int8)
    legal = board == 0
    for seed in range(5):
        cell = make_opponent("mcts:200", seed=seed).select(board, torch.tensor([8]), legal, 1, torch.Generator().manual_seed(seed))
        assert int(cell) == 2


@pytest.mark.parametrize("game,free_move", SETTINGS)
def test_same_seed_same_moves(game: str, free_move: str) -> None:
    rules, states = _random_positions(game, free_move, 20, seed=9)
    boards, last_move, legal = _batch(rules, states)
    for name in _names(game):
        runs = [
            make_opponent(name, game=game, free_move=free_move).select(
                boards, last_move, legal, 1, torch.Generator().manual_seed(42)
            )
            for _ in range(2)
        ]
        assert torch.equal(runs[0], runs[1]), name
    first = play_match(make_opponent("rule", game), make_opponent("random", game), 20, seed=7, free_move=free_move)
    again = play_match(make_opponent("rule", game), make_opponent("random", game), 20, seed=7, free_move=free_move)
    assert first == dataclass_without_time(again, first)


def dataclass_without_time(result, like):
    """The same match result with the timing fields copied from ``like`` (time is not reproducible)."""
    import dataclasses

    return dataclasses.replace(result, first_seconds=like.first_seconds, second_seconds=like.second_seconds)


def test_random_opponent_is_uniform_enough() -> None:
    legal = torch.zeros(20000, 9, dtype=torch.bool)
    legal[:, [1, 4, 7]] = True
    cells = make_opponent("random").select(torch.zeros(20000, 9, dtype=torch.int8), torch.full((20000,), -1), legal, 1,
                                           torch.Generator().manual_seed(0))
    counts = torch.bincount(cells, minlength=9)
    assert counts[[0, 2, 3, 5, 6, 8]].sum() == 0
    assert all(6300 < int(counts[c]) < 7000 for c in (1, 4, 7))


def test_bad_names_and_arguments_raise_clear_errors() -> None:
    with pytest.raises(ValueError, match=r"unknown opponent 'chess'.*random.*rule.*minimax.*mcts:N"):
        make_opponent("chess")
    with pytest.raises(ValueError, match="minimax.*solve exactly.*ultimate.*mcts"):
        make_opponent("minimax", game="ultimate")
    for bad in ("mcts", "mcts:0", "mcts:many"):
        with pytest.raises(ValueError, match="positive simulation count"):
            make_opponent(bad)
    with pytest.raises(ValueError, match="takes no ':' argument"):
        make_opponent("random:3")
    with pytest.raises(ValueError, match="game must be one of standard, ultimate"):
        make_opponent("random", game="go")
    with pytest.raises(ValueError, match="free_move must be one of"):
        make_opponent("random", game="ultimate", free_move="nowhere")
    with pytest.raises(ValueError, match=r"boards must have shape \(B, 9\)"):
        make_opponent("random").select(torch.zeros(2, 81, dtype=torch.int8), torch.zeros(2), torch.zeros(2, 81, dtype=torch.bool), 1)
    with pytest.raises(ValueError, match="player must be 1"):
        make_opponent("random").select(torch.zeros(2, 9, dtype=torch.int8), torch.zeros(2), torch.ones(2, 9, dtype=torch.bool), 0)


def test_register_opponent_adds_a_named_kind() -> None:
    class FirstLegal(Opponent):
        name = "first"

        def _select(self, boards, last_move, legal, player, generator, owners):
            return legal.long().argmax(dim=1)

    seen = {}

    def factory(arg, *, game, free_move, seed):
        seen["arg"] = arg
        return FirstLegal(game, free_move, seed)

    register_opponent("testfirst", factory, usage="testfirst:PATH")
    assert "testfirst:PATH" in opponent_choices()
    opponent = make_opponent("testfirst:some/ckpt.pt")
    assert seen["arg"] == "some/ckpt.pt"
    legal = torch.tensor([[False, True] + [True] * 7])
    assert int(opponent.select(torch.zeros(1, 9, dtype=torch.int8), torch.tensor([-1]), legal, 2)) == 1


# ---------------------------------------------------------------------------------------------------- bitboards
@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_ultimate_bitboards_agree_with_the_rules(free_move: str) -> None:
    rules, engine = Ultimate(free_move), UltimateBits(free_move)
    rng = random.Random(11)
    for _ in range(60):
        s = rules.new()
        pos = engine.from_board(list(s.board), 1, -1)
        while True:
            assert engine.moves(pos) == rules.legal(s)
            expected = {None: ONGOING, "x": 0, "o": 1, "draw": DRAW}[rules.outcome(s)]
            assert engine.result(pos) == expected
            mover = 1 if s.n_marks % 2 == 0 else 2
            rebuilt = engine.from_board(list(s.board), mover, s.last_move, owners=list(s.subgrids))
            assert engine.moves(rebuilt) == rules.legal(s)
            if rules.outcome(s) is not None:
                break
            cell = rng.choice(rules.legal(s))
            s, pos = rules.play(s, cell), engine.play(pos, cell)


def test_standard_bitboards_agree_with_the_rules() -> None:
    rules, engine = Standard(), StandardBits()
    rng = random.Random(12)
    for _ in range(300):
        s, pos = rules.new(), engine.from_board([0] * 9, 1)
        while rules.outcome(s) is None:
            assert engine.moves(pos) == rules.legal(s)
            cell = rng.choice(rules.legal(s))
            s, pos = rules.play(s, cell), engine.play(pos, cell)
        assert engine.result(pos) == {"x": 0, "o": 1, "draw": DRAW}[rules.outcome(s)]


@pytest.mark.parametrize("game,free_move", SETTINGS)
def test_random_playouts_match_the_rules_statistics(game: str, free_move: str) -> None:
    """The playout loop (a separate, faster path than ``play``) gives the same outcome rates as random games."""
    rules = make_game(game, free_move)
    engine = StandardBits() if game == "standard" else UltimateBits(free_move)
    rng = random.Random(0)
    n = 1500 if game == "standard" else 400
    playout = [0, 0, 0]
    reference = [0, 0, 0]
    start = engine.from_board([0] * rules.n_cells, 1)
    for _ in range(n):
        playout[engine.rollout(start, rng.random)] += 1
        s = rules.new()
        while rules.outcome(s) is None:
            s = rules.play(s, rng.choice(rules.legal(s)))
        reference[{"x": 0, "o": 1, "draw": 2}[rules.outcome(s)]] += 1
    for a, b in zip(playout, reference):
        assert abs(a - b) / n < 0.08, (playout, reference)


def test_rule_on_ultimate_prefers_winning_the_game() -> None:
    """Owners passed explicitly: the robot owns subgrids 0 and 1; taking subgrid 2 wins the game at once."""
    from ncbot.envs.rules import SUBGRID_CELLS

    board = [0] * 81
    for k in (0, 1):
        for square in (0, 1, 2):
            board[SUBGRID_CELLS[k][square]] = 1
    board[SUBGRID_CELLS[2][0]] = board[SUBGRID_CELLS[2][1]] = 1  # robot: square 2 of subgrid 2 wins the game
    board[SUBGRID_CELLS[2][3]] = board[SUBGRID_CELLS[2][4]] = 2  # human threatens square 5 of subgrid 2
    for k, square in ((4, 0), (4, 8), (6, 0), (6, 8), (7, 0), (8, 8)):
        board[SUBGRID_CELLS[k][square]] = 2
    last = SUBGRID_CELLS[7][2]  # the human's last move, at square 2 of subgrid 7: the robot must play in subgrid 2
    board[last] = 2
    boards = torch.tensor([board], dtype=torch.int8)
    legal = torch.tensor([[v == 0 and c in SUBGRID_CELLS[2] for c, v in enumerate(board)]])
    owners = torch.tensor([[1, 1, 0, 0, 0, 0, 0, 0, 0]], dtype=torch.int8)
    for seed in range(5):
        cell = make_opponent("rule", game="ultimate", seed=seed).select(
            boards, torch.tensor([last]), legal, 1, torch.Generator().manual_seed(seed), owners=owners)
        assert int(cell) == SUBGRID_CELLS[2][2]
    with pytest.raises(ValueError, match="owners must have shape"):
        make_opponent("rule").select(boards[:, :9], torch.tensor([0]), legal[:, :9], 1, owners=owners)


@pytest.mark.parametrize("game,free_move", SETTINGS)
def test_batched_line_helpers_agree_with_the_rules(game: str, free_move: str) -> None:
    """``winning_cells`` / ``subgrid_owners`` (the rule opponent's view) against playing each legal cell exactly."""
    from ncbot.envs.opponents.lines import subgrid_owners, winning_cells

    rules, states = _random_positions(game, free_move, 150, seed=21)
    boards, _, legal = _batch(rules, states)
    owners = torch.tensor([s.subgrids for s in states], dtype=torch.int8) if game == "ultimate" else None
    if owners is not None:  # without ambiguity (lines of both players in one subgrid) the board alone tells owners
        read = subgrid_owners(boards)
        both_lines = (read != owners) & (owners != 0)
        assert torch.equal(read[~both_lines], owners[~both_lines])
    found = 0
    for player in (1, 2):
        wins = winning_cells(boards, player, owners)
        for row, s in enumerate(states):
            if rules.mark_to_move(s) != player:
                continue
            for cell in rules.legal(s):
                expected = rules.outcome(rules.play(s, cell)) == ("x" if player == 1 else "o")
                assert bool(wins[row, cell]) == expected, (row, cell)
                found += expected
    assert found >= 5  # the positions do contain winning cells


def test_uct_search_spends_every_simulation_below_the_root() -> None:
    from ncbot.envs.opponents.mcts import uct_search

    engine = UltimateBits("open_subgrids")
    pos = engine.from_board([0] * 81, 1)
    move, stats = uct_search(engine, pos, engine.moves(pos), 300, random.Random(0))
    assert sum(visits for visits, _ in stats.values()) == 300
    assert move in engine.moves(pos) and stats[move][0] == max(v for v, _ in stats.values())
    assert all(0.0 <= rate <= 1.0 for _, rate in stats.values())


def test_shared_search_loop_makes_the_decisions_of_the_former_uct_loop() -> None:
    """ncbot.envs.opponents.search replaced mcts.py's own loop: the hash of root moves and root statistics on
    120 positions, pinned from the former loop (commit 1c89ae0), must not move."""
    import hashlib

    from tests.envs.helpers import search_of as make_bits
    from ncbot.envs.opponents.mcts import uct_search

    digest = hashlib.sha256()
    for game, free_move, simulations in (("standard", "anywhere", 50), ("ultimate", "anywhere", 60), ("ultimate", "open_subgrids", 60)):
        rules, rng, engine = make_game(game, free_move), random.Random(1), make_bits(game, free_move)
        found = 0
        while found < 40:
            s = rules.new()
            for _ in range(rng.randrange(0, 30 if game == "ultimate" else 6)):
                if rules.outcome(s) is not None:
                    break
                s = rules.play(s, rng.choice(rules.legal(s)))
            if rules.outcome(s) is not None or len(rules.legal(s)) < 2:
                continue
            pos = engine.from_board(list(s.board), rules.mark_to_move(s), s.last_move, list(s.subgrids) or None)
            move, stats = uct_search(engine, pos, rules.legal(s), simulations, random.Random(found))
            digest.update(repr((move, sorted(stats.items()))).encode())
            found += 1
    assert digest.hexdigest()[:16] == "d75a2893e1f9bc07"
