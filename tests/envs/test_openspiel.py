"""OpenSpiel's bots as opponents: the rules agree game for game, moves translate both ways, mismatches refuse.

Skipped only when the optional package open_spiel is missing (``pip install -e '.[all]'`` or ``'.[openspiel]'`` installs it).
"""
from __future__ import annotations

import random
import subprocess
import sys
from pathlib import Path

import pytest
import torch

pyspiel = pytest.importorskip("pyspiel")

from ncbot.envs.opponents import make_opponent  # noqa: E402
from ncbot.envs.opponents.arena import play_match  # noqa: E402
from ncbot.envs.opponents.openspiel import apply_cell, legal_cells, load_openspiel_game  # noqa: E402
from ncbot.envs.core import SUBGRID_OF_CELL  # noqa: E402
from ncbot.envs.games import make_game  # noqa: E402

OUTCOMES = {1.0: "x", -1.0: "o", 0.0: "draw"}  # OpenSpiel's return of player 0 (x) -> our outcome


def _random_games(game: str, free_move: str, games: int, seed: int) -> tuple[int, int]:
    """Play uniformly random games of OUR rules through both engines; (positions compared, positions that differ).

    A position differs when the legal cells or the end of the game disagree; play stops at the first one."""
    rng = random.Random(seed)
    ours = make_game(game, free_move)
    theirs = pyspiel.load_game({"standard": "tic_tac_toe", "ultimate": "ultimate_tic_tac_toe"}[game])
    compared = differing = 0
    for _ in range(games):
        state, os_state = ours.new(), theirs.new_initial_state()
        while True:
            compared += 1
            if ours.legal(state) != legal_cells(os_state, game) or ours.is_over(state) != os_state.is_terminal():
                differing += 1
                break
            if ours.is_over(state):
                assert ours.outcome(state) == OUTCOMES[os_state.returns()[0]]
                break
            cell = rng.choice(ours.legal(state))
            state = ours.play(state, cell)
            apply_cell(os_state, game, cell)
    return compared, differing


@pytest.mark.parametrize("game,free_move,games", [("standard", "anywhere", 500), ("ultimate", "open_subgrids", 300)])
def test_openspiel_rules_equal_ours_on_random_games(game, free_move, games) -> None:
    compared, differing = _random_games(game, free_move, games, seed=1)
    assert differing == 0 and compared > games * (8 if game == "standard" else 40)


def test_openspiel_ultimate_is_not_the_paper_rule() -> None:
    """Under ``anywhere`` a player sent to a decided subgrid may also play inside decided subgrids; OpenSpiel may not."""
    compared, differing = _random_games("ultimate", "anywhere", 100, seed=2)
    assert differing > 50  # most random games reach a redirect to a decided subgrid


def test_openspiel_free_move_after_a_decided_subgrid_is_open_subgrids() -> None:
    """Sent to a decided subgrid: both allow every open subgrid's squares; OpenSpiel refuses a decided one's."""
    rng = random.Random(3)
    ours = make_game("ultimate", "open_subgrids")
    theirs = load_openspiel_game("ultimate", "open_subgrids")
    checked = 0
    while checked < 20:
        state, os_state = ours.new(), theirs.new_initial_state()
        while not ours.is_over(state):
            cell = rng.choice(ours.legal(state))
            state = ours.play(state, cell)
            apply_cell(os_state, "ultimate", cell)
            decided = [k for k in range(9) if ours.subgrid_owner(state, k) is not None]
            if not ours.is_over(state) and ours.forced_subgrid(state) is None and decided:
                assert legal_cells(os_state, "ultimate") == ours.legal(state)
                empty_decided = [c for c in range(81) if state.board[c] == 0 and SUBGRID_OF_CELL[c] in decided]
                if empty_decided:
                    with pytest.raises(ValueError, match="refuses cell"):
                        apply_cell(os_state.clone(), "ultimate", empty_decided[0])  # `anywhere` would allow it
                    checked += 1


@pytest.mark.parametrize("game,free_move", [("standard", "anywhere"), ("ultimate", "open_subgrids")])
def test_openspiel_mcts_plays_legal_moves_from_both_seats_and_beats_random(game, free_move) -> None:
    games = 12 if game == "standard" else 4
    bot = make_opponent("openspiel-mcts:30", game=game, free_move=free_move, seed=0)
    rand = make_opponent("random", game=game, free_move=free_move, seed=1)
    first = play_match(bot, rand, games, seed=3, free_move=free_move)  # the arena referees with envs.rules
    second = play_match(rand, bot, games, seed=4, free_move=free_move)
    assert first.second_wins + second.first_wins <= 2
    assert first.first_score + second.second_score >= 1.5


def test_openspiel_mcts_same_seed_same_moves() -> None:
    results = []
    for _ in range(2):
        bot = make_opponent("openspiel-mcts:20", game="ultimate", free_move="open_subgrids", seed=5)
        rand = make_opponent("random", game="ultimate", free_move="open_subgrids", seed=6)
        result = play_match(rand, bot, 3, seed=7, free_move="open_subgrids")
        results.append((result.first_wins, result.second_wins, result.draws, result.marks))
    assert results[0] == results[1]


def test_openspiel_mcts_as_the_envs_user() -> None:
    """The dialogue env asks it for the user's squares (robot-first and human-first games, partial batches)."""
    from ncbot.envs import make_env

    env = make_env("ultimate", batch_size=(4,), free_move="open_subgrids", opponent="openspiel-mcts:5", seed=0,
                   first="alternate")
    td, finished = env.reset(), 0
    for _ in range(200):
        td = env.rand_action(td)
        out, td = env.step_and_maybe_reset(td)
        finished += int(out["next", "done"].sum())
    assert finished >= 2  # whole games, with every user square checked against our rules before and after


def test_openspiel_refuses_a_position_it_did_not_follow() -> None:
    bot = make_opponent("openspiel-mcts:5", game="standard", seed=0)
    boards = torch.tensor([[1, 2, 1, 0, 0, 0, 0, 0, 0]], dtype=torch.int8)
    legal = boards == 0
    with pytest.raises(ValueError, match="did not see arise"):
        bot.select(boards, torch.tensor([2]), legal, 2)


def test_openspiel_errors_are_one_line() -> None:
    with pytest.raises(ValueError, match="open_subgrids"):
        make_opponent("openspiel-mcts:10", game="ultimate", free_move="anywhere")
    with pytest.raises(ValueError, match="positive simulation count"):
        make_opponent("openspiel-mcts:zero")
    run = subprocess.run([sys.executable, "-m", "ncbot", "match", "openspiel-mcts:10", "random", "--game",
                          "ultimate", "--games", "2"], capture_output=True, text=True)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert "uses the 'open_subgrids' rule, not 'anywhere'" in run.stderr.strip().splitlines()[-1]


def test_missing_open_spiel_is_one_clear_error(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "pyspiel", None)  # what an environment without the wheel sees on import
    with pytest.raises(ValueError, match=r"pip install 'ncbot\[openspiel\]'"):
        make_opponent("openspiel-mcts:10", game="standard")


BENCH = Path(__file__).resolve().parents[2] / "bench" / "time_to_quality.py"


def test_time_to_quality_trains_and_evaluates_openspiel_dqn(tmp_path) -> None:
    """The DQN side of the bench for real (2 s of training): snapshots on its clock, evaluated by our referee."""
    pytest.importorskip("tree")  # open_spiel.python.pytorch.dqn needs dm-tree (in the openspiel extra)
    from ncbot.pipelines.evaluate.openspiel_dqn import dqn_worker, evaluate_dqn, first_time

    out = tmp_path / "dqn.pt"
    dqn_worker("standard", cap=2.0, clock_name="wall_time", every=0.5, opponent="random", hidden=[32, 32], out=out,
                     seed=0)
    data = torch.load(out, weights_only=True)
    times = [s["wall_time"] for s in data["snapshots"]]
    assert len(times) >= 3 and times == sorted(times) and times[-1] >= 2.0
    assert data["settings"] == {"hidden_layers_sizes": [32, 32], "replay_buffer_capacity": 10_000}
    success = evaluate_dqn(data["snapshots"][-1], data, "standard", 60, seed=1)
    assert set(success) == {"first", "second"} and all(0.0 <= v <= 1.0 for v in success.values())
    from open_spiel.python.pytorch.dqn import MLP

    ultimate = {"q": [MLP(254, [32, 32], 9).state_dict() for _ in range(2)]}  # OpenSpiel's Ultimate observation: 254
    assert set(evaluate_dqn(ultimate, {**data, "state_size": 254}, "ultimate", 3, seed=2)) == {"first", "second"}
    points = [{"wall_time": 1.0, "first": 0.96, "second": 0.90}, {"wall_time": 2.0, "first": 0.97, "second": 0.99},
              {"wall_time": 3.0, "first": 1.0, "second": 0.996}]
    assert first_time(points, 0.95) == 2.0 and first_time(points, 0.995) == 3.0
    assert first_time(points[:2], 0.995) is None


def test_time_to_quality_exact_dqn_score_equals_an_enumeration_with_our_rules() -> None:
    """`--exact`: the DQN's exact task success per seat, checked on a network that always takes its lowest legal
    cell (zero weights, biases falling with the action) against the same game tree walked with our own rules."""
    pytest.importorskip("tree")
    from open_spiel.python.pytorch.dqn import MLP

    from ncbot.envs.rules import Standard

    network = MLP(27, [32, 32], 9)
    with torch.no_grad():
        for parameter in network.parameters():
            parameter.zero_()
        [*network.parameters()][-1].copy_(-torch.arange(9, dtype=torch.float32))
    rules = Standard()

    def loss(state, mark: str) -> float:
        outcome = rules.outcome(state)
        if outcome is not None:
            return 1.0 if outcome not in (mark, "draw") else 0.0
        moves = [min(rules.legal(state))] if rules.to_move(state) == mark else rules.legal(state)
        return sum(loss(rules.play(state, move), mark) for move in moves) / len(moves)

    meta = {"state_size": 27, "num_actions": 9, "settings": {"hidden_layers_sizes": [32, 32]}}
    from ncbot.pipelines.evaluate.openspiel_dqn import exact_dqn

    success = exact_dqn({"q": [network.state_dict()] * 2}, meta)
    expected = {"first": 1 - loss(rules.new(), "x"), "second": 1 - loss(rules.new(), "o")}
    assert success == pytest.approx(expected, abs=1e-12)
    assert 0.3 < expected["second"] < 0.99  # a weak fixed policy: the comparison is not trivially 1 == 1


def test_ladder_against_openspiel_mcts_on_open_subgrids(tmp_path) -> None:
    """`ncbot ladder --opponents openspiel-mcts:N`: a real (untrained) Ultimate checkpoint of the open_subgrids rule."""
    from ncbot.envs import make_env
    from ncbot.modules.networks.qnet import make_qnet
    from ncbot.pipelines.checkpoint import FORMAT, atomic_save
    from ncbot.pipelines.config import RunConfig
    from ncbot.pipelines.evaluate.ladder import check_goals, run_ladder

    config = RunConfig()
    config.env.game, config.env.free_move = "ultimate", "open_subgrids"
    env = make_env("ultimate", batch_size=(1,), free_move="open_subgrids")
    qnet = make_qnet(env.n_features, env.n_actions, config.agent.hidden)
    path = tmp_path / "run" / "checkpoint.pt"
    atomic_save({"format": FORMAT, "config": config.to_dict(), "n_features": env.n_features,
                 "n_actions": env.n_actions, "qnet": qnet.state_dict()}, path)
    result = run_ladder(str(path), games=2, opponents=["openspiel-mcts:3"], seed=0, progress=False)
    assert [(r["opponent"], r["seat"], r["games"]) for r in result["rows"]] == [
        ("openspiel-mcts:3", "first", 2), ("openspiel-mcts:3", "second", 2)]
    rows = [{"opponent": "openspiel-mcts:1000", "seat": seat, "games": 10, "score": score}
            for seat, score in (("first", 0.6), ("second", 0.3))]
    assert check_goals("ultimate", rows) == [{"goal": "score >= 0.5 against openspiel-mcts:1000", "met": False,
                                              "value": "0.450 [0.258, 0.658] over 20 games", "verdict": "undecided"}]


def test_time_to_quality_search_option_errors_stop_before_any_training(tmp_path) -> None:
    """`--ours-search N --ours-value V`: bad options stop before any training with one line, exit 2 (the bench run
    as a script, as it is used)."""
    from ncbot.modules.search.value_net import make_value_net, value_checkpoint

    value = tmp_path / "value" / "value.pt"
    value.parent.mkdir()
    torch.save(value_checkpoint(make_value_net([8]), [8], "open_subgrids", {}), value)
    (value.parent / "value.json").write_text('{"labelling_cpu_s": 10.5, "training_cpu_s": 1.5}')
    cases = [
        (["--game", "ultimate", "--ours-value", str(value)], "give --ours-search N too"),
        (["--game", "ultimate", "--ours-search", "0"], "--ours-search must be a positive number"),
        (["--ours-search", "4", "--ours-value", str(value)], "--ours-value is for Ultimate"),
        (["--game", "ultimate", "--ours-search", "4", "--ours-value", str(tmp_path / "none.pt")], "not found"),
        (["--game", "ultimate", "--free-move", "anywhere", "--ours-search", "4", "--ours-value", str(value)],
         "trained on the 'open_subgrids' free-move rule"),
    ]
    runs = [subprocess.Popen([sys.executable, str(BENCH), *argv, "--only", "ours", "--out", str(tmp_path / "out")],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for argv, _ in cases]
    for (argv, message), run in zip(cases, runs):
        _, err = run.communicate(timeout=120)
        error = err.strip().splitlines()[-1]
        assert run.returncode == 2 and message in error, (argv, error)
    assert not (tmp_path / "out").exists()
