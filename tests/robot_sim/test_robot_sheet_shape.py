"""Field conditions of the sheet and camera: a curled or folded sheet (a bent SAPIEN mesh) and a camera whose
exposure follows the frame's brightness; both drawn from the game seed without moving any earlier draw."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ncbot.robot_sim.camera_post import CameraPost
from ncbot.robot_sim.conditions import PRESETS, CameraEffects, load_conditions, sample_conditions
from ncbot.robot_sim.sheet_shape import SheetShape


def test_new_draws_leave_every_earlier_value_alone_and_ranges_are_checked(tmp_path):
    for name in ("office", "atrium", "random"):
        ranges = PRESETS[name]
        flat = dataclasses.replace(ranges, curl_probability=0.0, fold_probability=0.0, auto_exposure_rate=(0.0, 0.0))
        for seed in range(5):
            dressed, plain = sample_conditions(ranges, seed), sample_conditions(flat, seed)
            stripped = dataclasses.replace(dressed, sheet_shape=plain.sheet_shape,
                                           camera=dataclasses.replace(dressed.camera, auto_exposure_rate=0.0,
                                                                      exposure_target=plain.camera.exposure_target))
            assert stripped == plain, (name, seed)
    shapes = [sample_conditions(PRESETS["atrium"], s).sheet_shape for s in range(40)]
    assert any(s.curl > 0 for s in shapes) and any(s.fold > 0 for s in shapes) and any(s.flat for s in shapes)
    assert all(sample_conditions(PRESETS["lab"], s).sheet_shape.flat for s in range(5))
    (tmp_path / "roll.yaml").write_text("base: office\ncurl_height: [0.01, 0.05]\n")
    with pytest.raises(ValueError, match="curl_height and fold_height"):
        load_conditions(tmp_path / "roll.yaml")
    (tmp_path / "ae.yaml").write_text("base: office\nauto_exposure_rate: [0.5, 1.5]\n")
    with pytest.raises(ValueError, match="auto_exposure_rate"):
        load_conditions(tmp_path / "ae.yaml")


def test_sheet_shape_heights():
    side = 0.22
    curl = SheetShape(curl=0.01, curl_edge=0, curl_start=0.5)
    assert curl.height(0.0, 0.0, side) == 0.0 and abs(curl.height(side / 2, 0.05, side) - 0.01) < 1e-9
    assert curl.height(-side / 2, 0.0, side) == 0.0          # only the one edge lifts
    fold = SheetShape(fold=0.006, fold_angle=0.0, fold_offset=0.0)  # crease along x through the centre
    assert abs(fold.height(0.05, 0.0, side) - 0.006) < 1e-9 and 0 < fold.height(0.0, 0.08, side) < 0.006


def test_auto_exposure_follows_the_frame_brightness():
    dark, bright = np.full((48, 64, 3), 40, np.uint8), np.full((48, 64, 3), 200, np.uint8)
    camera = CameraPost(CameraEffects(auto_exposure_rate=0.5, exposure_target=0.45, seed=1))
    assert abs(float(camera(dark).mean()) - 0.45 * 255) < 3, "the first frame is metered and met"
    steps = [float(camera(bright).mean()) for _ in range(8)]
    assert steps[0] > 180 and all(a > b for a, b in zip(steps, steps[1:])), steps   # over-exposed, then adapts
    assert abs(steps[-1] - 0.45 * 255) < 4
    off = CameraPost(CameraEffects(exposure=0.8, seed=1))
    assert abs(float(off(dark).mean()) - 32) < 1 and abs(float(off(bright).mean()) - 160) < 1, "off: a fixed gain"
    one, two = (CameraPost(CameraEffects(auto_exposure_rate=0.3, exposure_target=0.4, noise=2.0, seed=3)) for _ in range(2))
    assert all(np.array_equal(one(f), two(f)) for f in (dark, bright, bright, dark)), "one seed, the same frames"


@pytest.mark.sapien
def test_a_folded_and_curled_sheet_renders_bent_and_is_still_read(sapien_render_system):
    from ncbot.robot_sim.scene import PepperScene, SceneConfig
    from ncbot.robot_sim.sheet import MarkSpec
    from ncbot.vision.grid import read_board

    bent = dataclasses.replace(PRESETS["office"], curl_probability=1.0, curl_height=(0.012, 0.012),
                               fold_probability=1.0, fold_height=(0.008, 0.008), auto_exposure_rate=(0.4, 0.4))
    flat = dataclasses.replace(bent, curl_probability=0.0, fold_probability=0.0)
    frames, scenes = [], []
    for ranges in (bent, flat):
        scene = PepperScene(SceneConfig(camera_width=320, camera_height=240, conditions=ranges, conditions_seed=4))
        for cell, kind in ((0, "nought"), (4, "cross"), (8, "nought"), (5, "cross")):
            scene.canvas.draw(MarkSpec(cell, kind, seed=cell, ink=scene.conditions.ink_bgr), 1.0)
        frames.append(scene.render())
        scenes.append(scene)
    assert not scenes[0].conditions.sheet_shape.flat and scenes[1].conditions.sheet_shape.flat
    differ = np.abs(frames[0].astype(int) - frames[1].astype(int)).max(axis=2) > 12
    assert differ.mean() > 0.01, "the bend changes the picture"
    # the pen follows the bent surface: a cell on the crease or curl lies above the flat sheet's plane
    lifted = [scenes[0].cell_world(c)[2] - scenes[1].cell_world(c)[2] for c in range(9)]
    assert max(lifted) > 0.004 and min(lifted) >= -1e-9
    board = ["o", "", "", "", "x", "x", "", "", "o"]
    assert read_board(frames[0][:, :, ::-1].copy(), 3) == board
