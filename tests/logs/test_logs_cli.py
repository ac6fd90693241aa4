"""`ncbot logs ...` on real log files: every command, and one clear line + exit 2 for bad input."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from ncbot.logs import EpisodeLogger
from tests.logs.helpers import NamedEnv, fake_batch, run_cli

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run with train episodes at growing env_steps, periodic eval episodes, and one robot game."""
    directory = tmp_path_factory.mktemp("run")
    with EpisodeLogger(directory, run_info={"test": True}, max_file_bytes=20_000) as log:
        for block in range(4):
            log.record_steps(fake_batch(3, 12, {0: [3, 9], 1: [6], 2: [2, 5, 11]}, seed=block), phase="train",
                             agent="proposed", seed=0, epsilon=1.0 - 0.2 * block, env_steps=36 * (block + 1),
                             env=NamedEnv())
            log.record_steps(fake_batch(2, 4, {0: [3], 1: [3]}, seed=100 + block), phase="eval", agent="proposed",
                             seed=0, env_steps=36 * (block + 1), env=NamedEnv())
        log.record_steps(fake_batch(1, 5, {0: [4]}, seed=7), phase="robot", agent="proposed", seed=0, env=NamedEnv())
        log.log_camera(b"\xff\xd8\xff" + bytes(100) + b"\xff\xd9", t=0.0)
        log.log_joint_states(["HeadPitch"], [0.3])
    return directory


def test_inspect_text_and_json(run_dir: Path, capsys: pytest.CaptureFixture) -> None:
    code, out, err = run_cli("logs", "inspect", run_dir, capsys=capsys)
    assert code == 0, err
    assert "/step" in out and "ncbot.Step" in out and "truncated: no" in out and "robot" in out
    code, out, _ = run_cli("logs", "inspect", run_dir, "--json", capsys=capsys)
    summary = json.loads(out)
    assert {"episodes", "by_phase", "channels", "truncated"} <= set(summary)
    assert summary["episodes"] == 4 * 6 + 4 * 2 + 1
    assert summary["by_phase"]["train"]["episodes"] == 24 and summary["by_phase"]["eval"]["episodes"] == 8
    assert sum(summary["by_phase"]["train"]["outcomes"].values()) == 24
    assert summary["channels"]["/board/image"]["messages"] == 5  # robot game only
    assert summary["channels"]["/camera/bottom/compressed"]["schema"] == "foxglove.CompressedImage"
    assert len(summary["files"]) >= 2 and summary["truncated"] is False


def test_episodes_table_filters(run_dir: Path, capsys: pytest.CaptureFixture) -> None:
    code, out, _ = run_cli("logs", "episodes", run_dir, "--phase", "eval", "--limit", "3", capsys=capsys)
    assert code == 0
    rows = [line for line in out.splitlines()[1:-1]]
    assert len(rows) == 3 and all(" eval " in row for row in rows)
    assert out.splitlines()[-1].startswith("3 of 8 matching")
    code, out, _ = run_cli("logs", "episodes", run_dir, "--outcome", "win", capsys=capsys)
    assert code == 0 and all(" win " in row for row in out.splitlines()[1:-1])


def test_show_replays_one_dialogue(run_dir: Path, capsys: pytest.CaptureFixture) -> None:
    code, out, err = run_cli("logs", "show", run_dir, "0", capsys=capsys)
    assert code == 0, err
    assert out.startswith("episode 0: train standard agent=proposed")
    assert "[step 0] robot chose act_" in out and "ROBOT: utterance number" in out and "Q: " in out
    assert "A_hat=" in out and "mask=[0, " in out
    assert sum(1 for line in out.splitlines() if line.strip().startswith("[step")) == 3  # first to end: row 2 at t=2


def test_curve_writes_a_png(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    output = tmp_path / "curve.png"
    code, out, err = run_cli("logs", "curve", run_dir, "-o", output, "--window", "5", capsys=capsys)
    assert code == 0, err
    assert output.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and output.stat().st_size > 10_000
    assert out.startswith("proposed: train task success") and "last eval task success" in out
    assert "(2 games at 144 env steps)" in out  # the last periodic evaluation: 2 games at env_steps 36 * 4


def test_to_rerun_writes_a_recording(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    output = tmp_path / "run.rrd"
    code, out, err = run_cli("logs", "to-rerun", run_dir, "-o", output, "--episodes", "0-2,32", capsys=capsys)
    assert code == 0, err
    assert output.stat().st_size > 1000 and "4 episodes" in out and "1 camera frames" in out
    rerun = shutil.which("rerun")
    if rerun:  # read the recording back with rerun's own tool
        printed = subprocess.run([rerun, "rrd", "print", str(output)], capture_output=True, text=True, timeout=120)
        assert printed.returncode == 0, printed.stderr
        for entity in ("/board - ", "/dialogue - ", "/reward - ", "/q/act_", "/camera - "):
            assert entity in printed.stdout


@pytest.mark.parametrize("command", [["inspect"], ["episodes"], ["show", "PATH", "0"], ["curve", "PATH", "-o", "c.png"],
                                     ["to-rerun", "PATH", "-o", "r.rrd"]])
def test_bad_input_is_one_line_and_exit_2(command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from mcap.writer import Writer

    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    text = tmp_path / "notes.mcap"
    text.write_text("not an mcap file\n")
    foreign = tmp_path / "foreign.mcap"
    with open(foreign, "wb") as handle:
        writer = Writer(handle)
        writer.start()
        writer.register_channel("/lidar", "json", writer.register_schema("x", "jsonschema", b"{}"))
        writer.finish()
    cases = {tmp_path / "missing.mcap": "does not exist", empty: "is empty", text: "is not an MCAP file",
             foreign: "without ncbot channels"}
    for path, message in cases.items():
        args = [str(path) if part == "PATH" else str(tmp_path / part) if part in ("c.png", "r.rrd") else part
                for part in command]
        if len(args) == 1:
            args.append(str(path))
        code, out, err = run_cli("logs", *args, capsys=capsys)
        assert code == 2, (args, out, err)
        assert len(err.strip().splitlines()) == 1 and message in err and "Traceback" not in err


def test_unknown_episode_and_bad_options(run_dir: Path, capsys: pytest.CaptureFixture) -> None:
    code, _, err = run_cli("logs", "show", run_dir, "999", capsys=capsys)
    assert code == 2 and "episode 999 is not in" in err
    code, _, err = run_cli("logs", "episodes", run_dir, "--phase", "testing", capsys=capsys)
    assert code == 2 and "--phase must be one of" in err
    code, _, err = run_cli("logs", "to-rerun", run_dir, "-o", "x.rrd", "--episodes", "a-b", capsys=capsys)
    assert code == 2 and "bad --episodes value" in err


def test_truncated_run_is_reported(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    last = sorted(run_dir.glob("*.mcap"))[0]
    cut = tmp_path / "cut.mcap"
    data = last.read_bytes()
    cut.write_bytes(data[: len(data) - 700])
    code, out, err = run_cli("logs", "inspect", cut, "--json", capsys=capsys)
    assert code == 0, err
    summary = json.loads(out)
    assert summary["truncated"] is True and summary["files"][0]["cut_bytes"] > 0
    code, out, _ = run_cli("logs", "inspect", cut, capsys=capsys)
    assert "TRUNCATED" in out and "bytes unreadable" in out


def test_console_script_prints_no_traceback(tmp_path: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "ncbot", "logs", "inspect", str(tmp_path / "nope")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "does not exist" in result.stderr
