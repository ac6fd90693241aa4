"""The episode logger writes real MCAP files; the reader gets back exactly what was logged, also after a crash."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from ncbot.logs import EpisodeLogger, LogReader, read_episode_records, read_episodes
from ncbot.logs.summary import summarize
from tests.logs.helpers import NamedEnv, expected_episodes, fake_batch

torch.set_num_threads(1)
DONE_AT = {0: [3, 9], 1: [6], 2: [2, 5, 11]}


def write_batch(run_dir: Path, td, **options) -> list[int]:
    with EpisodeLogger(run_dir, run_info={"config": {"lr": 1e-3}}, **options) as log:
        return log.record_steps(td, phase="train", agent="proposed", seed=7, epsilon=0.25, env_steps=1234,
                                env=NamedEnv())


@pytest.mark.parametrize("detail", ["packed", "per_action"])
def test_round_trip_matches_what_was_logged(detail: str, tmp_path: Path) -> None:
    td = fake_batch(3, 12, DONE_AT)
    ids = write_batch(tmp_path, td, step_detail={"train": detail})
    topics = LogReader(tmp_path).scan()[0].counts
    # per action, steps stream out as they come (also the 7 of unfinished episodes); packed waits for the end
    assert (topics["/episode/steps"], topics["/step"]) == ((6, 0) if detail == "packed" else (0, 36))
    expected = expected_episodes(td)  # in the order episodes end, like `ids`
    assert sorted(ids) == list(range(len(expected))) == list(range(6))
    records = read_episode_records(tmp_path)
    assert sorted(key for key, record in records.items() if record.summary) == sorted(ids)
    names = NamedEnv()
    for episode_id, want in zip(ids, expected):
        record = records[episode_id]
        summary = record.summary
        assert summary["phase"] == "train" and summary["agent"] == "proposed" and summary["seed"] == 7
        assert summary["game"] == "standard" and summary["epsilon"] == 0.25 and summary["env_steps"] == 1234
        assert summary["outcome"] == want.outcome and summary["seat"] == want.seat
        assert summary["length"] == len(want.steps) == len(record.steps) == len(record.boards)
        assert summary["return"] == pytest.approx(want.total, abs=1e-3)
        assert summary["task_success"] == (want.outcome in ("win", "draw"))
        assert summary["truncated"] == want.truncated
        for step, board, want_step in zip(record.steps, record.boards, want.steps):
            assert step["act"] == want_step["act"] and step["step"] == want_step["step"] == board["step"]
            assert step["mask"] == want_step["mask"]
            assert step["A"] == want_step["A"] and step["A_hat"] == want_step["A_hat"]
            assert step["reward"] == pytest.approx(want_step["reward"])
            assert np.allclose(step["q"], want_step["q"], rtol=1e-3, atol=1e-3)  # float16: 3 significant digits
            assert board["cells"] == want_step["cells"] and board["size"] == 3
            features = np.zeros(len(want_step["features"]), np.float32)
            features[step["on"]] = 1.0
            for index, value in step.get("val", []):
                features[int(index)] = value
            assert np.allclose(features, want_step["features"], atol=1e-3)
        robot_turns = [turn for turn in record.dialogue if turn["speaker"] == "robot"]
        user_turns = [turn for turn in record.dialogue if turn["speaker"] == "user"]
        assert [turn["text"] for turn in robot_turns] == [names.templates[s["act"]] for s in want.steps]
        assert [turn["command"] for turn in robot_turns] == [names.robot_commands[s["act"]] for s in want.steps]
        assert [turn["act"] for turn in user_turns] == [s["user_act"] for s in want.steps if s["user_act"] >= 0]
        for turn in user_turns:
            assert turn["act_name"] == names.user_act_names[turn["act"]]
        texts = [names.model.utterance_texts[s["utterance"]] for s in want.steps if s["user_act"] >= 0]
        assert [turn["text"] for turn in user_turns] == texts
        said = {"Yes, sure!": ["yes"], "No.": ["no"], "My name is Sam": ["name"], "bye": []}
        for turn, want_step in zip(user_turns, [s for s in want.steps if s["user_act"] >= 0]):
            assert [word for word, _ in turn.get("words", [])] == said[turn["text"]]
            for word, confidence in turn.get("words", []):
                column = names.feature_names.index(f"word[{word}]")
                assert confidence == pytest.approx(float(want_step["next_features"][column]), abs=1e-3)


def test_log_times_increase_and_names_and_run_info_are_stored(tmp_path: Path) -> None:
    write_batch(tmp_path, fake_batch(3, 12, DONE_AT), step_detail={"train": "per_action"})
    reader = LogReader(tmp_path)
    times = [message.log_time for message in reader.messages()]
    assert len(times) > 50 and all(b > a for a, b in zip(times, times[1:]))
    scan = reader.scans[reader.files[0]]
    assert '"lr": 0.001' in scan.metadata["ncbot.run"]["run_info"]
    assert reader.names()["action_names"].startswith('["act_0"')


def test_unfinished_episodes_wait_across_calls_and_single_steps_equal_a_batch(tmp_path: Path) -> None:
    td = fake_batch(3, 12, DONE_AT, seed=3)
    with EpisodeLogger(tmp_path / "batch") as log:  # eval is packed by default
        batch_ids = log.record_steps(td, phase="eval", agent="a", seed=0, env=NamedEnv())
    with EpisodeLogger(tmp_path / "steps", step_detail={"eval": "per_action"}, board_image_phases=("eval",)) as log:
        ids = []
        for t in range(12):  # one env step at a time, batch size (B,)
            ids += log.record_steps(td[:, t], phase="eval", agent="a", seed=0, env=NamedEnv())
    assert batch_ids == [0, 1, 2, 3, 4, 5] and sorted(ids) == batch_ids  # per action: ids given at the first step
    by_batch = read_episode_records(tmp_path / "batch")
    by_step = read_episode_records(tmp_path / "steps")
    for packed_id, streamed_id in zip(batch_ids, ids):  # both lists are in the order episodes ended

        def renumbered(messages: list[dict]) -> list[dict]:
            return [{**message, "episode": packed_id} for message in messages]

        assert by_batch[packed_id].steps == renumbered(by_step[streamed_id].steps)
        assert by_batch[packed_id].boards == renumbered(by_step[streamed_id].boards)
        assert by_batch[packed_id].dialogue == renumbered(by_step[streamed_id].dialogue)
        assert by_batch[packed_id].summary["length"] == by_step[streamed_id].summary["length"]
    # board images are drawn for eval episodes: one PNG per step
    counts = LogReader(tmp_path / "steps").scan()[0].counts
    assert counts["/board/image"] == counts["/board"] == 36  # every step, also of the unfinished episodes


def test_training_phase_has_no_board_images_and_step_detail_none_keeps_only_summaries(tmp_path: Path) -> None:
    td = fake_batch(3, 12, DONE_AT)
    write_batch(tmp_path / "a", td)
    assert "/board/image" not in LogReader(tmp_path / "a").scan()[0].counts
    with EpisodeLogger(tmp_path / "b", step_detail={"train": "none"}) as log:
        log.record_steps(td, phase="train", agent="a", seed=0)
    counts = LogReader(tmp_path / "b").scan()[0].counts
    assert counts["/episode"] == 6 and counts["/step"] == counts["/episode/steps"] == counts["/dialogue"] == 0
    assert [e["length"] for e in read_episodes(tmp_path / "b")] == [e["length"] for e in read_episodes(tmp_path / "a")]
    with pytest.raises(ValueError, match="step_detail for train must be one of"):
        EpisodeLogger(tmp_path / "c", step_detail={"train": "everything"})


def test_rollover_by_size_keeps_episodes_whole_and_ids_continue_on_reopen(tmp_path: Path) -> None:
    with EpisodeLogger(tmp_path, max_file_bytes=3000) as log:
        for seed in range(6):
            log.record_steps(fake_batch(3, 12, DONE_AT, seed=seed), phase="train", agent="a", seed=0)
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) >= 3 and files[0] == "episodes-0000.mcap"
    per_file = [read_episode_records(tmp_path / name) for name in files]
    for records in per_file:  # every episode lives wholly in one file
        for record in records.values():
            assert record.summary is not None and len(record.steps) == record.summary["length"]
    assert sorted(e["episode"] for e in read_episodes(tmp_path)) == list(range(36))
    with EpisodeLogger(tmp_path) as log:  # a second process (e.g. eval) appends to the same run
        ids = log.record_steps(fake_batch(3, 12, DONE_AT), phase="eval", agent="a", seed=0)
        assert log.current_file.name == f"episodes-{len(files):04d}.mcap"
    assert ids == [36, 37, 38, 39, 40, 41]


def test_cut_off_file_is_recovered_up_to_the_cut(tmp_path: Path) -> None:
    with EpisodeLogger(tmp_path, flush_interval_s=0.0) as log:
        for seed in range(8):
            log.record_steps(fake_batch(3, 12, DONE_AT, seed=seed), phase="train", agent="a", seed=0)
    path = tmp_path / "episodes-0000.mcap"
    whole = path.read_bytes()
    path.write_bytes(whole[: int(len(whole) * 0.6)])
    episodes = read_episodes(path)
    assert 10 <= len(episodes) < 40
    assert [e["episode"] for e in episodes] == list(range(len(episodes)))
    summary = summarize(path)
    assert summary["truncated"] is True and summary["episodes"] == len(episodes)
    assert 0 < summary["files"][0]["cut_bytes"] < len(whole) * 0.4
    assert summary["by_phase"]["train"]["episodes"] == len(episodes)


WRITER_SCRIPT = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {root!r})
    from ncbot.logs import EpisodeLogger
    from tests.logs.helpers import fake_batch
    log = EpisodeLogger({run_dir!r}, flush_interval_s=0.0)
    done_at = {{0: [3, 9], 1: [6], 2: [2, 5, 11]}}
    written = 0
    seed = 0
    while True:
        written += len(log.record_steps(fake_batch(3, 12, done_at, seed=seed), phase="train", agent="a", seed=0))
        seed += 1
        print(written, flush=True)
        if written > 40:
            time.sleep(0.01)
""")


def test_kill_9_while_writing_leaves_a_readable_file(tmp_path: Path) -> None:
    script = WRITER_SCRIPT.format(root=str(Path(__file__).resolve().parents[2]), run_dir=str(tmp_path))
    process = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                               cwd=Path(__file__).resolve().parents[2])
    try:
        flushed = 0
        deadline = time.monotonic() + 60
        while flushed < 60 and time.monotonic() < deadline:
            line = process.stdout.readline()
            if not line:
                break
            flushed = int(line)
        os.kill(process.pid, signal.SIGKILL)
        process.wait(timeout=10)
    finally:
        if process.poll() is None:
            process.kill()
    assert flushed >= 60, "the writer did not get going"
    episodes = read_episodes(tmp_path)
    assert len(episodes) >= flushed  # everything reported as flushed before the kill is there
    assert [e["episode"] for e in episodes] == list(range(len(episodes)))
    assert summarize(tmp_path)["truncated"] is True
    with EpisodeLogger(tmp_path) as log:  # a new run after the crash continues the ids of what was recovered
        assert log.new_episode_id() == len(episodes)


def test_robot_streams_round_trip_as_foxglove_protobuf(tmp_path: Path) -> None:
    jpeg = bytes([0xFF, 0xD8, 0xFF]) + bytes(range(200)) + bytes([0xFF, 0xD9])
    with EpisodeLogger(tmp_path) as log:
        log.log_camera(jpeg, t=1.5)
        log.log_joint_states(["HeadPitch", "RShoulderPitch"], [0.1, -0.4], velocities=[0.0, 0.2], t=1.5)
        log.log_transform("world", "base_link", (0.5, -0.2, 0.0), (0.0, 0.0, 0.7071, 0.7071), t=1.5)
        log.log_step({"episode": 0, "step": 0, "who": "robot", "act": 3, "mask": [1, 3], "reward": 0.0})
        log.log_episode({"episode": 0, "phase": "robot", "game": "standard", "agent": "proposed", "seed": 0,
                         "seat": "first", "outcome": "draw", "return": 1.0, "length": 1, "task_success": True})
    messages = {m.topic: m for m in LogReader(tmp_path).messages()}
    camera = messages["/camera/bottom/compressed"].data
    assert camera.data == jpeg and camera.format == "jpeg" and camera.timestamp.ToNanoseconds() == 1_500_000_000
    joints = messages["/joint_states"].data.joints
    assert [j.name for j in joints] == ["HeadPitch", "RShoulderPitch"] and joints[1].position == pytest.approx(-0.4)
    transform = messages["/tf"].data
    assert transform.child_frame_id == "base_link" and transform.translation.x == pytest.approx(0.5)
    assert messages["/episode"].data["outcome"] == "draw"
    schemas_seen = LogReader(tmp_path).scan()[0].channels
    assert schemas_seen["/camera/bottom/compressed"] == ("foxglove.CompressedImage", "protobuf")


def test_bad_input_to_the_logger_is_one_clear_error(tmp_path: Path) -> None:
    with EpisodeLogger(tmp_path) as log:
        with pytest.raises(ValueError, match="action_mask"):
            td = fake_batch(2, 3, {})
            del td["action_mask"]
            log.record_steps(td, phase="train", agent="a", seed=0)
        with pytest.raises(ValueError, match="phase must be one of"):
            log.record_steps(fake_batch(2, 3, {}), phase="training", agent="a", seed=0)
        with pytest.raises(ValueError, match="missing episode"):
            log.log_board({"step": 0, "cells": "000000000", "size": 3})
        with pytest.raises(ValueError, match="non-empty bytes"):
            log.log_camera(b"")
    with pytest.raises(ValueError, match="closed"):
        log.log_step({"episode": 0, "step": 0, "who": "robot", "act": 3, "mask": [1], "reward": 0.0})
    with pytest.raises(NotADirectoryError):
        EpisodeLogger(tmp_path / "episodes-0000.mcap")


def test_foreign_mcap_is_rejected(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as handle:
        writer = Writer(handle)
        writer.start()
        schema = writer.register_schema("other.Thing", "jsonschema", b"{}")
        channel = writer.register_channel("/lidar", "json", schema)
        writer.add_message(channel, log_time=1, publish_time=1, data=b"{}")
        writer.finish()
    with pytest.raises(ValueError, match="without ncbot channels"):
        summarize(path)


def test_an_abandoned_episode_is_not_glued_to_the_next_one(tmp_path: Path) -> None:
    first = fake_batch(2, 4, {})  # two games cut off after 4 steps (e.g. an eval env closed mid-game)
    second = fake_batch(2, 5, {0: [4], 1: [4]}, seed=1)  # fresh games: turn starts again at 0
    with EpisodeLogger(tmp_path) as log:
        assert log.record_steps(first, phase="eval", agent="a", seed=0) == []
        assert log.record_steps(second, phase="eval", agent="a", seed=0) == [0, 1]
    records = read_episode_records(tmp_path)
    assert [len(records[i].steps) for i in (0, 1)] == [5, 5]
    assert [s["step"] for s in records[0].steps] == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_real_env_games_round_trip(game: str, tmp_path: Path) -> None:
    from ncbot.envs import make_env

    env = make_env(game=game, batch_size=(4,), seed=5, first="alternate")
    generator = torch.Generator().manual_seed(5)
    steps_by_slot: dict[int, list] = {b: [] for b in range(4)}
    finished, ids = [], []
    td = env.reset()
    with EpisodeLogger(tmp_path, step_detail={"eval": "per_action"}, board_image_phases=("eval",)) as log:
        while len(finished) < 6:
            td["action"] = torch.multinomial(td["action_mask"].float(), 1, generator=generator).squeeze(-1)
            td["action_value"] = torch.randn(td["action_mask"].shape, generator=generator)
            td, root = env.step_and_maybe_reset(td)
            for b in range(4):
                steps_by_slot[b].append(td[b].clone())
                if td["next", "done"][b]:
                    finished.append(steps_by_slot[b])
                    steps_by_slot[b] = []
            ids += log.record_steps(td, phase="eval", agent="random", seed=5, env=env)
            td = root
    records = read_episode_records(tmp_path)
    assert len(ids) == len(finished) >= 6
    for episode_id, steps in zip(ids, finished):  # both in the order episodes ended
        record = records[episode_id]
        assert record.summary["game"] == game and record.summary["length"] == len(steps)
        assert record.summary["outcome"] == ("none", "win", "loss", "draw")[int(steps[-1]["next", "outcome"])]
        assert [s["act"] for s in record.steps] == [int(step["action"]) for step in steps]
        assert [b["cells"] for b in record.boards] == ["".join(map(str, step["next", "board"].tolist())) for step in steps]
        robot = [turn for turn in record.dialogue if turn["speaker"] == "robot"]
        assert [f"{t['text']} [{t['command']}]" for t in robot] == [env.describe_action(int(s["action"])) for s in steps]
        user = [turn for turn in record.dialogue if turn["speaker"] == "user"]
        spoken = [env.user_utterance(int(s["next", "user_utterance"])) for s in steps if int(s["next", "user_act"]) >= 0]
        assert [turn.get("text", "") for turn in user] == spoken
    counts = LogReader(tmp_path).scan()[0].counts
    assert counts["/board/image"] == counts["/board"] >= sum(len(steps) for steps in finished[:6])


def test_inactive_rows_are_not_logged(tmp_path: Path) -> None:
    td = fake_batch(3, 12, DONE_AT)
    with EpisodeLogger(tmp_path) as log:
        ids = log.record_steps(td, phase="eval", agent="a", seed=0, active=torch.tensor([True, False, True]))
        with pytest.raises(ValueError, match="one flag per batch row"):
            log.record_steps(td, phase="eval", agent="a", seed=0, active=torch.tensor([True, False]))
    assert len(ids) == 5  # row 1's single episode is left out
    lengths = sorted(e["length"] for e in read_episodes(tmp_path))
    assert lengths == sorted([4, 6, 3, 3, 6])


def test_robot_steps_are_written_when_they_happen_between_camera_frames(tmp_path: Path) -> None:
    td = fake_batch(1, 3, {0: [2]})
    with EpisodeLogger(tmp_path) as log:
        for t in range(3):  # a robot game: one step at a time, camera frames in between
            log.log_camera(b"\xff\xd8" + bytes([t]) + b"\xff\xd9")
            log.record_steps(td[:, t], phase="robot", agent="a", seed=0, env=NamedEnv())
    order = [m.topic for m in LogReader(tmp_path).messages(["/camera/bottom/compressed", "/step", "/episode"])]
    assert order == ["/camera/bottom/compressed", "/step"] * 3 + ["/episode"]


def test_curve_series_spreads_batches_and_places_final_eval() -> None:
    from ncbot.logs.curve import curve_series

    train = [{"phase": "train", "agent": "p", "seed": 0, "env_steps": steps, "task_success": ok, "return": 1.0,
              "length": 10} for steps, ok in [(100, True), (100, False), (200, True), (200, True)]]
    final = [{"phase": "eval", "agent": "p", "seed": 9, "env_steps": None, "task_success": True, "return": 2.0,
              "length": 10}] * 3
    series = curve_series(train + final, window=2)["p"]
    assert series["train"]["x"].tolist() == [100.0, 150.0, 200.0]  # 2 episodes per batch spread over its frames
    assert series["train"]["task_success"].tolist() == [0.5, 0.5, 1.0]
    assert series["eval"]["x"].tolist() == [200.0] and series["eval"]["games"] == [3]
    assert series["eval"]["reward_per_step"].tolist() == [0.2]
