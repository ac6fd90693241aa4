"""The env option `threat_features` (beyond the paper): the threat planes against a brute-force reading of the
board, their place in the observation and names, and a clear error where a typical-turn reader meets such an agent."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from ncbot.envs import make_env
from ncbot.envs.core import HUMAN, LINES_3X3, ROBOT, SUBGRID_CELLS
from ncbot.envs.threat_features import threat_names, threat_planes

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


def _seen_by(board: torch.Tensor, owners: torch.Tensor | None, player: int):
    """The position from ``player``'s side: its marks (and subgrids) as the robot's (code 1), the other's as 2."""
    def swap(codes: torch.Tensor) -> torch.Tensor:
        return codes if player == ROBOT else torch.where((codes == ROBOT) | (codes == HUMAN), 3 - codes, codes)
    return swap(board), None if owners is None else swap(owners)


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_typical_turn_features_carry_the_threat_planes_of_the_position_from_the_side_to_move(game: str) -> None:
    """The search's and self-play's features (``TurnFeatures``) of real positions: the same planes as the env's
    observation (robot to move), seen from the other side too, and the one-position paths (cell lists, the search's
    bitboards) equal to the batch."""
    from tests.envs.helpers import search_of as make_bits
    from ncbot.modules.search.guided_mcts import TurnFeatures

    env = make_env(game, batch_size=(16,), threat_features=True, free_move="open_subgrids", seed=5, first="alternate")
    features = TurnFeatures(game, True, "open_subgrids", threats=True)
    engine = make_bits(game, "open_subgrids")
    assert features.n_features == env.n_features and features.threat_plane == env.n_features - (2 * env.cells + (18 if game == "ultimate" else 0))
    generator = torch.Generator().manual_seed(1)
    td = env.reset()
    checked = 0
    for _ in range(50):
        boards = env.boards.board.clone()
        owners = env.boards.owners.clone() if game == "ultimate" else None
        last = torch.full((16,), -1)
        for player in (ROBOT, HUMAN):
            seen = features.batch(boards, player, last)[:, features.threat_plane:]
            expected = threat_planes(*_seen_by(boards, owners, player))
            assert torch.equal(seen, expected)
            for row in range(0, 16, 5):
                cells = boards[row]
                own = (cells == player).nonzero().flatten().tolist()
                other = ((cells != 0) & (cells != player)).nonzero().flatten().tolist()
                one = features(own, other, -1)  # the cell-list path: owners read from the board
                assert one.dtype == np.float32 and torch.equal(torch.from_numpy(one[features.threat_plane:]), expected[row])
                pos = engine.from_board(cells.tolist(), player, -1, None if owners is None else owners[row].tolist())
                searched = features(own, other, -1, pos)  # the search's path: the bitboard's exact owners
                assert torch.equal(torch.from_numpy(searched), torch.from_numpy(one))
                checked += int(expected[row].sum() > 0)
        mask = td["action_mask"]
        action = torch.multinomial(mask.float() + 1e-9 * (~mask).float(), 1, generator=generator).squeeze(1)
        td = env.step(td.set("action", action))["next"]
        if td["done"].any():
            td = env.reset(td.clone().set("_reset", td["done"].clone()))
    assert checked > 20


def test_a_threat_reading_agent_is_searched_and_a_mismatched_reader_is_refused() -> None:
    from ncbot.envs.opponents import make_opponent
    from ncbot.envs.opponents.arena import play_match
    from ncbot.modules.search.guided_mcts import GuidedMCTS, QMCTSOpponent, TurnFeatures
    from ncbot.modules.networks.qnet import make_qnet

    env = make_env("ultimate", batch_size=(1,), threat_features=True)
    qnet = make_qnet(env.n_features, env.n_actions, [8])
    with pytest.raises(ValueError, match="reads 469 features, a typical game turn of this env has 289"):
        GuidedMCTS(qnet.module, TurnFeatures("ultimate", True), "ultimate", "anywhere", 4)
    search = GuidedMCTS(qnet.module, TurnFeatures("ultimate", True, threats=True), "ultimate", "anywhere", 8)
    result = play_match(QMCTSOpponent(search, "ultimate", "anywhere", 0), make_opponent("random", game="ultimate"), 2, seed=0)
    assert result.games == 2 and result.first_wins + result.second_wins + result.draws == 2
    with pytest.raises(ValueError, match="must be true or false"):
        make_env("ultimate", batch_size=(1,), threat_features="yes")


def test_a_run_with_threat_planes_self_plays_and_is_searched_at_eval(tmp_path) -> None:
    """End to end: self-play snapshots read the planes while training, ``ncbot eval --search`` plays with them."""
    import json

    from tests.learning_helpers import ncbot, write_tiny_config

    config = write_tiny_config(tmp_path, env={"options": {"threat_features": True}},
                               selfplay={"enabled": True, "snapshot_every_frames": 128, "random_share": 0.0})
    done = ncbot("train", str(config), "--out", str(tmp_path / "run"))
    assert done.returncode == 0, done.stderr
    summary = json.loads((tmp_path / "run" / "eval.json").read_text())
    assert summary["selfplay"]["snapshots_taken"] >= 2
    done = ncbot("eval", str(tmp_path / "run" / "checkpoint.pt"), "--search", "4", "--games", "4", "--json")
    assert done.returncode == 0, done.stderr
    metrics = json.loads(done.stdout.strip().splitlines()[-1])
    assert metrics["search_decisions"] > 0
