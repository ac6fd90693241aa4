"""The paper's ambiguous readings as options (envs.core, docs/env.md "Readings"), on the real env, no mocks.

taken_squares (never | refused | misread | offered, with misread_rate), win_set, about_to and the masks' all_negative; the
defaults leave the env bit-identical (tests/test_faithful.py checks the recorded fingerprints).
"""
from __future__ import annotations

import pytest
import torch

from ncbot.envs import make_env
from ncbot.envs.core import LINES_3X3
from ncbot.modules.mask_rules import all_moves_negative, untaken_actions
from ncbot.modules.masks import LookaheadMasks, LookaheadOnlyPolicy
from ncbot.modules.policy import make_policies
from ncbot.modules.qnet import make_qnet
from tests.envs.helpers import to_robot_move

torch.set_num_threads(1)
MOVE_REFUSED = -5.0


def _has_line(board: list[int], mark: int) -> bool:
    return any(all(board[c] == mark for c in line) for line in LINES_3X3)


# ------------------------------------------------------------------------------------------------ taken_squares
def test_a_refused_move_corrects_the_belief_and_the_next_observation_differs() -> None:
    env = make_env("standard", batch_size=(1,), seed=3, first="robot", taken_squares="misread", misread_rate=0.99)
    for _ in range(50):  # find a misread: a square the robot believes free that the user really took
        td = to_robot_move(env, env.reset())
        td["action"] = td["action_mask"][0, :9].nonzero()[0]
        td = to_robot_move(env, env.step(td)["next"])
        truth, believed = env.boards.board[0], td["board"][0]
        misread = ((truth == 2) & (believed == 0)).nonzero().flatten()
        if misread.numel():
            break
    else:
        raise AssertionError("no misread in 50 games at rate 0.99")
    square = int(misread[0])
    assert bool(td["action_mask"][0, square])  # offered: "not taken yet (to the robot's knowledge)"
    td["action"] = torch.tensor([square])
    after = env.step(td)["next"]
    assert float(after["reward"][0]) == MOVE_REFUSED  # "a repeated (already taken) action"
    assert int(after["user_move"][0]) == -1  # the user did not move
    assert torch.equal(after["board"][0], env.boards.board[0])  # the sheet read again: belief == truth
    assert not torch.equal(after["observation"], td["observation"])  # so the robot does not loop
    assert not bool(after["action_mask"][0, square])


def test_the_misread_rate_is_honoured() -> None:
    rate = 0.2
    env = make_env("ultimate", batch_size=(128,), seed=5, first="alternate", taken_squares="misread", misread_rate=rate)
    policy = LookaheadOnlyPolicy(seed=1, all_negative="untaken")
    td = env.reset()
    moves = misreads = 0
    for _ in range(300):
        stepped, td = env.step_and_maybe_reset(policy(td))
        moved = stepped["next", "user_move"][:, 0] >= 0
        moves += int(moved.sum())
        misreads += int((env.d.misread & moved).sum())
    # a draw that finds no other square, or meets an earlier misread's mark (re-read), reads correctly
    assert moves > 10_000 and rate - 0.02 < misreads / moves <= rate + 0.01, misreads / moves


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_the_true_board_decides_the_game_and_what_is_accepted(game: str) -> None:
    env = make_env(game, batch_size=(64,), seed=2, first="alternate", taken_squares="misread", misread_rate=0.5)
    td = env.reset()
    differing = refused = believed_user_lines = 0
    for _ in range(400):
        td = env.rand_action(td)  # uniform in action_mask: the believed legal moves
        accepted = env.d.legal.gather(1, td["action"].unsqueeze(1)).squeeze(1)  # what the true board accepts
        stepped, td = env.step_and_maybe_reset(td)
        nxt = stepped["next"]
        assert torch.equal(td["outcome"][:, 0].long(), env.boards.outcome)  # the outcome is the true board's
        assert bool(td["action_mask"].any(1).all())
        board = td["board"]  # after the resets of finished games, as env.boards
        assert bool((board <= 2).all()) and bool((board >= 0).all())
        robot_marks = board == 1
        assert torch.equal(robot_marks, env.boards.board == 1)  # the robot knows its own marks
        differing += int((board != env.boards.board).any(1).sum())
        refusals = (stepped["action"] < env.cells) & ~accepted
        assert bool((nxt["reward"][:, 0][refusals] == MOVE_REFUSED).all())
        assert bool((nxt["user_move"][:, 0][refusals] == -1).all())
        refused += int(refusals.sum())
        if game == "standard":
            for row in (td["outcome"][:, 0] == 0).nonzero().flatten().tolist():
                believed_user_lines += _has_line(board[row].tolist(), 2)
    assert differing > 100 and refused > 10
    if game == "standard":
        assert believed_user_lines > 0  # the robot may believe the user won: the game goes on (the truth decides)


def test_refused_offers_taken_squares_and_misread_offers_believed_free_ones() -> None:
    for taken, rate in (("never", None), ("refused", None), ("misread", 0.3)):
        env = make_env("ultimate", batch_size=(32,), seed=1, first="robot", taken_squares=taken, misread_rate=rate)
        td = env.reset()
        offered_taken = 0
        for _ in range(200):
            offered_taken += int((td["action_mask"][:, :81] & (td["board"] != 0)).sum())
            td = env.rand_action(td)
            _, td = env.step_and_maybe_reset(td)
        assert (offered_taken > 0) == (taken == "refused"), taken


# ------------------------------------------------------------------------------------------------------ win_set
@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_win_set_wins_holds_only_the_moves_that_win(game: str) -> None:
    sizes = {}
    for win_set in ("wins", "wins_and_threats"):
        env = make_env(game, batch_size=(64,), seed=4, first="alternate", win_set=win_set)
        td = env.reset()
        held = won = 0
        for _ in range(300):
            winning = td["winning_actions"].clone()
            td["action"] = torch.where(winning.any(1), (torch.rand(winning.shape) + winning).argmax(1),
                                       env.rand_action(td)["action"])
            stepped, td = env.step_and_maybe_reset(td)
            chose = winning.gather(1, stepped["action"].unsqueeze(1)).squeeze(1)
            held += int(chose.sum())
            won += int((chose & (stepped["next", "outcome"][:, 0] == 1)).sum())
            assert bool((stepped["next", "reward"][:, 0][chose] == 5.0).all())  # both readings: every move in A is +5
        sizes[win_set] = held
        if win_set == "wins":
            assert held > 20 and won == held  # each move of the set won the game at once
        else:
            assert won < held  # threats too
    assert sizes["wins"] < sizes["wins_and_threats"]


# ----------------------------------------------------------------------------------------------------- about_to
def test_about_to_created_pays_about_to_win_once_per_threat() -> None:
    """3x3: +5 for a move that does not win only when the robot had no winning square before it."""
    paid = {}
    for about_to in ("standing", "created"):
        env = make_env("standard", batch_size=(128,), seed=6, first="alternate", about_to=about_to)
        td = env.reset()
        kept = 0
        for _ in range(300):
            before = td["board"].clone()
            stepped, td = env.step_and_maybe_reset(env.rand_action(td))
            action, reward = stepped["action"], stepped["next", "reward"][:, 0]
            for row in ((action < 9) & (reward == 5.0) & (stepped["next", "outcome"][:, 0] != 1)).nonzero().flatten().tolist():
                board = before[row].tolist()
                had = any(board[c] == 0 and _has_line([1 if i == c else v for i, v in enumerate(board)], 1) for c in range(9))
                kept += had
        paid[about_to] = kept
    assert paid["created"] == 0 and paid["standing"] > 20


# ------------------------------------------------------------------------------------------------- all_negative
def test_all_moves_negative_and_untaken_fallback_on_a_hand_made_row() -> None:
    available = torch.tensor([[True, True, True, False, True]])  # 4 "cells", then one dialogue act
    reward = torch.tensor([[-5.0, -5.0, -5.0, 0.0, -5.0]])
    board = torch.tensor([[1, 2, 0, 1]], dtype=torch.int8)
    assert bool(all_moves_negative(available, reward, 4)[0])
    assert not bool(all_moves_negative(available, torch.tensor([[-5.0, 0.0, -5.0, 0.0, -5.0]]), 4)[0])
    assert not bool(all_moves_negative(torch.tensor([[False] * 4 + [True]]), reward, 4)[0])  # no move allowed
    td_keys = {"action_mask": available, "lookahead_reward": reward, "winning_actions": torch.zeros_like(available),
               "board": board}
    from tensordict import TensorDict

    for all_negative, expected in (("available", available), ("untaken", available & untaken_actions(board, 5))):
        td = LookaheadMasks("one_step", all_negative)(TensorDict(dict(td_keys), batch_size=[1]))
        assert torch.equal(td["greedy_mask"], expected), all_negative
        assert torch.equal(td["explore_mask"], available)  # exploration is unchanged


@pytest.mark.parametrize("lookahead", ["variant", "one_step"])
def test_all_negative_untaken_never_picks_a_taken_square(lookahead: str) -> None:
    env = make_env("ultimate", batch_size=(64,), seed=8, first="robot", taken_squares="refused")
    policy = LookaheadOnlyPolicy(seed=2, lookahead=lookahead, all_negative="untaken")
    td = env.reset()
    fallbacks = 0
    for _ in range(400):
        td = policy(td)
        fallbacks += int(all_moves_negative(td["action_mask"], td["lookahead_reward"], 81).sum())
        action = td["action"]
        taken = (action < 81) & (td["board"].gather(1, action.clamp(max=80).unsqueeze(1)).squeeze(1) != 0)
        assert not bool(taken.any())
        _, td = env.step_and_maybe_reset(td)
    assert fallbacks > 10  # the fallback was exercised


def test_bad_values_are_one_line_errors() -> None:
    cases = [
        (dict(taken_squares="sometimes"), "taken_squares must be one of never, refused, misread, offered; got 'sometimes'"),
        (dict(taken_squares="misread"), "misread_rate must be a number in \\(0, 1\\) with taken_squares=misread"),
        (dict(taken_squares="misread", misread_rate=1.0), "misread_rate must be a number in \\(0, 1\\)"),
        (dict(taken_squares="refused", misread_rate=0.1), "misread_rate is only used with taken_squares=misread or offered"),
        (dict(win_set="all"), "win_set must be one of wins_and_threats, wins; got 'all'"),
        (dict(about_to="once"), "about_to must be one of standing, created; got 'once'"),
    ]
    for kwargs, message in cases:
        with pytest.raises(ValueError, match=message) as error:
            make_env("standard", **kwargs)
        assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="all_negative must be one of available, untaken; got 'never'"):
        LookaheadMasks("one_step", "never")


def test_config_fields_reach_the_env_and_the_masks() -> None:
    from pathlib import Path

    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.run_env import make_run_env

    default = Path(__file__).resolve().parents[2] / "pipelines" / "configs" / "default.yaml"
    config = load_config(default, ["env.taken_squares=misread", "env.misread_rate=0.1", "env.win_set=wins",
                                   "env.about_to=created", "agent.all_negative=untaken"])
    env = make_run_env(config.env, batch_size=2, seed=0)
    assert (env.taken_squares, env.misread_rate, env.win_set, env.about_to) == ("misread", 0.1, "wins", "created")
    for overrides, key in ((["env.taken_squares=misread"], "env.misread_rate"),
                           (["env.misread_rate=0.1"], "env.misread_rate"),
                           (["env.taken_squares=maybe"], "env.taken_squares"),
                           (["env.win_set=all"], "env.win_set"), (["env.about_to=x"], "env.about_to"),
                           (["agent.all_negative=x"], "agent.all_negative")):
        with pytest.raises(ValueError, match=key.replace(".", "\\.")) as error:
            load_config(default, overrides)
        assert "\n" not in str(error.value)


# ------------------------------------------------------------------------------------------------------- smoke
def test_paper_readings_on_ultimate_never_loop_on_refusals() -> None:
    """Ultimate, the paper configs' readings, an untrained Q-network with epsilon 0.1: a refused square corrects the
    robot's knowledge, so no game repeats refusals (the loop that filled the 100-act cap under ``refused``)."""
    env = make_env("ultimate", batch_size=(16,), seed=9, first="robot", taken_squares="misread", misread_rate=0.10,
                   win_set="wins", about_to="standing", dialogues="paper", temporal=True)
    torch.manual_seed(0)
    qnet = make_qnet(env.n_features, env.n_actions, [32])
    agent = make_policies(qnet, env.action_spec_unbatched, "one_step", eps_init=0.1, eps_end=0.1, annealing_frames=1,
                          all_negative="untaken")
    td = env.reset()
    run = torch.zeros(16, dtype=torch.int64)  # consecutive refused game moves per game
    longest = refused = truncated = 0
    with torch.no_grad():
        for _ in range(250):  # 4,000 frames
            td = agent.explore(td)
            refusal = (td["action"] < 81) & ~env.d.legal.gather(1, td["action"].unsqueeze(1)).squeeze(1)
            stepped, td = env.step_and_maybe_reset(td)
            nxt = stepped["next"]
            run = torch.where(refusal, run + 1, 0)
            longest = max(longest, int(run.max()))
            refused += int(refusal.sum())
            truncated += int(nxt["truncated"].sum())
    assert refused > 0 and longest == 1 and truncated == 0, (refused, longest, truncated)
