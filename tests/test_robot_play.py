"""The closed loop on real SAPIEN frames: a whole game perceived through the vision recogniser, logged to MCAP."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.sapien


def test_a_whole_game_is_played_from_rendered_frames_and_logged(sapien_render_system, tmp_path):
    from logs import LogReader, read_episodes
    from robot_sim.game_config import RobotPlayConfig
    from robot_sim.play import play_robot_games

    config = RobotPlayConfig(game="standard", games=1, seed=5, camera_width=320, camera_height=240,
                             robot_frame_period=1.0)
    report = play_robot_games(config, out_dir=tmp_path, progress=False)

    assert report["games"] == 1 and report["wins"] + report["draws"] + report["losses"] == 1, report
    assert report["misrecognised_moves"] == 0 and report["unseen_moves"] == 0, report
    assert report["human_moves"] >= 2 and report["robot_moves"] >= 3
    assert report["seconds_per_robot_turn"] > 0
    assert json.loads((tmp_path / "report.json").read_text()) == report
    snapshot = tmp_path / "game-000.png"
    assert snapshot.stat().st_size > 1000

    # The log holds the camera stream, joints and transforms, and the episode with the true boards.
    reader = LogReader(tmp_path)
    topics = {}
    for message in reader.messages():
        topics[message.topic] = topics.get(message.topic, 0) + 1
    assert topics.get("/camera/bottom/compressed", 0) >= 10
    assert topics.get("/joint_states", 0) == topics["/camera/bottom/compressed"]
    assert topics.get("/tf", 0) >= topics["/camera/bottom/compressed"]
    episodes = read_episodes(tmp_path)
    assert len(episodes) == 1 and episodes[0]["phase"] == "robot"
    extra = episodes[0]["extra"]
    assert extra["misrecognised_moves"] == 0
    # With no misrecognition the robot's belief (the env board) ends equal to the true board.
    boards = [m.data for m in reader.messages() if m.topic == "/board"]
    assert boards[-1]["cells"] == extra["true_boards"][-1]

    # --rrd: the run exports to a rerun recording with the camera frames.
    from logs.rerun_export import export_to_rerun

    export_to_rerun(tmp_path, tmp_path / "run.rrd")
    assert (tmp_path / "run.rrd").stat().st_size > 10_000


def test_robot_cli_rejects_bad_input_with_one_line(tmp_path, monkeypatch, capsys):
    import sys

    from pipelines.cli import main

    for args, needle in ((["--rrd"], "--rrd needs --out"), (["--checkpoint", str(tmp_path / "missing.pt")], "does not exist"),
                         (["--game", "chess"], "game must be one of"), (["--meshes", str(tmp_path / "none")], "meshes folder")):
        monkeypatch.setattr(sys, "argv", ["ncbot", "robot", "play", "--no-progress", *args])
        with pytest.raises(SystemExit) as exit_info:
            main()
        err = capsys.readouterr().err
        assert exit_info.value.code == 2, err
        assert needle in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1


def test_lookahead_policy_is_seeded_and_respects_masks():
    import torch
    from envs import make_env
    from modules.masks import LookaheadOnlyPolicy

    env = make_env("standard", batch_size=(1,), seed=0)
    td = env.reset()
    first = [int(LookaheadOnlyPolicy(seed=3)(td.clone())["action"]) for _ in range(2)]
    assert first[0] == first[1]
    for _ in range(30):
        td = LookaheadOnlyPolicy(seed=1)(td)
        assert bool(td["action_mask"][0, int(td["action"])])
        td = env.step(td)
        if bool(td["next", "done"].item()):
            break
        from torchrl.envs.utils import step_mdp
        td = step_mdp(td)
    assert isinstance(np.asarray(first), np.ndarray) and torch.is_tensor(td["action"])


def test_render_command_writes_the_mouth_camera_view(tmp_path):
    import subprocess
    import sys

    import cv2

    output = tmp_path / "mouth.png"
    result = subprocess.run([sys.executable, "-m", "pipelines.cli", "robot", "render", "-o", str(output),
                             "--width", "160", "--height", "120", "--marks", "x4,o0", "--frames", "2"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["output"] == str(output) and report["ms_per_frame_median"] > 0
    image = cv2.imread(str(output))
    assert image.shape == (120, 160, 3) and image.std() > 20


def test_no_vulkan_device_is_one_line_with_the_recipe(tmp_path):
    import os
    import subprocess
    import sys

    env = dict(os.environ, VK_ICD_FILENAMES=str(tmp_path / "no_such_icd.json"))
    result = subprocess.run([sys.executable, "-m", "pipelines.cli", "robot", "render", "-o", str(tmp_path / "x.png")],
                            capture_output=True, text=True, timeout=300, env=env)
    assert result.returncode == 2
    assert "scripts/setup.sh" in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
