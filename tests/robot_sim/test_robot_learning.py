"""The robot learns from a game it plays on real SAPIEN frames (`ncbot robot play --learn`), and learning from the
game's MCAP log afterwards (`ncbot learn`) gives the very same reader and agent."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

pytestmark = pytest.mark.sapien


@pytest.fixture(scope="module")
def tiny_agent(tmp_path_factory) -> Path:
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.run import train
    from tests.learning_helpers import write_tiny_config

    folder = tmp_path_factory.mktemp("agent")
    train(load_config(write_tiny_config(folder), ["collector.total_frames=256"]), folder / "run")
    return folder / "run" / "checkpoint.pt"


def test_a_game_played_while_learning_is_learned_again_the_same_from_its_log(sapien_render_system, tiny_agent,
                                                                              tmp_path) -> None:
    from ncbot.pipelines.online.learning import LearnSettings
    from ncbot.pipelines.online.offline import learn_from_logs
    from ncbot.pipelines.online.play_learner import PlayLearning
    from ncbot.pipelines.online.robot_games import play_and_learn
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.vision.online import ReaderLearning

    torch.set_num_threads(1)
    conditions = tmp_path / "sketch.yaml"
    conditions.write_text("base: lab\nhandwriting: [sketch]\n")
    settings = LearnSettings(ReaderLearning(updates=4), PlayLearning(updates=3, batch_size=32, sim_frames=64,
                                                                     gate_games=20))
    config = RobotPlayConfig(game="standard", games=1, seed=2, first="human", camera_width=320, camera_height=240,
                             conditions=str(conditions))
    played = tmp_path / "played"
    report = play_and_learn(config, tiny_agent, played, "ada", settings)

    (game,) = report["per_game"]
    assert game["handwriting"] == "sketch" and game["outcome"] in ("win", "draw", "loss", "unfinished")
    reader, play = game["reader"], game["play"]
    assert reader["views"] == game["human_moves"] + report["robot_moves"], "a look after every settled move"
    assert sum(reader["examples"].values()) == 9 * reader["views"] and reader["updated"]
    assert play["updated"] and play["transitions"] > 0 and play["person_moves"] == game["human_moves"]
    assert report["learned_weights"] == str(played / "learning" / "ada" / "reader" / "reader.pt")
    assert json.loads((played / "report.json").read_text())["per_game"] == report["per_game"]
    assert (played / "learning.png").stat().st_size > 1000
    assert set(report["learning"]["reader"]["accuracy"]) == {"sketch", "hershey"}

    offline = learn_from_logs([played], tmp_path / "offline", settings, None, tiny_agent)
    again = offline.per_game[0]["reader"]
    assert again == {**reader, "weights": again["weights"], "cpu_seconds": again["cpu_seconds"]}
    for name, folder in (("reader/reader.pt", "state_dict"), ("play/agent.pt", "qnet")):
        online = torch.load(played / "learning" / "ada" / name, weights_only=True)[folder]
        again = torch.load(tmp_path / "offline" / name, weights_only=True)[folder]
        assert all(torch.equal(online[k], again[k]) for k in online), name
