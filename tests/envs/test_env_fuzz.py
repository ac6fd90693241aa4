"""Fuzz: 1,000,000 random action indices across both games, masked and unmasked, plus out-of-range ones.

No crash; every act outside the mask earns the paper's -5 and leaves the board alone; out-of-range indices
raise a clear ValueError and leave the env usable; the rules' invariants hold at every step.
"""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from ncbot.envs import make_env
from ncbot.envs.rules import LINES_3X3

torch.set_num_threads(1)
LINES = torch.tensor(LINES_3X3)
TOTAL_ACTIONS = 1_000_000


def has_line(grid: torch.Tensor, player: int) -> torch.Tensor:
    """(N,) whether each 3x3 grid (N, 9) holds a line of ``player`` (independent of the engine's tables)."""
    return (grid[:, LINES] == player).all(-1).any(-1)


def check_invariants(env, td: TensorDict, game: str) -> None:
    board = td["board"].long()
    robot, human = (board == 1).sum(1), (board == 2).sum(1)
    first = td["robot_first"].squeeze(1)
    assert ((robot - human) == torch.where(first, (robot + human) % 2, -((robot + human) % 2))).all()
    assert td["action_mask"].any(1).all()
    assert (td["lookahead_reward"][~td["action_mask"]] == -5).all()
    outcome = td["outcome"].squeeze(1).long()
    if game == "standard":
        robot_line, human_line = has_line(board, 1), has_line(board, 2)
        assert not (robot_line & human_line).any(), "two winners"
        assert (robot_line == (outcome == 1)).all() and (human_line == (outcome == 2)).all()
    else:  # subgrid owners live in the env (they depend on move order); finished games were reset already
        live = ~td["done"].squeeze(1)
        owners = env.boards.owners[live]
        robot_meta, human_meta = has_line(owners, 1), has_line(owners, 2)
        assert not (robot_meta & human_meta).any(), "two winners"
        assert (robot_meta == (outcome[live] == 1)).all() and (human_meta == (outcome[live] == 2)).all()


RUNS = [("standard", "anywhere", 2000, 250), ("ultimate", "anywhere", 1000, 250), ("ultimate", "open_subgrids", 1000, 250)]
assert sum(batch * steps for _, _, batch, steps in RUNS) == TOTAL_ACTIONS


@pytest.mark.parametrize("game,free_move,batch,steps", RUNS)
def test_fuzz_random_actions(game: str, free_move: str, batch: int, steps: int) -> None:
    env = make_env(game, batch_size=(batch,), free_move=free_move, first="random", seed=13)
    generator = torch.Generator().manual_seed(0)
    td = env.reset()
    unmasked = torch.arange(batch) % 2 == 0  # half the games act blindly, half from the mask
    refused = 0
    for _ in range(steps):
        masked_choice = (torch.rand(td["action_mask"].shape, generator=generator) + td["action_mask"]).argmax(1)
        blind_choice = torch.randint(0, env.n_actions, (batch,), generator=generator)
        action = torch.where(unmasked, blind_choice, masked_choice)
        allowed = td["action_mask"].gather(1, action.unsqueeze(1)).squeeze(1)
        board_before = td["board"].clone()
        td["action"] = action
        step, td = env.step_and_maybe_reset(td)
        reward = step["next", "reward"].squeeze(1)
        assert (reward[~allowed] == -5).all()
        assert torch.equal(step["next", "board"][~allowed], board_before[~allowed])
        assert torch.isin(reward, torch.tensor([-5.0, 0.0, 1.0, 5.0])).all()
        check_invariants(env, step["next"], game)
        refused += int((~allowed).sum())
    assert refused > 0


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_out_of_range_indices_raise_and_leave_env_usable(game: str) -> None:
    env = make_env(game, batch_size=(4,))
    td = env.reset()
    generator = torch.Generator().manual_seed(1)
    for bad in torch.cat([torch.randint(-10**6, 0, (50,), generator=generator), torch.randint(env.n_actions, 10**6, (50,), generator=generator)]).tolist():
        action = (torch.rand(td["action_mask"].shape, generator=generator) + td["action_mask"]).argmax(1)
        action[int(bad) % 4] = bad
        with pytest.raises(ValueError, match=rf"action {bad} is out of range: expected 0\.\.{env.n_actions - 1}"):
            env.step(td.clone().set("action", action))
    td = env.rand_action(td)
    assert env.step(td)["next", "turn"].eq(1).all()
