"""What the robot sees of the human's move: occluded frames never yield a move, the finished mark does."""
from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.sapien


@pytest.mark.parametrize("cell, seed, nudge", [(4, 0, 0.0), (2, 1, 1.0)])
def test_recogniser_waits_for_the_hand_and_then_reads_the_move(sapien_render_system, cell, seed, nudge):
    from ncbot.envs.rules import Standard
    from ncbot.robot_sim.human import HumanConfig, SimulatedHuman
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.scene import PepperScene, SceneConfig
    import cv2
    from ncbot.vision.page import find_page
    from ncbot.vision.recogniser import MoveRecogniser

    scene = PepperScene(SceneConfig(camera_width=320, camera_height=240))
    human = SimulatedHuman(scene, Standard(), HumanConfig(drawing_frames=4, nudge_probability=nudge), seed=seed)
    recogniser = MoveRecogniser(grid=3, tau=RobotPlayConfig().recogniser_tau)
    known = [0] * 9
    results = []

    def hand_over_sheet(frame):
        """Pixels of the arm (frame vs. the same scene rendered without it) inside the sheet's outline."""
        if not scene.arm_visible:
            return False
        pose = scene.human_arm.pose
        scene.hide_human_arm()
        clean = scene.render()
        scene.human_arm.set_pose(pose)
        scene.arm_visible = True
        corners = find_page(np.ascontiguousarray(clean[:, :, ::-1]))
        sheet = np.zeros(clean.shape[:2], np.uint8)
        cv2.fillConvexPoly(sheet, corners.astype(np.int32), 1)
        arm = np.abs(frame.astype(int) - clean.astype(int)).sum(axis=2) > 30
        return bool((arm & (sheet > 0)).sum() > 3)

    def watch(frame, t):
        over = hand_over_sheet(frame)
        results.append((recogniser.update(np.ascontiguousarray(frame[:, :, ::-1]), known), over))

    start_pose = np.array(scene.sheet.pose.p)
    human.draw(cell, "cross", watch)
    for _ in range(6):
        scene.step(0.25)
        watch(scene.render(), scene.time)
    assert any(over for _, over in results), "the human's hand should cover part of the sheet while drawing"
    for result, over in results:
        if over:
            assert result.status != "move", "a move was reported from a frame with the hand over the sheet"
    moves = [r for r, _ in results if r.status == "move"]
    assert moves, [r.status for r, _ in results]
    assert moves[0].move == cell and moves[0].label == "x"
    if nudge:
        assert np.linalg.norm(np.array(scene.sheet.pose.p) - start_pose) > 1e-4, "the sheet was nudged"


def test_licensed_meshes_replace_primitives(sapien_render_system, tmp_path):
    from ncbot.robot_sim.pepper_model import pepper_urdf_text
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "Head.obj").write_text(
        "v -0.1 -0.1 0\nv 0.1 -0.1 0\nv 0.1 0.1 0\nv -0.1 0.1 0\nv 0 0 0.2\n"
        "f 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\nf 1 3 2\nf 1 4 3\n")
    text = pepper_urdf_text(tmp_path / "meshes")
    assert "Head.obj" in text and text.count("<mesh") == 1
    scene = PepperScene(SceneConfig(camera_width=64, camera_height=48, meshes_dir=str(tmp_path / "meshes")))
    assert "Head" in scene.links
    with pytest.raises(FileNotFoundError, match="meshes folder"):
        pepper_urdf_text(tmp_path / "nope")


def test_speaker_keeps_text_without_audio(tmp_path):
    from ncbot.robot_sim.speech import Speaker

    speaker = Speaker(None)
    assert speaker.say("Hello, nice to meet you!") is None
    assert speaker.said == ["Hello, nice to meet you!"] and not speaker.has_audio


def test_a_curled_sheet_edge_is_not_a_hand_once_the_robot_has_seen_the_sheet(sapien_render_system):
    """A curled edge bows out of the page's four-corner quad, so a sliver of table lies along the rim in every
    frame: judged alone, every still frame looks like a hand over the sheet's edge and the move is never seen
    (the random preset's unseen moves); judged against the robot's look before the turn, the move is read."""
    from ncbot.envs.rules import Standard
    from ncbot.robot_sim.conditions import PRESETS
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.human import HumanConfig, SimulatedHuman
    from ncbot.robot_sim.scene import PepperScene, SceneConfig
    from ncbot.vision.recogniser import MoveRecogniser

    # the scene of `ncbot robot play --conditions random --seed 11`, game 7: curl 15 mm, sheet turned 25 degrees
    scene = PepperScene(SceneConfig(camera_width=640, camera_height=480, conditions=PRESETS["random"],
                                    conditions_seed=11007))
    assert scene.conditions.sheet_shape.curl > 0.01
    human = SimulatedHuman(scene, Standard(), HumanConfig(drawing_frames=4), seed=3)
    reference = np.ascontiguousarray(scene.render()[:, :, ::-1])
    tau = RobotPlayConfig().recogniser_tau
    alone, told = MoveRecogniser(grid=3, tau=tau), MoveRecogniser(grid=3, tau=tau)
    told.reset(reference=reference)
    statuses = {"alone": [], "told": []}

    def watch(frame, t):
        bgr = np.ascontiguousarray(frame[:, :, ::-1])
        statuses["alone"].append(alone.update(bgr, [0] * 9))
        statuses["told"].append(told.update(bgr, [0] * 9))

    human.draw(4, "cross", watch)
    for _ in range(8):
        scene.step(0.25)
        watch(scene.render(), scene.time)
    moves = [r for r in statuses["told"] if r.status == "move"]
    assert moves and moves[0].move == 4 and moves[0].label == "x", [r.status for r in statuses["told"]]
    assert not any(r.status == "move" for r in statuses["alone"]), [r.status for r in statuses["alone"]]
