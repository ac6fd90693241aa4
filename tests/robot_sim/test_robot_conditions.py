"""The field's conditions in the robot's scene: presets, sampling from a seed, the camera's post-processing,
and real SAPIEN renders (presets look different, one seed gives one frame, a game under `office` reads moves)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ncbot.robot_sim.conditions import PRESETS, SceneConditions, load_conditions, sample_conditions

SMALL = dict(camera_width=160, camera_height=120, texture_px=300)


def test_lab_is_the_scene_as_it_was_and_presets_vary_per_seed():
    assert sample_conditions(PRESETS["lab"], 7) == SceneConditions(seed=7)
    for name in ("office", "atrium", "random"):
        ranges = PRESETS[name]
        ranges.validate()
        assert sample_conditions(ranges, 3) == sample_conditions(ranges, 3), "one seed, one scene"
        assert sample_conditions(ranges, 3) != sample_conditions(ranges, 4)
    # one seed in two presets is not the same scene drawn from other ranges
    atrium, random = sample_conditions(PRESETS["atrium"], 0), sample_conditions(PRESETS["random"], 0)
    assert atrium.props != random.props or atrium.sheet_yaw != random.sheet_yaw
    yaws = [abs(np.degrees(sample_conditions(PRESETS["atrium"], s).sheet_yaw)) for s in range(40)]
    assert max(yaws) > 15 and max(yaws) <= 25


def test_conditions_file_overrides_a_preset_and_bad_files_are_one_clear_error(tmp_path):
    path = tmp_path / "dim.yaml"
    # the draw is seeded by the file's name too (its path), so the test pins every prop source to zero
    path.write_text("base: office\nlight_intensity: [0.3, 0.4]\nclutter: [0, 0]\nsecond_sheet_probability: 0.0\n")
    ranges = load_conditions(path)
    assert ranges.light_intensity == (0.3, 0.4) and ranges.clutter == (0, 0)
    assert ranges.second_sheet_probability == 0.0 and PRESETS["office"].second_sheet_probability > 0
    assert ranges.table_textures == PRESETS["office"].table_textures
    assert not sample_conditions(ranges, 1).props
    (tmp_path / "bad.yaml").write_text("base: office\nglare: 3\n")
    with pytest.raises(ValueError, match="unknown fields glare"):
        load_conditions(tmp_path / "bad.yaml")
    (tmp_path / "lohi.yaml").write_text("base: office\nnoise: [3, 1]\n")
    with pytest.raises(ValueError, match="noise range must be"):
        load_conditions(tmp_path / "lohi.yaml")
    with pytest.raises(FileNotFoundError, match="neither a preset"):
        load_conditions("moon")


def test_camera_post_leaves_the_lab_alone_and_adds_the_configured_noise():
    from ncbot.robot_sim.camera_post import CameraPost
    from ncbot.robot_sim.conditions import CameraEffects

    frame = np.full((120, 160, 3), 128, np.uint8)
    assert CameraPost(CameraEffects()).__call__(frame) is frame
    noisy = CameraPost(CameraEffects(noise=3.0, seed=1))
    first, second = noisy(frame).astype(float), noisy(frame).astype(float)
    assert 2.5 < first.std() < 4.0, "std of the noise at mid grey is `noise`"
    assert not np.array_equal(first, second), "fresh noise every frame"
    again = CameraPost(CameraEffects(noise=3.0, seed=1))
    assert np.array_equal(again(frame), first.astype(np.uint8)), "one seed, the same frames"
    dark = CameraPost(CameraEffects(exposure=0.5, jpeg_quality=50, seed=2))(frame)
    assert abs(float(dark.mean()) - 64) < 2


def _stats(frame: np.ndarray) -> np.ndarray:
    """Mean R, G, B; colour cast (R - B); contrast (std of grey)."""
    rgb = frame.reshape(-1, 3).astype(float)
    return np.array([*rgb.mean(axis=0), rgb[:, 0].mean() - rgb[:, 2].mean(), rgb.mean(axis=1).std()])


@pytest.mark.sapien
def test_presets_render_and_look_different(sapien_render_system):
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    stats = {}
    for name in ("lab", "office", "atrium", "random"):
        scene = PepperScene(SceneConfig(**SMALL, conditions=PRESETS[name], conditions_seed=2))
        frame = scene.render()
        assert frame.shape == (120, 160, 3) and frame.std() > 15, name
        stats[name] = _stats(frame)
    names = list(stats)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            difference = np.abs(stats[a] - stats[b])
            # mean colour by > 6 grey levels, or colour cast by > 6, or contrast by > 4
            assert difference[:3].max() > 6 or difference[3] > 6 or difference[4] > 4, (a, b, stats[a], stats[b])


@pytest.mark.sapien
def test_one_seed_gives_one_frame_sequence(sapien_render_system):
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    def frames(seed: int) -> list[np.ndarray]:
        scene = PepperScene(SceneConfig(**SMALL, conditions=PRESETS["random"], conditions_seed=seed))
        out = []
        for _ in range(3):
            scene.step(0.25)
            out.append(scene.render())
        return out

    first, again, other = frames(5), frames(5), frames(6)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert not np.array_equal(first[0], other[0])


@pytest.mark.sapien
def test_sheet_is_found_where_the_conditions_laid_it(sapien_render_system):
    """A sheet turned and moved by the conditions is still localised from the camera (the robot draws there)."""
    from ncbot.robot_sim.localise import localise_sheet
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    seed = next(s for s in range(50) if abs(np.degrees(sample_conditions(PRESETS["office"], s).sheet_yaw)) > 6)
    scene = PepperScene(SceneConfig(camera_width=320, camera_height=240, conditions=PRESETS["office"], conditions_seed=seed))
    estimate = localise_sheet(scene, scene.render())
    assert estimate is not None
    errors = [np.linalg.norm(estimate.canvas_to_world(*scene.canvas.cell_pixel(c)) - scene.cell_world(c)) for c in range(9)]
    assert max(errors) < 0.008
    assert abs(estimate.yaw - scene.sheet_yaw()) < np.radians(2.5)
    scene.nudge_sheet(0.0, 0.0, np.radians(3))
    assert abs(scene.sheet_yaw() - scene.conditions.sheet_yaw - np.radians(3)) < 1e-6, "nudges turn from where it lay"


@pytest.mark.sapien
def test_a_short_game_under_office_still_reads_the_moves(sapien_render_system, tmp_path):
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.play import play_robot_games

    config = RobotPlayConfig(games=2, seed=1, camera_width=320, camera_height=240, conditions="office", first="alternate")
    report = play_robot_games(config, out_dir=tmp_path, log_mcap=False, progress=False)
    assert report["conditions"] == "office"
    assert report["human_moves"] >= 4 and report["misrecognised_moves"] == 0 and report["unseen_moves"] == 0, report
    assert {"misrecognised_moves", "unseen_moves", "seconds_per_robot_turn"} <= set(report)
    assert [c["preset"] for c in report["game_conditions"]] == ["office", "office"]


@pytest.mark.sapien
def test_render_command_shows_a_preset(tmp_path, sapien_render_system):
    import subprocess
    import sys

    import cv2

    output = tmp_path / "atrium.png"
    result = subprocess.run([sys.executable, "-m", "ncbot", "robot", "render", "--conditions", "atrium",
                             "--seed", "3", "-o", str(output), "--width", "160", "--height", "120", "--frames", "1", "--json"],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["conditions"]["preset"] == "atrium"
    assert cv2.imread(str(output)).shape == (120, 160, 3)


def test_unknown_conditions_are_one_line(monkeypatch, capsys):
    import sys

    from ncbot.pipelines.cli.app import main

    monkeypatch.setattr(sys, "argv", ["ncbot", "robot", "play", "--no-progress", "--conditions", "moon"])
    with pytest.raises(SystemExit) as exit_info:
        main()
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "neither a preset" in err and len(err.strip().splitlines()) == 1


def test_a_conditions_file_that_is_not_yaml_is_named_in_one_line(tmp_path):
    """Conditions files go through the one safe YAML loader (fileio.yaml_file), so its errors name the file."""
    binary, broken = tmp_path / "photo.yaml", tmp_path / "broken.yaml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xd0\xff")
    broken.write_text("light_intensity: [0.3,\n")
    for path, problem in ((binary, "is not UTF-8 text"), (broken, "is not valid YAML")):
        with pytest.raises(ValueError) as error:
            load_conditions(path)
        message = str(error.value)
        assert f"conditions file {str(path)!r} {problem}" in message and "\n" not in message
