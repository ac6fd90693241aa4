"""A declared game's sheet in the simulator: its grid rendered by the mouth camera and read back, every cell
within the pen's reach."""
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
    assert json.loads(read.stdout)["cells"] == [""] * 16


def test_rendered_connect_four_marks_read_back_in_their_cells(tmp_path):
    frame = tmp_path / "c4.png"
    rendered = _ncbot("robot", "render", "--game", "connect_four", "--marks", "xd6,od5,xa1", "--frames", "1",
                      "-o", str(frame))
    assert rendered.returncode == 0, rendered.stderr
    read = _ncbot("vision", "read", str(frame), "--grid", "6x7", "--json")
    cells = json.loads(read.stdout)["cells"]
    expected = [""] * 42
    expected[0], expected[31], expected[38] = "x", "o", "x"  # a1 top-left; d5, d6 near the robot
    assert cells == expected


def test_every_declared_cell_is_reached_and_a_sheet_out_of_reach_is_refused(sapien_render_system):
    import sapien

    from ncbot.envs.rules import make_game
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
