"""The simulated Pepper scene: model, camera, sheet texture, IK, base and gestures, all with real SAPIEN."""
from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.sapien

SMALL = dict(camera_width=160, camera_height=120, texture_px=300)


@pytest.fixture
def scene(sapien_render_system):
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    return PepperScene(SceneConfig(**SMALL))


def test_packaged_urdf_is_current_and_has_peppers_joints():
    from ncbot.robot_sim.pepper_model import PACKAGED_URDF, joint_limits, pepper_urdf_text

    assert PACKAGED_URDF.read_text() == pepper_urdf_text(), "assets/pepper.urdf is stale: run `ncbot robot urdf`"
    limits = joint_limits()
    for name in ("HeadYaw", "HeadPitch", "HipRoll", "HipPitch", "KneePitch"):
        assert name in limits
    for side in "LR":
        for part in ("ShoulderPitch", "ShoulderRoll", "ElbowYaw", "ElbowRoll", "WristYaw", "Hand"):
            assert f"{side}{part}" in limits
    assert limits["HeadPitch"] == pytest.approx((-0.706858, 0.637045))
    assert limits["RShoulderRoll"] == pytest.approx((-1.56207, -0.00872665))
    assert limits["LElbowRoll"] == pytest.approx((-1.56207, -0.00872665))


def test_mouth_camera_sits_where_peppers_camerabottom_is(scene):
    zero = np.zeros(len(scene.joint_names))
    camera = scene.link_pose("CameraBottom_frame", zero)
    assert camera.p[2] == pytest.approx(1.052, abs=0.002)
    shoulder = scene.link_pose("RShoulder", zero)
    assert shoulder.p == pytest.approx([-0.057, -0.1497, 0.907], abs=0.002)


def test_render_is_not_blank_and_shows_the_sheet(scene):
    frame = scene.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 20, "frame is (nearly) uniform"
    bright = (frame.min(axis=2) > 200)
    assert bright.mean() > 0.15, "the white sheet should fill a good part of the mouth camera's view"
    ys, xs = np.nonzero(bright)
    assert abs(xs.mean() - 80) < 20 and abs(ys.mean() - 60) < 30, "the home posture looks at the sheet"


def test_texture_update_is_visible_in_the_next_frame(scene):
    from ncbot.robot_sim.sheet import MarkSpec

    before = scene.render().astype(int)
    scene.canvas.draw(MarkSpec(4, "cross", 3, (20, 20, 20), 0.8), 1.0)
    after = scene.render().astype(int)
    changed = np.abs(after - before).sum(axis=2) > 60
    assert changed.sum() > 20, "drawing a mark must change the next rendered frame"
    ys, xs = np.nonzero(changed)
    assert abs(xs.mean() - 80) < 25, "the change is where the middle cell is"


def test_ik_reaches_every_cell_within_1cm(scene):
    from ncbot.robot_sim.motion import RobotMotion

    motion = RobotMotion(scene)
    for cell in (0, 4, 8):
        target = scene.cell_world(cell)
        motion.drive_base_to(motion.base_goal_for(target))
        motion.reach(target, 0.6)
        motion.settle(0.3)
        assert np.linalg.norm(scene.tool_position() - target) < 0.01, f"pen missed cell {cell}"
        motion.go_home(0.5)


def test_ik_jacobian_matches_finite_differences(scene):
    from ncbot.robot_sim.ik import PositionIK
    from ncbot.robot_sim.pepper_model import ARM_JOINTS

    ik = PositionIK(scene, "r_tool", ARM_JOINTS["R"])
    q = scene.home.copy()
    q[ik.columns] += 0.2
    analytic = ik.jacobian(q)
    numeric = np.zeros_like(analytic)
    for k, column in enumerate(ik.columns):
        step = np.zeros_like(q)
        step[column] = 1e-3
        numeric[:, k] = (ik.position(q + step) - ik.position(q - step)) / 2e-3
    assert np.abs(analytic - numeric).max() < 2e-3


def test_base_tracks_goals_and_an_arc(scene):
    from ncbot.robot_sim.motion import RobotMotion

    motion = RobotMotion(scene)
    assert motion.drive_base_to(np.array([0.10, -0.05, 0.0])) < 0.005
    worst = 0.0
    rate = (np.pi / 2) / 2.0  # a quarter circle of radius 0.1 m in 2 s of simulated time
    for angle in np.linspace(0, np.pi / 2, 100):
        goal = np.array([0.10 + 0.1 * np.sin(angle), -0.05 - 0.1 * (1 - np.cos(angle)), 0.0])
        velocity = 0.1 * rate * np.array([np.cos(angle), -np.sin(angle), 0.0])
        motion.tick(goal, velocity)
        worst = max(worst, np.linalg.norm(scene.base_pose()[:2] - goal[:2]))
    assert worst < 0.01


@pytest.mark.parametrize("name", ["hello", "please", "happy", "no", "think", "asr", "read"])
def test_gestures_move_and_return_home(scene, name):
    from ncbot.robot_sim.motion import RobotMotion

    motion = RobotMotion(scene)
    start = scene.qpos.copy()
    moved = 0.0
    previous = motion.move_to

    def watched(q, duration, base_goal=None):
        nonlocal moved
        previous(q, duration, base_goal)
        moved = max(moved, float(np.abs(scene.qpos - start).max()))

    motion.move_to = watched
    motion.gesture(name)
    motion.settle(0.5)
    assert moved > 0.1, f"gesture {name} did not move any joint"
    assert np.abs(scene.qpos - scene.home).max() < 0.05


def test_robot_draws_a_mark_that_the_camera_sees(scene):
    from ncbot.robot_sim.motion import RobotMotion
    from ncbot.robot_sim.sheet import ROBOT_INK, MarkSpec

    frames = []
    motion = RobotMotion(scene, on_frame=lambda frame, t: frames.append(frame), frame_period=0.5)
    before = scene.render().astype(int)
    worst = motion.draw_mark(MarkSpec(2, "nought", 5, ROBOT_INK), scene.canvas_to_world)
    assert worst < 0.005
    assert len(scene.canvas.marks) == 1 and frames
    assert np.linalg.norm(scene.base_pose()[:2]) < 0.005, "the base returns home"
    after = scene.render().astype(int)
    assert (np.abs(after - before).sum(axis=2) > 60).sum() > 10


def test_human_draws_with_an_occluding_arm(scene):
    from ncbot.envs.rules import Standard
    from ncbot.robot_sim.human import HumanConfig, SimulatedHuman

    game = Standard()
    human = SimulatedHuman(scene, game, HumanConfig(drawing_frames=3), seed=1)
    clean = scene.render().astype(int)
    frames = []
    cell = human.choose(game.new(), 2)
    mark = human.draw(cell, "nought", lambda frame, t: frames.append(frame.astype(int)))
    assert mark.cell == cell and len(frames) == 2 + 3 + 1
    # While drawing, the skin-coloured arm hides a large part of the view; after it leaves, only the mark differs.
    occluded = (np.abs(frames[2] - clean).sum(axis=2) > 60).mean()
    final = (np.abs(scene.render().astype(int) - clean).sum(axis=2) > 60).mean()
    assert occluded > 0.03 and final < occluded / 2


def test_bad_config_is_one_clear_error(sapien_render_system):
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    with pytest.raises(ValueError, match="game must be one of"):
        PepperScene(SceneConfig(game="chess"))
    with pytest.raises(ValueError, match="camera must be at least"):
        PepperScene(SceneConfig(camera_width=4))


def test_sheet_is_localised_from_the_camera_after_a_nudge(scene):
    from ncbot.robot_sim.localise import localise_sheet

    scene.nudge_sheet(0.01, -0.008, np.radians(4))
    estimate = localise_sheet(scene, scene.render())
    assert estimate is not None
    errors = [np.linalg.norm(estimate.canvas_to_world(*scene.canvas.cell_pixel(c)) - scene.cell_world(c)) for c in range(9)]
    assert max(errors) < 0.005, "cell centres from the camera should be within 5 mm at 160x120"
    assert abs(estimate.yaw - scene.sheet_yaw()) < np.radians(1.5)


def test_scenes_in_one_process_do_not_light_or_show_each_other(sapien_render_system):
    """Each scene renders in its own world: a second scene (first still alive) gives the same picture."""
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    first = PepperScene(SceneConfig(**SMALL))
    before = first.render()
    second = PepperScene(SceneConfig(**SMALL))
    assert np.array_equal(second.render(), before)
    assert np.array_equal(first.render(), before)
