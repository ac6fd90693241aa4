"""`ncbot play` driven as a person would: the real program in a pseudo-terminal (pexpect), then its MCAP log read back."""
from __future__ import annotations

import re
import signal
import sys

import pexpect
import pytest

from ncbot.envs.games import make_game

PROMPTS = [r"Your move \(e\.g\. [a-i]\d\): ", r"You: ", pexpect.EOF]
ROW = re.compile(r"^(\d)\s+(\S.*)?$")


def _spawn(tmp_path, *args: str) -> pexpect.spawn:
    # SIGINT back to its default in the child: a suite run as a background job inherits it ignored, and Ctrl-C
    # would then never reach the game
    child = pexpect.spawn(sys.executable, ["-m", "ncbot", "play", *args], cwd=str(tmp_path.parent),
                          encoding="utf-8", timeout=60, env={"PYTHONUNBUFFERED": "1", "PATH": "/usr/bin:/bin",
                                                             "COLUMNS": "120", **_pythonpath()},
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    return child


def _pythonpath() -> dict[str, str]:
    import os

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return {"PYTHONPATH": root, "HOME": os.environ.get("HOME", "/root")}


def legal_from_board(text: str, size: int) -> list[str]:
    """Cells shown as · in the last board drawn in ``text`` (the program's legal-square view)."""
    rules = make_game("standard" if size == 3 else "ultimate")
    board_lines = [line for line in text.splitlines() if ROW.match(line.rstrip()) or re.match(r"^\d\s", line)]
    rows = board_lines[-size:]
    cells = []
    for row_index, line in enumerate(rows):
        body = line[4:]
        if size == 3:
            squares = [body[4 * c] if 4 * c < len(body) else " " for c in range(3)]
        else:
            squares = [body[8 * b + 2 * c] if 8 * b + 2 * c < len(body) else " " for b in range(3) for c in range(3)]
        cells += [rules.cell_name(row_index * size + c) for c, sym in enumerate(squares) if sym == "·"]
    return cells


REPLIES = {"Hello": "hello", "name": "my name is Ann", "play a game": "yes please", "won": "well done pepper",
           "draw": "good game", "goodbye": "goodbye"}


def _reply_to(before: str) -> str:
    last_robot = [line for line in before.splitlines() if line.startswith("Pepper:")]
    said = last_robot[-1] if last_robot else ""
    for key, answer in REPLIES.items():
        if key in said:
            return answer
    return "thank you"


def _play_to_the_end(child: pexpect.spawn, size: int) -> str:
    transcript = ""
    for _ in range(400):
        index = child.expect(PROMPTS)
        transcript += child.before + (child.after if isinstance(child.after, str) else "")
        if index == 2:
            return transcript
        if index == 0:
            child.sendline(legal_from_board(child.before, size)[0])
        else:
            child.sendline(_reply_to(child.before))
    raise AssertionError("the dialogue did not end in 400 exchanges:\n" + transcript[-2000:])


def test_a_full_standard_game_is_played_and_logged(tmp_path) -> None:
    logs = tmp_path / "playlog"
    child = _spawn(tmp_path, "--first", "robot", "--out", str(logs), "--seed", "3")
    transcript = _play_to_the_end(child, 3)
    child.close()
    assert child.exitstatus == 0, transcript[-1500:]
    assert "Traceback" not in transcript
    assert "Pepper: Hello, nice to meet you!" in transcript and "[who=rob, what=hello]" in transcript
    assert "    a   b   c" in transcript  # the board with coordinates
    assert re.search(r"Result: (robot won|you won|draw) after \d+ robot actions", transcript)

    from ncbot.logs import read_episodes

    episodes = read_episodes(logs)
    assert len(episodes) == 1
    episode = episodes[0]
    summary = episode if isinstance(episode, dict) else vars(episode)
    assert summary.get("game", "standard") == "standard"
    assert summary.get("outcome") in ("win", "loss", "draw")


def test_bad_input_is_explained_and_asked_again(tmp_path) -> None:
    child = _spawn(tmp_path, "--first", "human", "--no-log")
    child.expect("You: ")
    child.sendline("purple elephants")
    child.expect("did not understand 'purple elephants'")
    child.expect("You: ")
    child.sendline("b2")  # a cell while the robot is talking
    child.expect("not waiting for your move")
    child.expect("You: ")
    child.sendline("hello")
    for _ in range(6):  # name, play request, ... until the robot asks for our move
        index = child.expect([r"Your move \(e\.g\. [a-c]\d\): ", "You: "])
        if index == 0:
            break
        child.sendline(_reply_to(child.before))
    else:
        pytest.fail("the robot never asked for a move")
    child.sendline("zz")
    child.expect("not a cell of the standard board")
    child.expect("Your move")
    child.sendline("d7")
    child.expect("not a cell")
    child.expect("Your move")
    child.sendline("2b")  # one notation: column letter, then row
    child.expect("not a cell")
    child.expect("Your move")
    child.sendline("b2")
    child.expect(r"Your move \(e\.g\. [a-c]\d\): ")  # the robot moved; our next move
    child.sendline("b2")
    child.expect("already taken")
    child.sendline("quit")
    child.expect(pexpect.EOF)
    child.close()
    assert child.exitstatus == 0
    assert "Traceback" not in child.before


def test_ctrl_c_ends_cleanly(tmp_path) -> None:
    logs = tmp_path / "interrupted"
    child = _spawn(tmp_path, "-o", str(logs))
    child.expect("You: ")
    child.sendintr()
    child.expect(pexpect.EOF)
    child.close()
    assert "interrupted (Ctrl-C)" in child.before
    assert "Traceback" not in child.before
    assert child.exitstatus == 130
    from ncbot.logs import LogReader

    LogReader(logs)  # the log file was closed properly and reads back


def test_ultimate_game_from_the_first_seat(tmp_path) -> None:
    logs = tmp_path / "ultimate"
    child = _spawn(tmp_path, "--game", "ultimate", "--first", "human", "--out", str(logs), "--seed", "1")
    transcript = _play_to_the_end(child, 9)
    child.close()
    assert child.exitstatus == 0, transcript[-1500:]
    assert "a b c   d e f   g h i" in transcript
    assert "You are x, Pepper is o" in transcript
    from ncbot.logs import read_episodes

    assert len(read_episodes(logs)) == 1


def test_bad_options_are_one_line_errors(tmp_path) -> None:
    (tmp_path / "config.yaml").write_text("env: {game: standard}\n")
    for args, message in ((["--game", "chess"], "game must be one of standard, ultimate"),
                          (["--first", "third"], "--first must be one of robot, human"),
                          (["--seat", "first"], "No such option: --seat"),
                          ([str(tmp_path / "missing.pt")], "not found"),
                          ([str(tmp_path / "config.yaml")], "expected a checkpoint .pt or a run folder")):
        child = _spawn(tmp_path, *args)
        child.expect(pexpect.EOF)
        child.close()
        assert message in child.before and "Traceback" not in child.before
        assert child.exitstatus == 2
