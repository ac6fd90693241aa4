"""The env option `threat_features` (beyond the paper): the threat planes against a brute-force reading of the
board, their place in the observation and names, and a clear error where a typical-turn reader meets such an agent."""
from __future__ import annotations

import pytest
import torch

from envs import make_env
from envs.core import HUMAN, LINES_3X3, ROBOT, SUBGRID_CELLS
from envs.threat_features import threat_names, threat_planes

torch.set_num_threads(1)


def _brute_force(board: list[int], owners: list[int] | None) -> list[float]:
    """Each plane square by square: place the mark and look for a line (subgrids: give the subgrid and look)."""
    grids = [list(range(9))] if owners is None else [list(cells) for cells in SUBGRID_CELLS]
    cells = len(board)
    planes = []
    for player in (ROBOT, HUMAN):
        plane = [0.0] * cells
        for k, grid in enumerate(grids):
            if owners is not None and owners[k] != 0:
                continue
            own = {square for square, cell in enumerate(grid) if board[cell] == player}
            for square, cell in enumerate(grid):  # a line through the square whose two other squares are own
                if board[cell] == 0 and any(square in line and all(s in own for s in line if s != square)
                                            for line in LINES_3X3):
                    plane[cell] = 1.0
        planes += plane
    if owners is not None:
        for player in (ROBOT, HUMAN):
            won = {k for k in range(9) if owners[k] == player}
            planes += [1.0 if owners[k] == 0 and any(k in line and all(s in won | {k} for s in line)
                                                     for line in LINES_3X3) else 0.0 for k in range(9)]
    return planes


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_threat_planes_match_a_brute_force_reading_over_random_games(game: str) -> None:
    env = make_env(game, batch_size=(32,), threat_features=True, seed=3, first="alternate")
    cells = env.cells
    n = 2 * cells + (18 if cells == 81 else 0)
    assert env.feature_names[-n:] == threat_names(cells) and env.n_features == len(env.feature_names)
    generator = torch.Generator().manual_seed(0)
    td = env.reset()
    checked = 0
    for _ in range(60):
        boards, owners = env.boards.board.clone(), env.boards.owners.clone() if cells == 81 else None
        planes = threat_planes(boards, owners)
        assert torch.equal(td["observation"][:, -n:], planes)  # the observation carries them, last
        for row in range(0, 32, 4):
            expected = _brute_force(boards[row].tolist(), owners[row].tolist() if owners is not None else None)
            assert planes[row].tolist() == expected
            checked += sum(expected) > 0
        mask = td["action_mask"]
        action = torch.multinomial(mask.float() + 1e-9 * (~mask).float(), 1, generator=generator).squeeze(1)
        td = env.step(td.set("action", action))["next"]
        if td["done"].any():
            td = env.reset(td.clone().set("_reset", td["done"].clone()))
    assert checked > 10  # positions with threats were seen, not only empty boards


def test_an_agent_with_threat_features_is_refused_by_typical_turn_readers() -> None:
    from modules.guided_mcts import GuidedMCTS, TurnFeatures
    from modules.qnet import make_qnet

    env = make_env("ultimate", batch_size=(1,), threat_features=True)
    qnet = make_qnet(env.n_features, env.n_actions, [8])
    with pytest.raises(ValueError, match="reads 469 features, a typical game turn has 289"):
        GuidedMCTS(qnet.module, TurnFeatures("ultimate", True), "ultimate", "anywhere", 4)
    with pytest.raises(ValueError, match="must be true or false"):
        make_env("ultimate", batch_size=(1,), threat_features="yes")
