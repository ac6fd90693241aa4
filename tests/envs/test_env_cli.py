"""`ncbot env describe` prints both tables and turns bad input into one line + exit code 2."""
from __future__ import annotations

import subprocess
import sys

from typer.testing import CliRunner

from ncbot.pipelines.cli.app import app


def run(*args: str):
    """In-process run (fast); the exit-code path through pipelines.cli.app.main is checked by a subprocess below."""
    return CliRunner().invoke(app, ["env", *args])


def test_describe_standard_lists_every_feature_and_action() -> None:
    result = run("describe", "--game", "standard")
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "73 features, 18 actions, vocabulary of 39 words" in out
    assert "   72  time[8]" in out and "word[hello]" in out and "command[read]" in out
    assert "Request(userGameMove)" in out and "[who=rob, what=draw, where=b2]" in out
    assert "GameMove(b2)" in out and "gridloc" not in out  # cells as the board names them


def test_describe_ultimate_without_temporal() -> None:
    result = run("describe", "--game", "ultimate", "--no-temporal")
    assert result.exit_code == 0, result.output
    assert "208 features, 90 actions" in result.stdout and "time[" not in result.stdout


def test_bad_game_is_one_line_exit_2() -> None:
    result = subprocess.run([sys.executable, "-m", "ncbot", "env", "describe", "--game", "chess"], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "ncbot: error: game must be one of standard, ultimate, connect_four, four, a game YAML file or an import path MODULE:CLASS / FILE.py:CLASS; got 'chess'"]
