"""A game given as code (docs/examples/misere.py) on the robot's sheet: named by its import path, rendered by the
mouth camera with marks in its cells, and read back by the grid reader."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.sapien
MISERE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "misere.py"


def _ncbot(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True)


def test_the_misere_plugin_is_drawn_on_the_sheet_and_read_back(tmp_path):
    frame = tmp_path / "misere.png"
    rendered = _ncbot("robot", "render", "--game", f"{MISERE}:Misere", "--marks", "xa1,ob2,xc3,oa3", "--frames", "1",
                      "-o", str(frame))
    assert rendered.returncode == 0, rendered.stderr
    read = _ncbot("vision", "read", str(frame), "--grid", "3x3", "--json")
    assert read.returncode == 0, read.stderr
    assert json.loads(read.stdout)["images"][0]["cells"] == ["x", "", "", "", "o", "", "o", "", "x"]  # row-major from a1
