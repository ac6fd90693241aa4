"""``taken_squares="offered"``: the ``misread`` reading with every square the robot knows is taken offered too (the
paper's "-5 ... a repeated (already taken) action" payable to an agent without look-ahead masks); real env, no mocks.
"""
from __future__ import annotations

import pytest
import torch

from ncbot.envs import make_env
from ncbot.modules.masks import LookaheadMasks
from tests.envs.helpers import to_robot_move

torch.set_num_threads(1)
MOVE_REFUSED = -5.0


def _first_free(td, cells: int) -> torch.Tensor:
    """A fixed policy: the first offered act that is not a square the robot knows is taken."""
    free = td["action_mask"].clone()
    free[:, :cells] &= td["board"] == 0
    return free.float().argmax(1)


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_every_known_taken_square_is_offered_at_minus_five_and_never_wins(game: str) -> None:
    env = make_env(game, batch_size=(32,), seed=4, first="alternate", taken_squares="offered", misread_rate=0.2)
    cells = env.cells
    td = env.reset()
    offered_taken = 0
    for _ in range(300):
        moves = td["action_mask"][:, :cells]
        turn = moves.any(1)  # the filter allows a game move: the robot's turn in a game not over
        taken = td["board"] != 0
        assert bool((moves[turn] | ~taken[turn]).all())  # every square it knows is taken is offered
        assert bool((td["lookahead_reward"][:, :cells][taken & moves] == MOVE_REFUSED).all())
        assert not bool((td["winning_actions"][:, :cells] & taken).any())
        if game == "standard":  # 3x3: all nine squares on the robot's turn
            assert bool(moves[turn].all())
        offered_taken += int((moves & taken).sum())
        td["action"] = _first_free(td, cells)
        _, td = env.step_and_maybe_reset(td)
    assert offered_taken > 100


def test_a_taken_square_is_refused_at_minus_five_and_the_sheet_is_read_again() -> None:
    env = make_env("standard", batch_size=(1,), seed=3, first="robot", taken_squares="offered", misread_rate=0.5)
    td = to_robot_move(env, env.reset())
    td["action"] = torch.tensor([0])
    td = to_robot_move(env, env.step(td)["next"])  # the robot holds a1, the user one square more
    assert bool(td["action_mask"][0, 0])  # its own square is offered again
    turn = int(td["turn"][0])
    td["action"] = torch.tensor([0])
    after = env.step(td)["next"]
    assert float(after["reward"][0]) == MOVE_REFUSED
    assert int(after["user_move"][0]) == -1  # refused: the user does not move
    assert int(after["turn"][0]) == turn + 1 and int(after["outcome"][0]) == 0  # one act spent, the game goes on
    assert torch.equal(after["board"][0], env.boards.board[0])  # re-read: what the robot knows is the sheet


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_offered_plays_as_misread_when_no_taken_square_is_chosen(game: str) -> None:
    """The offer adds choices only: the same seed and the same choices give the same games as ``misread``."""
    envs = [make_env(game, batch_size=(16,), seed=7, first="alternate", taken_squares=taken, misread_rate=0.3,
                     temporal=True) for taken in ("misread", "offered")]
    tds = [env.reset() for env in envs]
    for _ in range(200):
        for td in tds:
            td["action"] = _first_free(td, envs[0].cells)
        assert torch.equal(tds[0]["action"], tds[1]["action"])
        steps = [env.step_and_maybe_reset(td) for env, td in zip(envs, tds)]
        (first, tds[0]), (second, tds[1]) = steps
        for key in ("reward", "observation", "board", "user_move", "done"):
            assert torch.equal(first["next", key], second["next", key]), key


def test_dqn_original_masks_offer_taken_squares_and_proposed_masks_drop_them() -> None:
    env = make_env("standard", batch_size=(64,), seed=5, first="alternate", taken_squares="offered", misread_rate=0.1)
    original, proposed = LookaheadMasks("none"), LookaheadMasks("one_step", "untaken")
    td = env.reset()
    in_original = 0
    for _ in range(100):
        taken = td["board"] != 0
        in_original += int((original(td.clone())["greedy_mask"][:, :9] & taken).sum())
        proposed_masks = proposed(td.clone())
        assert not bool((proposed_masks["greedy_mask"][:, :9] & taken).any())
        td["action"] = _first_free(td, 9)
        _, td = env.step_and_maybe_reset(td)
    assert in_original > 50


def test_offered_needs_a_misread_rate_and_is_a_config_value() -> None:
    from pathlib import Path

    from ncbot.pipelines.config import load_config

    with pytest.raises(ValueError, match="misread_rate must be a number in \\(0, 1\\) with taken_squares=offered"):
        make_env("standard", taken_squares="offered")
    default = Path(__file__).resolve().parents[2] / "pipelines" / "configs" / "default.yaml"
    config = load_config(default, ["env.taken_squares=offered", "env.misread_rate=0.1"])
    assert (config.env.taken_squares, config.env.misread_rate) == ("offered", 0.1)
    with pytest.raises(ValueError, match="env\\.misread_rate") as error:
        load_config(default, ["env.taken_squares=offered"])
    assert "\n" not in str(error.value)
