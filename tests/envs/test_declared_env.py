"""A declared game in the dialogue env and against the opponents: sizes from the declaration, masks and look-ahead from
the engine, example dialogues generated as data, MCTS bitboards that agree with the exact rules."""
from __future__ import annotations

import random

import pytest
import torch

from ncbot.envs import make_env
from ncbot.envs.dialogue import build_dialogue_model
from ncbot.envs.opponents import make_opponent
from ncbot.envs.opponents.arena import play_match
from ncbot.envs.games import make_game
from ncbot.envs.opponents.bitboards import DRAW, ONGOING
from tests.envs.helpers import search_of as make_bits


@pytest.fixture()
def five_four(tmp_path) -> str:
    """A game the project never saw: 5 rows x 4 columns, three in a line, marks drop down."""
    path = tmp_path / "five_four.yaml"
    path.write_text("name: five_four\nrows: 5\ncols: 4\nk: 3\ngravity: true\n")
    return str(path)


def test_env_is_sized_from_the_declaration(five_four):
    env = make_env(five_four, batch_size=(4,), seed=0)
    words = len(env.words)
    assert (env.cells, env.n_actions) == (20, 29)
    assert env.n_features == 20 * 3 + 7 + words
    assert env.action_names[:2] == ["GameMove(gridloc=0)", "GameMove(gridloc=1)"]
    assert "where=b5" in env.describe_action(17)
    td = env.reset()
    assert td["observation"].shape == (4, env.n_features) and td["board"].shape == (4, 20)


def test_random_dialogues_never_accept_a_move_the_rules_refuse_and_lookahead_matches_the_engine(five_four):
    env = make_env(five_four, batch_size=(8,), seed=1, first="alternate")
    engine = env.engine
    td = env.reset()
    ended = 0
    for _ in range(150):
        mask = td["action_mask"]
        assert mask.any(1).all()
        moves = mask[:, : env.cells]
        for row in moves.any(1).nonzero().flatten().tolist():
            board = td["board"][row]
            expected = engine.move_rewards(engine.from_boards(board.unsqueeze(0)), 1)[0]
            legal = moves[row]
            assert torch.equal(td["lookahead_reward"][row, : env.cells][legal], expected[legal])
            playable = engine.playable(board.unsqueeze(0))[0]
            assert torch.equal(legal, playable)
        td = env.rand_action(td)
        td, td_next = env.step_and_maybe_reset(td)
        robot_moved = td["action"] < env.cells
        cells = td["action"].clamp(max=env.cells - 1).unsqueeze(1)
        assert (td["next", "board"].gather(1, cells).squeeze(1)[robot_moved] == 1).all()  # an offered move is taken
        ended += int(td["next", "done"].sum())
        td = td_next
    assert ended > 10


def test_example_dialogues_are_generated_from_the_declaration(five_four):
    model = build_dialogue_model(five_four)
    again = build_dialogue_model.__wrapped__(five_four)
    assert model.words == again.words and torch.equal(model.filter_allowed, again.filter_allowed)
    assert model.words == build_dialogue_model("standard").words  # same utterances and templates: same vocabulary
    assert model.n_examples > 100


def test_declared_bitboards_agree_with_the_rules():
    for game in ("four", "connect_four"):
        rules, bits, rng = make_game(game), make_bits(game), random.Random(0)
        for _ in range(30):
            s = rules.new()
            pos = bits.from_board(list(s.board), 1)
            while True:
                assert bits.moves(pos) == rules.legal(s)
                if rules.outcome(s) is not None:
                    result = {"draw": DRAW, "x": 0, "o": 1}[rules.outcome(s)]  # sides of the root position: x is 0
                    assert bits.result(pos) == result
                    break
                assert bits.result(pos) == ONGOING
                cell = rng.choice(rules.legal(s))
                s, pos = rules.play(s, cell), bits.play(pos, cell)
                # a position read off the board equals the one played to
                again = bits.from_board(list(s.board), 1 if s.n_marks % 2 == 0 else 2)
                assert again[:2] == (pos[:2] if pos[2] == 0 else pos[1::-1]) and again[4] == pos[4]


def test_search_and_rule_opponents_beat_random_and_minimax_refuses(five_four):
    for name in ("rule", "mcts:50"):
        strong, weak = make_opponent(name, game=five_four, seed=0), make_opponent("random", game=five_four, seed=1)
        result = play_match(strong, weak, 20, seed=0)
        assert result.first_wins >= 17, (name, result)
    with pytest.raises(ValueError, match="opponent 'minimax' needs a game small enough to solve exactly; 'four' is too large"):
        make_opponent("minimax", game="four")
