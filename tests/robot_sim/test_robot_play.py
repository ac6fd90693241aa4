"""The closed loop on real SAPIEN frames: a whole game perceived through the vision recogniser, logged to MCAP."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.sapien


def test_a_whole_game_is_played_from_rendered_frames_and_logged(sapien_render_system, tmp_path, capfd):
    """`ncbot robot play --json` with real speech (the default): the robot speaks, hears the person through
    pocketsphinx, and the log holds both voices' audio, decodable back to samples."""
    from ncbot.logs import LogReader, read_episodes
    from ncbot.speech import SAMPLE_RATE
    from ncbot.speech.audio import channels_from_raw_audio
    from tests.cli.conftest import run_main

    code, out, err = run_main(capfd, "robot", "play", "--games", "1", "--seed", "5", "--width", "320", "--height", "240",
                              "--robot-frame-period", "1.0", "--out", tmp_path, "--no-progress", "--json")
    assert code == 0, err
    assert err.strip().splitlines()[-1].startswith(f"wrote the games' MCAP log, snapshots and report.json to {tmp_path}")
    report = json.loads(out)
    assert report.pop("written") == [str(tmp_path)]

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

    # Speech: every utterance of both speakers is on /audio/*, 16 kHz pcm-s16, audible, as long as noted on
    # /dialogue beside its text: the robot's voice mono, the person's as Pepper's four microphones took it in, and
    # beside it the enhanced mono the recogniser decoded; the person's turns carry what the recogniser heard with
    # per-word confidences and what the array did (the beam aimed across the sheet the camera found).
    assert report["asr_utterances"] >= 5 and 0.0 <= report["asr_word_error_rate"] <= 0.5, report
    assert 0.5 < report["asr_mean_confidence"] <= 1.0 and report["robot_utterances"] > report["robot_moves"]
    assert report["hearing"] == "array" and report["enhancement"] == "mvdr+vad" and report["steered_by_doa"] == 0
    assert report["steered_by_camera"] == report["asr_utterances"] and report["beam_error_deg"] < 15.0
    assert 0 < report["enhancement_to_asr_cpu"] < 2.0 and "room" in report["game_conditions"][0]["speech"]
    audio = {"/audio/robot": [], "/audio/user": [], "/audio/user/enhanced": []}
    for message in reader.messages(list(audio)):
        channels = 4 if message.topic == "/audio/user" else 1
        assert (message.data.format, message.data.sample_rate, message.data.number_of_channels) == ("pcm-s16", SAMPLE_RATE, channels)
        samples = channels_from_raw_audio(message.data)
        assert 0.3 < samples.shape[1] / SAMPLE_RATE < 7.0 and np.abs(samples).max() > 2000  # a spoken utterance
        audio[message.topic].append((round(message.data.timestamp.ToNanoseconds() / 1e9, 4), samples.shape[1]))
    assert len(audio["/audio/robot"]) == report["robot_utterances"] and len(audio["/audio/user"]) == report["asr_utterances"]
    assert np.allclose([t for t, _ in audio.pop("/audio/user/enhanced")], [t for t, _ in audio["/audio/user"]])
    noted = {"/audio/robot": [], "/audio/user": []}
    turns = [m.data for m in reader.messages(["/dialogue"])]
    for turn in turns:
        for item in turn.get("audio", []):
            assert item["text"]
            noted[item["topic"]].append((item["t"], item["seconds"] * SAMPLE_RATE))
    for topic, logged in audio.items():  # the same utterances, in order, at the same times and lengths
        assert len(noted[topic]) == len(logged)
        assert np.allclose([t for t, _ in noted[topic]], [t for t, _ in logged], atol=2e-4)  # both rounded to 0.1 ms
        assert np.allclose([n for _, n in noted[topic]], [n for _, n in logged], atol=1.0)
    heard = [t for t in turns if t["speaker"] == "user"]
    assert heard and all(len(t["heard_words"]) == len(t["heard"].split()) for t in heard)
    assert all(0.0 <= c <= 1.0 for t in heard for _, c in t["heard_words"])
    assert all(t["ears"]["steered_by"] == "camera" for t in heard if t.get("heard_words"))

    # --rrd: the run exports to a rerun recording with the camera frames.
    from ncbot.logs.rerun_export import export_to_rerun

    export_to_rerun(tmp_path, tmp_path / "run.rrd")
    assert (tmp_path / "run.rrd").stat().st_size > 10_000


def test_unseen_moves_are_asked_about_aloud_and_the_answers_heard(sapien_render_system, tmp_path):
    """Real speech, a camera that never confirms a move: every human move is asked about ("where did you draw?"),
    the person's spoken cell is heard through Pepper's array by pocketsphinx and settled by its confidence
    (taken, confirmed, or touched on the tablet), and the answers are in the log."""
    from ncbot.logs import LogReader
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.play import play_robot_games
    from ncbot.robot_sim.where import ASK_WHERE

    config = RobotPlayConfig(game="standard", games=1, seed=5, camera_width=160, camera_height=120, speech="real",
                             confirm_frames=10_000, max_perception_frames=1)
    report = play_robot_games(config, out_dir=tmp_path, progress=False)
    assert report["unseen_moves"] == report["human_moves"] >= 2 and report["misrecognised_moves"] == 0, report
    # the lab is quiet: every answer settles its move in the cell drawn (or the tablet does), no question is asked
    # twice, and the game ends as it should
    assert report["cells_from_answers"] + report["tablet_fallbacks"] == report["unseen_moves"], report
    assert report["misheard_cells"] == 0 and report["where_repeats"] == 0 and report["answers"] == "confidence"
    assert report["answer_fallbacks"] == 0 and report["unfinished"] == 0 and report["cell_answer_word_error_rate"] == 0.0
    assert report["cell_answers"] == report["unseen_moves"] + report["confirmations"]
    # asked again because a reply was not understood: a part of the dialogue's repeats, never more
    assert report["where_repeats"] <= report["asked_again"] <= report["where_repeats"] + report["dialogue_repeats"]
    reader = LogReader(tmp_path)
    users = sum(1 for _ in reader.messages(["/audio/user"]))
    assert users == report["asr_utterances"] + report["cell_answers"]
    answers = [a for m in reader.messages(["/dialogue"]) for a in m.data.get("cell_answers", [])]
    assert len(answers) == report["cell_answers"] and answers[0]["question"] == ASK_WHERE
    assert all(a["ears"]["steered_by"] == "camera" for a in answers)
    boards = [m.data for m in reader.messages(["/board"])]
    assert boards[-1]["cells"] == [e for e in reader.messages(["/episode"])][-1].data["extra"]["true_boards"][-1]


def test_robot_cli_rejects_bad_input_with_one_line(tmp_path, monkeypatch, capsys):
    import sys

    from ncbot.pipelines.cli.app import main

    for args, needle in ((["--rrd"], "--rrd needs --out"), ([str(tmp_path / "missing.pt")], "not found"),
                         (["--game", "chess"], "game must be one of"), (["--meshes", str(tmp_path / "none")], "meshes folder"),
                         (["--speech", "loud"], "--speech must be real or text"),
                         (["--ears", "stereo"], "ears must be one of array, mono"),
                         (["--enhancement", "gsc"], "is not beamformer"),
                         (["--answers", "guess"], "answers must be one of confidence, confirm")):
        monkeypatch.setattr(sys, "argv", ["ncbot", "robot", "play", "--no-progress", *args])
        with pytest.raises(SystemExit) as exit_info:
            main()
        err = capsys.readouterr().err
        assert exit_info.value.code == 2, err
        assert needle in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1


def test_report_asr_keys_are_null_with_text_speech_and_filled_with_real():
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.report import GameRecord, games_report

    record = GameRecord(index=0, outcome="win", robot_first=True, actions=9, utterances={"robot": 9, "user": 4},
                        asr_words=10, asr_word_errors=2, asr_confidences=[0.5, 1.0], asr_understood=3)
    keys = ("asr_word_error_rate", "asr_mean_confidence", "asr_utterances", "asr_understood_rate", "robot_utterances")
    text = games_report([record], RobotPlayConfig(speech="text"))
    assert all(text[k] is None for k in keys) and text["speech"] == "text"
    answer_keys = ("cell_answers", "cells_from_answers", "misheard_cells", "answer_fallbacks")
    assert all(text[k] is None for k in answer_keys)
    assert [games_report([record], RobotPlayConfig(speech="real"))[k] for k in answer_keys] == [0, 0, 0, 0]
    real = games_report([record], RobotPlayConfig(speech="real"))
    assert [real[k] for k in keys] == [0.2, 0.75, 4, 0.75, 9]
    for key in ("misrecognised_moves", "unseen_moves", "seconds_per_robot_turn", "conditions"):
        assert key in real and key in text
    with pytest.raises(ValueError, match="speech must be one of real, text"):
        RobotPlayConfig(speech="loud").validate()
    # what the array and the dialogue did: null in text mode (and the array's keys with one microphone)
    array_keys = ("enhancement", "steered_by_camera", "steered_by_doa", "beam_error_deg",
                  "enhancement_cpu_seconds_per_utterance", "enhancement_to_asr_cpu")
    assert all(text[k] is None for k in (*array_keys, "hearing", "answers", "cells_accepted", "confirmations"))
    record.enhancement_cpu_seconds, record.asr_cpu_seconds = [0.01, 0.03], [0.05, 0.05]
    record.steered_by, record.beam_errors_deg = {"camera": 2}, [3.0, 5.0]
    record.confirmations, record.tablet_fallbacks, record.where_repeats, record.dialogue_repeats = 2, 1, 1, 3
    array = games_report([record], RobotPlayConfig(speech="real"))
    assert [array[k] for k in array_keys] == ["mvdr+vad", 2, 0, 4.0, 0.02, 0.4]
    assert (array["hearing"], array["answers"], array["confirmations"], array["tablet_fallbacks"]) == ("array", "confidence", 2, 1)
    assert array["repeated_questions"] == 4 and array["where_repeats"] == 1 and array["dialogue_repeats"] == 3
    # asked again because the robot did not understand: "where?" again, and a dialogue act said again right after
    # a reply not understood as said; a repeat after a reply understood (the person's "no thank you") is not one
    from ncbot.robot_sim.report import count_repeat

    record.dialogue_repeats = 0
    for repeat, understood in ((True, False), (True, True), (False, False), (True, False)):
        count_repeat(record, repeat, understood)
    assert (record.dialogue_repeats, record.dialogue_asked_again) == (3, 2)
    assert games_report([record], RobotPlayConfig(speech="real"))["asked_again"] == 1 + 2
    mono = games_report([record], RobotPlayConfig(speech="real", ears="mono"))
    assert mono["hearing"] == "mono" and all(mono[k] is None for k in array_keys)


def test_lookahead_policy_is_seeded_and_respects_masks():
    import torch
    from ncbot.envs import make_env
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy

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
    result = subprocess.run([sys.executable, "-m", "ncbot", "robot", "render", "-o", str(output),
                             "--width", "160", "--height", "120", "--marks", "xb2,oa1", "--frames", "2", "--json"],
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
    result = subprocess.run([sys.executable, "-m", "ncbot", "robot", "render", "-o", str(tmp_path / "x.png")],
                            capture_output=True, text=True, timeout=300, env=env)
    assert result.returncode == 2
    assert "scripts/setup.sh" in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
