"""`ncbot robot serve --learn`: each participant's games teach the robot's reader, in the study folder, resumed by
the participant's next session (real server, real SAPIEN sessions, scripted people over the websocket)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ncbot.pipelines.online.serving import person_folder
from tests.serve.helpers import running_server

pytestmark = pytest.mark.sapien
STUDY = Path(__file__).resolve().parents[2] / "bench" / "serve_study.py"


def test_a_participants_games_are_learned_from_and_a_later_server_resumes_them(tmp_path: Path) -> None:
    out = tmp_path / "study"
    for _ in range(2):  # a server stopped after one game, then another on the same folder
        with running_server(out, "--learn") as url:  # the scripted person of seed 0 is participant "scripted-0"
            done = subprocess.run([sys.executable, str(STUDY), "--url", url, "--sessions", "1", "--games", "1"],
                                  capture_output=True, text=True, timeout=600)
            assert done.returncode == 0, done.stderr[-2000:]
    state = json.loads((out / "learning" / "scripted-0" / "state.json").read_text())
    assert state["games"] == 2 and [entry["game"] for entry in state["per_game"]] == [0, 1]
    assert state["play"] is None, "no checkpoint: only the reader learns"
    assert all(entry["reader"]["views"] >= 3 for entry in state["per_game"])
    assert (out / "learning" / "scripted-0" / "reader" / "reader.pt").is_file()


def test_a_participant_code_becomes_a_safe_folder_name(tmp_path: Path) -> None:
    assert person_folder(tmp_path, "../../etc/passwd") == tmp_path / "learning" / "_.._etc_passwd"
    assert person_folder(tmp_path, "ada-7") == tmp_path / "learning" / "ada-7"
    assert person_folder(tmp_path, "") == tmp_path / "learning" / "_"
