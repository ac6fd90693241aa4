"""A declared game's sheet in the simulator: its grid rendered by the mouth camera and read back, every cell
within the pen's reach, and a whole game played with the camera in the loop."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.sapien


def _ncbot(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True)


def test_rendered_four_sheet_reads_back_as_sixteen_empty_cells(tmp_path):
    frame = tmp_path / "four.png"
    rendered = _ncbot("robot", "render", "--game", "four", "--frames", "1", "-o", str(frame))
    assert rendered.returncode == 0, rendered.stderr
    read = _ncbot("vision", "read", str(frame), "--grid", "4x4", "--json")
    assert read.returncode == 0, read.stderr
    assert json.loads(read.stdout)["images"][0]["cells"] == [""] * 16


def test_rendered_connect_four_marks_read_back_in_their_cells(tmp_path):
    frame = tmp_path / "c4.png"
    rendered = _ncbot("robot", "render", "--game", "connect_four", "--marks", "xd6,od5,xa1", "--frames", "1",
                      "-o", str(frame))
    assert rendered.returncode == 0, rendered.stderr
    read = _ncbot("vision", "read", str(frame), "--grid", "6x7", "--json")
    cells = json.loads(read.stdout)["images"][0]["cells"]
    expected = [""] * 42
    expected[0], expected[31], expected[38] = "x", "o", "x"  # a1 top-left; d5, d6 near the robot
    assert cells == expected


def test_every_declared_cell_is_reached_and_a_sheet_out_of_reach_is_refused(sapien_render_system):
    import sapien

    from ncbot.envs.games import make_game
    from ncbot.robot_sim.reach import check_reach, reach_errors
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    scene = PepperScene(SceneConfig(game="connect_four", camera_width=160, camera_height=120, texture_px=300))
    assert scene.grid == (6, 7) and scene.sheet_side == pytest.approx(0.28)
    errors = reach_errors(scene)
    assert errors.shape == (42,) and errors.max() < 0.005
    check_reach(scene, make_game("connect_four").cell_name)
    pose = scene.sheet.pose
    scene.sheet.set_pose(sapien.Pose(np.array(pose.p) + [0.0, 0.0, 0.9], pose.q))  # the sheet lifted above the head
    with pytest.raises(ValueError, match=r"^cell a1 is out of the arm's reach \(\d+ mm short\); expected"):
        check_reach(scene, make_game("connect_four").cell_name)


def test_a_bad_game_is_one_line():
    out = _ncbot("robot", "render", "--game", "nosuchgame", "--frames", "1")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "game must be one of standard, ultimate" in out.stderr.strip().splitlines()[-1]


def test_a_whole_connect_four_game_is_played_through_the_camera(sapien_render_system, tmp_path):
    """Gravity with vision in the loop: each of the person's marks lands on the lowest empty square of its column
    and the robot reads it there (through the 6x7 grid reader), the robot draws its own marks, and its belief
    ends equal to the true board."""
    from ncbot.envs.games import make_game
    from ncbot.logs import LogReader, read_episodes
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.play import play_robot_games

    config = RobotPlayConfig(game="connect_four", games=1, seed=0, camera_width=320, camera_height=240)
    report = play_robot_games(config, out_dir=tmp_path, progress=False)

    assert report["game"] == "connect_four" and report["wins"] + report["draws"] + report["losses"] == 1, report
    assert report["misrecognised_moves"] == 0 and report["unseen_moves"] == 0, report
    assert report["own_mark_misread"] == 0 and report["ik_failures"] == 0, report
    assert report["human_moves"] >= 3 and report["robot_moves"] >= 4
    rules = make_game("connect_four")
    true_boards = read_episodes(tmp_path)[0]["extra"]["true_boards"]
    final = true_boards[-1]
    assert len(final) == 42 and final.count("1") == report["robot_moves"] and final.count("2") == report["human_moves"]
    for cell in range(42 - rules.cols):  # every mark rests on the bottom row or on another mark
        assert final[cell] == "0" or final[cell + rules.cols] != "0", final
    boards = [m.data for m in LogReader(tmp_path).messages(["/board"])]
    assert boards[-1]["cells"] == final  # what the robot believed is what was drawn
