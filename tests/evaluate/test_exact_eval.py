"""`ncbot eval --exhaustive`: the branch table covers every game of the random user once, with exact weights.

The check that can fail: for a robot with a fixed square preference (dqn_original, Q = a bias favouring the
lowest (or highest) free square), the exact win/draw/loss from the real env + greedy policy must equal an
independent expectimax over plain tic-tac-toe rules, to the last digit, from both seats.
"""
from __future__ import annotations

import json
from fractions import Fraction
from functools import lru_cache
from pathlib import Path

import pytest
import torch

from ncbot.modules.policies.policy import make_policies
from ncbot.modules.networks.qnet import make_qnet
from ncbot.pipelines.config import load_config
from ncbot.pipelines.evaluate.exact import BranchUser, branch_digits, exact_seat
from ncbot.pipelines.train.run import train
from tests.learning_helpers import ncbot, write_tiny_config

torch.set_num_threads(1)
LINES = ((0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6), (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6))


def winner(board: tuple[int, ...]) -> int:
    for a, b, c in LINES:
        if board[a] and board[a] == board[b] == board[c]:
            return board[a]
    return 0


@lru_cache(maxsize=None)
def reference(board: tuple[int, ...], robot_to_move: bool, lowest_first: bool) -> tuple[Fraction, Fraction, Fraction]:
    """(win, draw, loss) of the robot taking the lowest (or highest) free square vs a uniform random user."""
    won = winner(board)
    if won:
        return (Fraction(1), Fraction(0), Fraction(0)) if won == 1 else (Fraction(0), Fraction(0), Fraction(1))
    free = [cell for cell in range(9) if board[cell] == 0]
    if not free:
        return Fraction(0), Fraction(1), Fraction(0)
    if robot_to_move:
        cell = free[0] if lowest_first else free[-1]
        return reference(board[:cell] + (1,) + board[cell + 1:], False, lowest_first)
    total = [Fraction(0)] * 3
    for cell in free:
        child = reference(board[:cell] + (2,) + board[cell + 1:], True, lowest_first)
        total = [t + c / len(free) for t, c in zip(total, child)]
    return tuple(total)


def preference_policy(config, lowest_first: bool):
    """A greedy dqn_original policy whose Q-values are a fixed bias: moves above every other act, in cell order."""
    from ncbot.envs import make_env

    env = make_env("standard", batch_size=(1,), temporal=config.env.temporal)
    qnet = make_qnet(env.n_features, env.n_actions, [4])
    with torch.no_grad():
        for layer in qnet.module:
            if isinstance(layer, torch.nn.Linear):
                layer.weight.zero_()
                layer.bias.zero_()
        bias = qnet.module[-1].bias
        bias[env.cells:] = -torch.arange(env.n_actions - env.cells, dtype=torch.float32) - 100.0  # dialogue in act order
        order = torch.arange(env.cells, dtype=torch.float32)
        bias[: env.cells] = -order if lowest_first else order
    return make_policies(qnet, env.action_spec_unbatched, "none").greedy


@pytest.fixture(scope="module")
def tiny_config(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("exact")
    return load_config(write_tiny_config(folder), ["agent.name=dqn_original"])


def test_branch_table_enumerates_every_digit_sequence_once() -> None:
    digits = branch_digits((9, 7, 5, 3, 1))
    assert digits.shape == (945, 5)
    assert len({tuple(row) for row in digits.tolist()}) == 945
    assert int(digits[:, 0].max()) == 8 and int(digits[:, 4].max()) == 0
    assert BranchUser("robot").branches == 8 * 6 * 4 * 2
    with pytest.raises(ValueError, match="first must be one of robot, human, got 'middle'"):
        BranchUser("middle")


@pytest.mark.parametrize("seat", ["first", "second"])
@pytest.mark.parametrize("lowest_first", [True, False])
def test_exact_probabilities_equal_an_independent_expectimax(tiny_config, seat: str, lowest_first: bool) -> None:
    policy = preference_policy(tiny_config, lowest_first)
    result = exact_seat(tiny_config, policy, "robot" if seat == "first" else "human", dialogue_seeds=[0, 5])
    assert result.seat == seat
    win, draw, loss = reference((0,) * 9, seat == "first", lowest_first)
    assert result.win == pytest.approx(float(win), abs=1e-12)
    assert result.draw == pytest.approx(float(draw), abs=1e-12)
    assert result.loss == pytest.approx(float(loss), abs=1e-12)
    assert result.worst_loss == pytest.approx(float(loss), abs=1e-12)  # the policy ignores the dialogue draws
    assert result.branches == (384 if seat == "first" else 945)
    assert loss > 0 and result.losing_lines  # this naive robot does lose: the lost games are listed
    first_mover = "robot" if seat == "first" else "user"
    assert all(line.startswith(first_mover) for line in result.losing_lines)
    assert all(line.split(", ")[-1].startswith("user") for line in result.losing_lines)  # the user's move ends it


def test_exact_eval_refuses_ultimate(tiny_config) -> None:
    ultimate = load_config(write_tiny_config(Path(__import__("tempfile").mkdtemp())),
                           ["env.game=ultimate", "agent.name=dqn_original"])
    with pytest.raises(ValueError, match="3x3 games only"):
        exact_seat(ultimate, None, "robot", dialogue_seeds=[0])
    with pytest.raises(ValueError, match="at least one dialogue seed"):
        exact_seat(tiny_config, None, "robot", dialogue_seeds=[])


def test_cli_exhaustive_json_and_bad_input(tmp_path: Path) -> None:
    train(load_config(write_tiny_config(tmp_path), ["collector.total_frames=256"]), tmp_path / "run")
    checkpoint = tmp_path / "run" / "checkpoint.pt"
    result = ncbot("eval", str(checkpoint), "--exhaustive", "--dialogue-seeds", "1", "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) == {"first", "second"}
    for seat, branches in (("first", 384), ("second", 945)):
        row = data[seat]
        assert row["branches"] == branches and row["dialogue_seeds"] == [0]
        assert row["win"] + row["draw"] + row["loss"] == pytest.approx(1.0)
        assert row["task_success"] == pytest.approx(row["win"] + row["draw"])
    table = ncbot("eval", str(checkpoint), "--exhaustive", "--dialogue-seeds", "1", "--first", "human")
    assert table.returncode == 0 and "| second | 945 |" in table.stdout and "| first |" not in table.stdout
    bad = ncbot("eval", str(checkpoint), "--exhaustive", "--dialogue-seeds", "0")
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "dialogue-seeds" in bad.stderr
