"""The Ultimate value network: features that follow the board's symmetries, a training that learns from UCT labels
and reproduces by seed, a search that uses it, and one-line errors for every bad --value."""
from __future__ import annotations

import json
import random

import pytest
import torch

from ncbot.envs.opponents import make_opponent
from ncbot.envs.opponents.arena import play_match
from ncbot.envs.opponents.bitboards import CELL_OF, ONGOING, SQUARE_OF, SUBGRID_OF
from tests.envs.helpers import search_of as make_bits
from ncbot.modules.search.guided_mcts import GuidedMCTS, QMCTSOpponent, TurnFeatures
from ncbot.modules.replay.symmetry import square_symmetries
from ncbot.modules.search.value_net import N_FEATURES, ValueNetEvaluator, feature_symmetries, load_value_net, position_features
from ncbot.pipelines.agents import load_agent
from ncbot.pipelines.config import load_config
from ncbot.pipelines.train.run import train
from ncbot.pipelines.train.value_training import train_value
from tests.learning_helpers import ncbot, write_tiny_config

torch.set_num_threads(1)


def random_positions(free_move: str, games: int, seed: int) -> list[tuple[tuple, list[int]]]:
    """(position, the cells played to reach it) along random games."""
    engine, rng = make_bits("ultimate", free_move), random.Random(seed)
    out = []
    for _ in range(games):
        pos, cells = engine.from_board([0] * 81, 1, -1), []
        while engine.result(pos) == ONGOING:
            move = rng.choice(engine.moves(pos))
            pos, cells = engine.play(pos, move), cells + [move]
            out.append((pos, list(cells)))
    return out


@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_features_follow_the_board_symmetries(free_move):
    """Replaying a game turned by symmetry g gives the features of the original position gathered by maps[g]."""
    engine, maps, images = make_bits("ultimate", free_move), feature_symmetries(), square_symmetries(3).tolist()
    for pos, cells in random_positions(free_move, 3, seed=4)[::7]:
        features = torch.tensor(position_features(pos))
        assert features.shape == (N_FEATURES,)
        for g, image in enumerate(images):
            turned = engine.from_board([0] * 81, 1, -1)
            for cell in cells:
                turned = engine.play(turned, CELL_OF[image[SUBGRID_OF[cell]]][image[SQUARE_OF[cell]]])
            assert torch.equal(torch.tensor(position_features(turned)), features[maps[g]]), (g, cells)


def test_features_are_seen_from_the_side_to_move():
    engine = make_bits("ultimate")
    start = engine.from_board([0] * 81, 1, -1)
    after = engine.play(start, 40)  # the centre of the centre subgrid: the next player must play there
    features = position_features(after)
    assert features[81 + 9 * SUBGRID_OF[40] + SQUARE_OF[40]] == 1.0 and sum(features[:81]) == 0  # the other side's mark
    assert features[189 + 4] == 1.0 and features[198] == 0.0  # sent to subgrid 4, not a free move
    assert position_features(start)[198] == 1.0  # the opening move is free
    board = [0] * 81
    for k, p, code in ((0, 0, 1), (0, 1, 1), (4, 4, 2), (8, 8, 2)):  # X holds two of subgrid 0's top row
        board[CELL_OF[k][p]] = code
    threats = position_features(engine.from_board(board, 1, CELL_OF[8][8]))[199:]
    assert threats[:9] == [1.0] + [0.0] * 8 and threats[9:18] == [0.0] * 9  # the mover's threat, none for O
    assert threats[18:] == [0.0, 0.0]  # owning subgrid 0 would not complete a line of subgrids yet


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Two small real trainings with one seed (UCT labels) and one with another (~10 s each)."""
    root = tmp_path_factory.mktemp("value")
    reports = {name: train_value(str(root / name), positions=6000, simulations=50, hidden=[64, 64], epochs=10,
                                 seed=seed, progress=False)
               for name, seed in (("a", 3), ("again", 3), ("other", 4))}
    return root, reports


def test_training_learns_from_the_labels_and_reproduces_by_seed(trained):
    root, reports = trained
    report = reports["a"]
    assert report["val_positions"] > 0 and report["train_positions"] + report["val_positions"] == 6000
    # on held-out games, clearly better than predicting the mean label (0.59-0.75 of its error over seeds 3-5)
    assert report["val_mse"] < 0.9 * report["val_mse_of_mean_label"]
    first = load_value_net(str(root / "a" / "value.pt"), "anywhere").state_dict()
    again = load_value_net(str(root / "again" / "value.pt"), "anywhere").state_dict()
    other = load_value_net(str(root / "other" / "value.pt"), "anywhere").state_dict()
    assert all(torch.equal(first[k], again[k]) for k in first)
    assert not all(torch.equal(first[k], other[k]) for k in first)
    assert (root / "a" / "value.png").stat().st_size > 0
    assert json.loads((root / "a" / "value.json").read_text())["history"][-1]["val_mse"] == report["val_mse"]


def test_a_second_run_reuses_the_labelled_positions(trained):
    root, reports = trained
    cache = root / "a" / "positions.pt"
    stamp = cache.stat().st_mtime_ns
    report = train_value(str(root / "a"), positions=6000, simulations=50, hidden=[64, 64], epochs=10, seed=3,
                         progress=False)
    assert cache.stat().st_mtime_ns == stamp and report["val_mse"] == reports["a"]["val_mse"]


@pytest.fixture(scope="module")
def ultimate_checkpoint(tmp_path_factory) -> str:
    folder = tmp_path_factory.mktemp("value_agent")
    config = load_config(write_tiny_config(folder, env={"game": "ultimate"}, eval={"games": 8, "periodic_games": 8}))
    train(config, folder / "run")
    return str(folder / "run" / "checkpoint.pt")


def test_the_search_scores_leaves_by_the_network_and_beats_random(trained, ultimate_checkpoint):
    root, _ = trained
    config, greedy = load_agent(ultimate_checkpoint)
    net = load_value_net(str(root / "a" / "value.pt"), "anywhere")
    features = TurnFeatures("ultimate", config.env.temporal)

    def match(seed: int):
        search = GuidedMCTS(greedy[0].module, features, "ultimate", simulations=16, value_net=net)
        assert isinstance(search.evaluator, ValueNetEvaluator)
        return play_match(QMCTSOpponent(search, "ultimate", "anywhere", seed), make_opponent("random", game="ultimate"),
                          4, seed=seed)

    first, again = match(2), match(2)
    assert (first.first_wins, first.marks) == (again.first_wins, again.marks)  # reproducible by seed
    assert first.first_wins >= 3
    evaluator = ValueNetEvaluator(GuidedMCTS(greedy[0].module, features, "ultimate", simulations=4), net)
    for pos, _ in random_positions("anywhere", 1, seed=9)[:20]:
        assert 0.0 <= evaluator.value(pos) <= 1.0


def test_ncbot_eval_and_ladder_take_a_value_network(trained, ultimate_checkpoint, tmp_path):
    root, _ = trained
    value = str(root / "a" / "value.pt")
    done = ncbot("eval", ultimate_checkpoint, "--search", "4", "--value", value, "--games", "2", "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1])["search_decisions"] > 0
    ladder = ncbot("ladder", ultimate_checkpoint, "--search", "4", "--value", value, "--opponents", "random",
                   "--games", "1", "--out", str(tmp_path / "ladder"))
    assert ladder.returncode == 0, ladder.stderr
    assert json.loads((tmp_path / "ladder" / "ladder.json").read_text())["value"] == value
    assert "leaves by value net value.pt" in ladder.stdout


def test_bad_value_options_are_one_line_errors(trained, ultimate_checkpoint, tmp_path):
    root, _ = trained
    value = str(root / "a" / "value.pt")
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(b"not a network")
    other_rule = train_value(str(tmp_path / "open"), free_move="open_subgrids", positions=60, simulations=5,
                             hidden=[8], epochs=1, seed=0, progress=False)
    assert other_rule["free_move"] == "open_subgrids"
    standard = load_config(write_tiny_config(tmp_path, eval={"games": 8, "periodic_games": 8}))
    assert standard.env.game == "standard"
    train(standard, tmp_path / "standard")
    cases = [
        (("eval", str(tmp_path / "standard" / "checkpoint.pt"), "--search", "4", "--value", value, "--games", "1"),
         "value networks score Ultimate positions; this agent plays standard"),
        (("eval", ultimate_checkpoint, "--value", value), "give --search N too"),
        (("eval", ultimate_checkpoint, "--search", "4", "--value", str(tmp_path / "missing.pt")), "not found"),
        (("eval", ultimate_checkpoint, "--search", "4", "--value", str(corrupt), "--games", "1"), "corrupt or not ncbot's"),
        (("ladder", ultimate_checkpoint, "--search", "4", "--value", str(tmp_path / "open" / "value.pt"),
          "--opponents", "random", "--games", "1"), "trained on the 'open_subgrids' free-move rule"),
        (("train-value", "--out", str(tmp_path / "bad"), "--free-move", "nowhere"), "--free-move must be one of"),
        (("train-value", "--out", str(tmp_path / "bad"), "--hidden", "wide"), "--hidden must be comma-separated"),
        (("train-value", "--out", str(tmp_path / "bad"), "--positions", "3"), "--positions must be at least 10"),
    ]
    for args, message in cases:
        done = ncbot(*args)
        assert done.returncode == 2 and message in done.stderr, (args, done.stderr)
        assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
