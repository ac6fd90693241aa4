"""The CLI is installed and lists its subcommands."""
import subprocess
import sys


def test_ncbot_help_runs() -> None:
    result = subprocess.run([sys.executable, "-m", "ncbot", "--help"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "ncbot" in result.stdout
