"""`ncbot env describe` prints both tables and turns bad input into one line + exit code 2."""
from __future__ import annotations

import subprocess
import sys


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipelines.cli", "env", *args], capture_output=True, text=True)


def test_describe_standard_lists_every_feature_and_action() -> None:
    result = run("describe", "--game", "standard")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "73 features, 18 actions, vocabulary of 39 words" in out
    assert "   72  time[8]" in out and "word[hello]" in out and "command[read]" in out
    assert "Request(userGameMove)" in out and "[who=rob, what=draw, where=b2]" in out


def test_describe_ultimate_without_temporal() -> None:
    result = run("describe", "--game", "ultimate", "--no-temporal")
    assert result.returncode == 0, result.stderr
    assert "208 features, 90 actions" in result.stdout and "time[" not in result.stdout


def test_bad_game_is_one_line_exit_2() -> None:
    result = run("describe", "--game", "chess")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == ["ncbot: error: game must be one of standard, ultimate; got 'chess'"]
