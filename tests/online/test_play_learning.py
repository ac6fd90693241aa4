"""Play that learns from play (`ncbot.pipelines.online`): logged games read back into the learner's transitions, the
model of the person, the bounded update that is kept or rolled back, one person's learning resumed after a crash,
and `ncbot learn LOGS`. Real env games against real opponents, logged to MCAP and read back; no rendering."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type, step_mdp

from ncbot.logs import EpisodeLogger
from ncbot.pipelines.config import load_config
from ncbot.pipelines.online import agent_parts
from ncbot.pipelines.online.learning import LearnSettings, PersonLearning
from ncbot.pipelines.online.logged import game_transitions, read_games
from ncbot.envs.games import make_game
from ncbot.pipelines.online.person_model import PersonModel, fork_cells, move_features, person_moves
from ncbot.pipelines.online.play_learner import PlayLearner, PlayLearning
from ncbot.pipelines.online.simulated import play_logged_game
from ncbot.pipelines.run_env import make_run_env
from ncbot.pipelines.train.run import train
from ncbot.vision.online import ReaderLearning
from tests.learning_helpers import ncbot_here, write_tiny_config

torch.set_num_threads(1)
SMALL = PlayLearning(updates=4, batch_size=32, sim_frames=64, gate_games=20)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("agent")
    train(load_config(write_tiny_config(folder), ["collector.total_frames=256"]), folder / "run")
    return folder / "run" / "checkpoint.pt"


def logged_games(checkpoint: Path, folder: Path, opponent: str, games: int, seed: int = 0) -> list:
    config, data = agent_parts.load_saved_agent(checkpoint)
    _, policies, _ = agent_parts.build_agent(config, data, 0)
    with EpisodeLogger(folder) as log:
        for game in range(games):
            play_logged_game(config, policies.greedy, log, opponent=opponent, seed=seed + game,
                             first="robot" if game % 2 == 0 else "human", agent_name="test")
    return list(read_games(folder))


def test_a_logged_game_gives_back_the_transitions_the_learner_took_live(checkpoint: Path, tmp_path: Path) -> None:
    config, data = agent_parts.load_saved_agent(checkpoint)
    _, policies, _ = agent_parts.build_agent(config, data, 0)
    env = make_run_env(config.env, batch_size=1, seed=5, first="human", opponent="rule")
    steps = []
    with EpisodeLogger(tmp_path / "log") as log, set_exploration_type(ExplorationType.DETERMINISTIC):
        td = env.reset()
        while True:
            td = env.step(policies.greedy(td))
            log.record_steps(td, phase="robot", agent="test", seed=5, env=env)
            steps.append(td.clone())
            if bool(td["next", "done"].item()):
                break
            td = step_mdp(td)
    live = agent_parts.buffer_rows(torch.stack(steps, dim=1), config)
    (game,) = read_games(tmp_path / "log")
    logged = agent_parts.buffer_rows(game_transitions(game, data["n_features"], data["n_actions"]), config)
    assert len(logged) == len(live) == len(steps)
    for key in ("action", ("next", "learning_reward"), ("next", "done"), ("next", "terminated")):
        assert torch.equal(logged[key], live[key]), key
    # after the last decision nothing is logged: its next state is never bootstrapped from (done)
    assert torch.equal(logged["next", "bootstrap_mask"][:-1], live["next", "bootstrap_mask"][:-1])
    assert torch.allclose(logged["observation"], live["observation"], atol=2e-3)  # logged as float16
    assert torch.allclose(logged["next", "observation"][:-1], live["next", "observation"][:-1], atol=2e-3)


def test_the_model_of_a_person_who_wins_and_blocks_learns_to_win_and_block(checkpoint: Path, tmp_path: Path) -> None:
    config, _ = agent_parts.load_saved_agent(checkpoint)
    moves = {}
    for opponent in ("rule", "random"):
        games = logged_games(checkpoint, tmp_path / opponent, opponent, 24)
        moves[opponent] = [m for g in games for m in person_moves(g.extra["settled_moves"], g.summary["seat"] == "first",
                                                                  "standard", config.env.free_move)]
    rule, uniform = PersonModel(), PersonModel()
    assert rule.fit(moves["rule"]) > PersonModel().log_likelihood(moves["rule"]) + 0.1, "explains the moves better"
    uniform.fit(moves["random"])
    assert abs(uniform.weights[:2]).max() < rule.weights[:2].min(), "the random user's model stays near uniform"
    board = torch.tensor([[1, 1, 0, 0, 2, 0, 0, 0, 0]])  # the robot threatens a1-b1-c1
    assert torch.softmax(rule.logits(board, board == 0), dim=1)[0, 2] > 0.5, "the rule person's model blocks c1"
    board = torch.tensor([[2, 2, 0, 0, 1, 0, 0, 0, 1]])  # the person can win at c1
    assert torch.softmax(rule.logits(board, board == 0), dim=1)[0, 2] > 0.5, "... and takes its win"


def test_a_fork_is_two_winning_cells_after_the_move_in_every_game() -> None:
    rules = make_game("standard")
    board = torch.tensor([[2, 1, 0,
                           0, 1, 0,
                           0, 0, 2]])  # the person (2) holds a1, c3; the robot b1, b2
    assert fork_cells(rules, board, 2).nonzero()[:, 1].tolist() == [6], "a3: threatens a2 and b3 at once"
    # the robot threatens b3 already: any square that adds a second threat is its fork; b3 itself wins outright
    assert fork_cells(rules, board, 1).nonzero()[:, 1].tolist() == [2, 3, 5, 6]
    features = move_features(rules, board)
    assert features[0, 7, :5].tolist() == [0.0, 1.0, 0.0, 0.0, 1.0], "b3 blocks the robot's win: the only best square"
    assert features[0, 6, :5].tolist() == [0.0, 0.0, 1.0, 1.0, 0.0], "a3: the person's fork and the robot's"
    corner = torch.tensor([[1, 0, 0, 0, 0, 0, 0, 0, 0]])
    assert move_features(rules, corner)[0, :, 4].nonzero().view(-1).tolist() == [4], "after a corner only b2 draws"
    for game in ("four", "connect_four", "ultimate"):  # any game: from its own winning_cells; no solver, no best square
        rules = make_game(game)
        boards = torch.zeros(2, len(rules.new().board), dtype=torch.long)
        features = move_features(rules, boards)
        assert features.shape == (2, boards.shape[1], 5 + boards.shape[1]) and not features[..., 4].any()
        assert not fork_cells(rules, boards, 2).any(), f"{game}: no fork on an empty board"


def test_the_model_of_a_perfect_player_learns_to_play_the_best_squares(checkpoint: Path, tmp_path: Path) -> None:
    config, _ = agent_parts.load_saved_agent(checkpoint)
    models = {}
    for opponent in ("minimax", "random"):
        games = logged_games(checkpoint, tmp_path / opponent, opponent, 24)
        moves = [m for g in games for m in person_moves(g.extra["settled_moves"], g.summary["seat"] == "first",
                                                        "standard", config.env.free_move)]
        models[opponent] = PersonModel()
        models[opponent].fit(moves)
    minimax, uniform = models["minimax"].weights, models["random"].weights
    assert minimax[4] > 2.0 and abs(uniform[4]) < 0.5, (minimax[:5], uniform[:5])  # best by exact play
    # minimax takes any square that wins by force, so forks are a share of its choices, not all: a lean
    assert minimax[2] > uniform[2], (minimax[:5], uniform[:5])


def test_a_game_makes_one_bounded_update_that_is_kept_or_rolled_back(checkpoint: Path, tmp_path: Path) -> None:
    game = logged_games(checkpoint, tmp_path / "log", "rule", 1)[0]
    learner = PlayLearner.start(checkpoint, SMALL, tmp_path / "play")
    steps_before = _optimiser_steps(learner)
    report = learner.add_game(game)
    assert report.updated and report.transitions == game.summary["length"] and report.person_moves >= 1
    assert _optimiser_steps(learner) - steps_before == SMALL.updates, "the bound: `updates` gradient steps a game"
    if report.kept:
        assert Path(report.weights).is_file()
        saved = torch.load(report.weights, weights_only=True)["qnet"]
        assert all(torch.equal(saved[k], v) for k, v in learner.qnet.state_dict().items())
    # an update whose gate fails goes back to the kept weights
    kept = {k: v.clone() for k, v in learner.qnet.state_dict().items()}
    learner._start_success = 2.0  # no agent reaches it: this update must be rolled back
    report = learner.add_game(game)
    assert report.updated and not report.kept
    assert all(torch.equal(kept[k], v) for k, v in learner.qnet.state_dict().items())


def test_without_the_gate_every_update_is_kept_unchecked(checkpoint: Path, tmp_path: Path) -> None:
    """gate=False (to measure what the gate refuses): the same bounded update, kept every time, no gate games."""
    games = logged_games(checkpoint, tmp_path / "log", "rule", 2)
    learner = PlayLearner.start(checkpoint, PlayLearning(**{**SMALL.__dict__, "gate": False}), tmp_path / "play")
    learner._start_success = 2.0  # a gate would refuse every update against this
    start = {k: v.clone() for k, v in learner.qnet.state_dict().items()}
    reports = [learner.add_game(game) for game in games]
    assert all(r.updated and r.kept and r.gate_task_success is None and r.kept_person_task_success is None
               for r in reports)
    assert learner.kept == 2 and Path(reports[-1].weights).is_file()
    assert not all(torch.equal(start[k], v) for k, v in learner.qnet.state_dict().items())


def _optimiser_steps(learner: PlayLearner) -> int:
    states = learner.learner.optimizer.state.values()
    return int(max((float(s["step"]) for s in states), default=0))


def test_a_persons_learning_resumes_from_its_last_committed_game(checkpoint: Path, tmp_path: Path) -> None:
    games = logged_games(checkpoint, tmp_path / "log", "rule", 3)
    settings = LearnSettings(reader=ReaderLearning(updates=2), play=SMALL)
    folder = tmp_path / "learning"
    learning = PersonLearning.open(folder, settings, checkpoint=checkpoint)
    for game in games[:2]:
        learning.learn([], game.extra["settled_moves"], game.summary["seat"] == "first", game, {"outcome": "x"})
    committed = json.loads((folder / "state.json").read_text())
    learning.play.add_game(games[2])  # its files are written, then the process dies before the commit
    resumed = PersonLearning.open(folder, settings)
    assert resumed.games == 2 and resumed.per_game == committed["per_game"]
    assert resumed.play.games == 2 and len(resumed.play.play_rows) == sum(g.summary["length"] for g in games[:2])
    current = torch.load(folder / "play" / committed["play"]["current"], weights_only=True)["qnet"]
    assert all(torch.equal(current[k], v) for k, v in resumed.play.qnet.state_dict().items())
    assert len(resumed.play.person_moves) == sum(len(person_moves(g.extra["settled_moves"], g.summary["seat"] == "first",
                                                                  "standard", "anywhere")) for g in games[:2])
    (folder / "state.json").write_text("{")
    with pytest.raises(ValueError, match="not a learning state written by ncbot"):
        PersonLearning.open(folder, settings)


def test_learn_cli_learns_from_a_log_once_and_rejects_bad_input_in_one_line(checkpoint: Path, tmp_path: Path) -> None:
    logged_games(checkpoint, tmp_path / "log", "rule", 2)
    out = tmp_path / "learned"
    code, stdout, stderr = ncbot_here("learn", str(tmp_path / "log"), "--out", str(out), "--agent", str(checkpoint),
                                      "--json", "--no-progress", "--updates", "4", "--test-games", "20")
    assert code == 0, stderr[-2000:]
    report = json.loads(stdout)
    assert [entry["game"] for entry in report["per_game"]] == [0, 1]
    assert all(entry["play"]["transitions"] > 0 for entry in report["per_game"])
    assert Path(report["learned_weights"]).is_file() and Path(report["learning"]["figure"]).is_file()
    code, stdout, stderr = ncbot_here("learn", str(tmp_path / "log"), "--out", str(out), "--no-progress", "--test-games", "20")
    assert code == 0 and stderr.strip().splitlines()[-1].startswith(f"wrote the learned state to {out}")
    assert json.loads((out / "state.json").read_text())["games"] == 2, "a folder that holds learning resumes"
    train_log = tmp_path / "trained"
    train(load_config(write_tiny_config(tmp_path), ["collector.total_frames=128", "logger.mcap=true"]), train_log)
    for args, message in (([str(tmp_path / "nope")], "does not exist"),
                          ([str(train_log)], "holds no robot games"),
                          ([str(tmp_path / "log"), "--wrong-claims", "2"], "--wrong-claims must be a share")):
        code, _, stderr = ncbot_here("learn", *args, "--out", str(tmp_path / "bad"))
        assert code == 2 and stderr.strip().startswith("ncbot: error:") and message in stderr
        assert len(stderr.strip().splitlines()) == 1
