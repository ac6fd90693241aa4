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
