"""Progress fits where it goes: redraws with rate and ETA on a terminal, one plain line per ~10 % in a pipe."""
from __future__ import annotations

import fcntl
import os
import pty
import struct
import termios
import subprocess
import sys
import textwrap

LOOP = textwrap.dedent("""
    import time
    from ncbot.pipelines.progress import progress_bar
    bar = progress_bar(total=200, desc="work", unit="step")
    for _ in range(200):
        time.sleep(0.002)
        bar.update(1)
        bar.set_postfix(eps="0.5", refresh=False)
    bar.close()
""")


def _run(stderr_fd: int | None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", LOOP], stdout=subprocess.DEVNULL,
                            stderr=stderr_fd if stderr_fd is not None else subprocess.PIPE)


def test_a_pipe_gets_one_plain_line_per_tenth_with_rate_and_eta() -> None:
    process = _run(None)
    _, err = process.communicate(timeout=60)
    text = err.decode()
    assert process.returncode == 0, text
    assert "\r" not in text
    lines = text.splitlines()
    assert len(lines) == 10, lines  # 10 %, 20 %, ..., 90 %, then the closing 100 % line
    assert lines[0].startswith("work:  10% 20/200 step [") and "ETA" in lines[0] and "step/s]" in lines[0]
    assert lines[-1].startswith("work: 100% 200/200 step [") and lines[-1].endswith("eps=0.5")


def test_a_terminal_gets_a_redrawn_tqdm_bar() -> None:
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a real terminal has a width
    process = _run(follower)
    os.close(follower)
    chunks = []
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    process.wait(timeout=60)
    os.close(leader)
    text = b"".join(chunks).decode(errors="replace")
    assert process.returncode == 0, text
    assert text.count("\r") > 1 and "200/200" in text and "step/s" in text  # tqdm redraws in place, with rate


def test_disabled_progress_prints_nothing(capsys) -> None:
    from ncbot.pipelines.progress import progress_bar

    with progress_bar(total=5, disable=True) as bar:
        for _ in range(5):
            bar.update(1)
    assert capsys.readouterr().err == ""


def test_work_past_its_estimate_reads_100_percent_not_more() -> None:
    import io

    from ncbot.pipelines.progress import progress_bar

    stream = io.StringIO()
    bar = progress_bar(total=20000, desc="train", unit="frame", unit_scale=True, stream=stream)
    for _ in range(10):  # whole collector batches: 20480 frames for a budget of 20000
        bar.update(2048)
    bar.close()
    last = stream.getvalue().splitlines()[-1]
    assert last.startswith("train: 100% 20.5k/20.5k frame"), last
    import re

    assert max(int(p) for p in re.findall(r"(\d+)%", stream.getvalue())) == 100
    resumed = io.StringIO()
    progress_bar(total=100, initial=120, unit="game", stream=resumed).close()  # resumed past its total
    assert "100% 120/120 game" in resumed.getvalue()


def test_rates_read_as_people_write_them() -> None:
    from ncbot.pipelines.progress import rate_text

    assert [rate_text(r) for r in (7463.1, 312.4, 42.25, 4.21, 0.349)] == ["7.5k", "312", "42.2", "4.2", "0.35"]


def test_an_error_inside_a_bar_leaves_no_progress_line(capsys) -> None:
    import pytest

    from ncbot.pipelines.progress import progress_bar

    with pytest.raises(ValueError):
        with progress_bar(total=5, desc="eval", unit="game") as bar:
            bar.update(0)
            raise ValueError("games must be a positive number")
    assert capsys.readouterr().err == ""


def test_silence_turns_every_bar_off(capsys) -> None:
    from ncbot.pipelines.progress import progress_bar, silence

    silence()
    try:
        with progress_bar(total=3, desc="quiet") as bar:
            bar.update(3)
    finally:
        silence(False)
    assert capsys.readouterr().err == ""
    with progress_bar(total=1, desc="loud") as bar:
        bar.update(1)
    assert "loud: 100%" in capsys.readouterr().err
