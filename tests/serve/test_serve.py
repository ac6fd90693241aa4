"""`ncbot robot serve` over its real websocket protocol: forged and junk requests, several sessions at once,
idle sessions closed with their logs finished, the study summary, and the CLI's bad input."""
from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
import websockets

from ncbot.logs.reader import LogReader
from ncbot.logs.summary import summarize_study
from ncbot.pipelines.serve.answers import PREFERRED_ACTS
from tests.serve.helpers import running_server

pytestmark = [pytest.mark.sapien, pytest.mark.slow]
STUDY = Path(__file__).resolve().parents[2] / "bench" / "serve_study.py"


async def _state(ws, until=lambda m: True, timeout: float = 120.0) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        raw = await asyncio.wait_for(ws.recv(), timeout=max(0.1, deadline - time.monotonic()))
        if isinstance(raw, bytes):
            continue
        message = json.loads(raw)
        if message["type"] == "state" and until(message):
            return message


async def _until_turn(ws, timeout: float = 120.0) -> dict:
    """Answer the robot cooperatively (the first fitting button) until it is the person's turn to click."""
    answered = -1
    while True:
        state = await _state(ws, lambda m: m["your_turn"] or (m["answering"] and m["says_seq"] != answered), timeout)
        if state["your_turn"]:
            return state
        answered = state["says_seq"]
        await ws.send(json.dumps({"type": "act", "act": next(a for a in PREFERRED_ACTS if a in state["acts"])}))


async def _reply(ws, payload) -> dict:
    """Send one raw request and return the next non-state, non-frame answer."""
    if isinstance(payload, bytes):
        await ws.send(payload)
    else:
        await ws.send(payload if isinstance(payload, str) else json.dumps(payload))
    while True:
        raw = await asyncio.wait_for(ws.recv(), timeout=30)
        if isinstance(raw, bytes):
            continue
        message = json.loads(raw)
        if message["type"] in ("error", "pong"):
            return message


def _junk(own: str, other: str, taken: int) -> list:
    """200 bad requests: junk bytes and JSON, wrong types, out-of-range and taken cells, forged sessions."""
    base = ["", "{", "not json", "[]", "42", "null", '"move"', "{}", '{"type": 5}', '{"type": "explode"}',
            b"\x00\xff binary", "x" * 5000, json.dumps({"type": "move"}), json.dumps({"type": "start", "first": "robot"}),
            json.dumps({"type": "again"}), json.dumps({"type": "act", "act": "shout"}), json.dumps({"type": "view", "view": "x-ray"}),
            json.dumps({"type": "act", "act": "yes"}), json.dumps({"type": "say", "text": "hello"}),  # no answer awaited
            json.dumps({"type": "say", "text": 42}), json.dumps({"type": "say", "text": "yes " * 60}), json.dumps({"type": "say"}),
            json.dumps({"type": "tap", "cell": 4}), json.dumps({"type": "tap", "cell": "4"})]  # no tablet touch asked
    cells = [-1, 9, 81, 1000, 2**40, "4", 4.5, None, True, [4], {"c": 4}, taken]
    requests = list(base) + [json.dumps({"type": "move", "cell": c}) for c in cells]
    requests += [json.dumps({"type": "move", "cell": 0, "session": other}), json.dumps({"type": "move", "cell": 0, "session": "f" * 16}),
                 json.dumps({"type": "act", "act": "hello", "session": other}), json.dumps({"type": "move", "cell": taken, "session": own})]
    return [requests[i % len(requests)] for i in range(200)]


def test_forged_and_junk_requests_get_errors_and_change_nothing(tmp_path):
    out = tmp_path / "study"

    async def scenario(url: str) -> None:
        ws_url = url.replace("http", "ws")
        a = httpx.post(url + "/api/session", json={}).json()["session"]
        b = httpx.post(url + "/api/session", json={}).json()["session"]
        async with websockets.connect(f"{ws_url}/ws/{a}", max_size=None) as wa, \
                websockets.connect(f"{ws_url}/ws/{b}", max_size=None) as wb:
            await wa.send(json.dumps({"type": "start", "first": "robot"}))
            await wb.send(json.dumps({"type": "start", "first": "robot"}))
            state_a = await _until_turn(wa)
            state_b = await _until_turn(wb)
            taken = state_b["board"].index("x")
            answers = [await _reply(wb, junk) for junk in _junk(b, a, taken)]
            assert len(answers) == 200 and all(m["type"] == "error" and m["error"] for m in answers)
            assert any("taken" in m["error"] for m in answers) and any("out of range" in m["error"] for m in answers)
            assert any("another session" in m["error"] for m in answers) and any("not JSON" in m["error"] for m in answers)
            assert any("not waiting for an answer" in m["error"] for m in answers)
            assert any("not asking for a touch on its tablet" in m["error"] for m in answers)
            # Plain HTTP junk: clear 4xx answers.
            for path in ("/api/session/zzz", f"/api/session/{'0' * 16}", f"/audio/{a}/../../etc/passwd",
                         f"/audio/{a}/utterance-9999.wav", "/frame/nope.jpg"):
                assert 400 <= httpx.get(url + path).status_code < 500
            assert httpx.post(url + "/api/session", content=b"{bad").status_code == 400
            # Nothing changed, for either session, and both still play.
            now_a = httpx.get(f"{url}/api/session/{a}").json()
            now_b = httpx.get(f"{url}/api/session/{b}").json()
            assert now_a["board"] == state_a["board"] and now_a["your_turn"]
            assert now_b["board"] == state_b["board"] and now_b["your_turn"]
            free = now_b["board"].index("")
            await wb.send(json.dumps({"type": "move", "cell": free}))
            after = await _state(wb, lambda m: m["board"][free] == "o", timeout=120)
            assert after["board"][taken] == "x"
        # A person who never answers: after --answer-seconds the robot hears silence and goes on talking.
        c = httpx.post(url + "/api/session", json={}).json()["session"]
        async with websockets.connect(f"{ws_url}/ws/{c}", max_size=None) as wc:
            await wc.send(json.dumps({"type": "start", "first": "robot"}))
            asked = await _state(wc, lambda m: m["answering"])
            silent = await _state(wc, lambda m: "said nothing" in m["heard"], timeout=60)
            assert not silent["answering"]
            await _state(wc, lambda m: m["says_seq"] > asked["says_seq"], timeout=60)
        # A closed socket for an unknown session: a clear error, then closed.
        async with websockets.connect(f"{ws_url}/ws/{'0' * 16}") as ws:
            message = json.loads(await ws.recv())
            assert message["type"] == "error" and "unknown" in message["error"]
        assert httpx.get(url + "/healthz").json()["ok"]

    # --no-parallel: the one-simulator-lock mode stays tested (the other tests run the default, parallel sessions)
    with running_server(out, "--idle-seconds", "30", "--answer-seconds", "3", "--no-parallel") as url:
        asyncio.run(scenario(url))


def test_several_sessions_at_once_and_idle_sessions_are_closed_with_their_log(tmp_path):
    out = tmp_path / "study"
    with running_server(out, "--idle-seconds", "4", "--conditions", "office") as url:
        assert httpx.get(url + "/healthz").json()["conditions"] == "office"
        done = subprocess.run([sys.executable, str(STUDY), "--url", url, "--sessions", "3", "--games", "1", "--parallel", "3"],
                              capture_output=True, text=True, timeout=400)
        assert done.returncode == 0, done.stderr[-2000:]
        report = json.loads(done.stdout.strip().splitlines()[-1])
        assert len(report["outcomes"]) == 3 and set(report["outcomes"]) <= {"win", "loss", "draw"}
        assert report["click_to_reply_seconds"]["n"] >= 3
        abandoned = httpx.post(url + "/api/session", json={}).json()["session"]
        deadline = time.monotonic() + 30
        while httpx.get(f"{url}/api/session/{abandoned}").status_code == 200:
            assert time.monotonic() < deadline, "the idle session was not closed"
            time.sleep(0.5)
        deadline = time.monotonic() + 30
        while httpx.get(url + "/healthz").json()["sessions"]:
            assert time.monotonic() < deadline, "finished sessions were not closed when idle"
            time.sleep(0.5)
    study = summarize_study(out)
    assert study["sessions"] == 3 and study["games"] == 3 and study["truncated_sessions"] == 0
    episodes = [m.data["extra"] for folder in out.iterdir() for m in LogReader(folder).messages(["/episode"])]
    assert len(episodes) == 3 and {e["conditions"]["preset"] for e in episodes} == {"office"}  # --conditions reached the scenes
    assert study["misrecognised_moves"] == 0 and study["seconds_per_person_turn"]["median"] > 0
    printed = subprocess.run([sys.executable, "-m", "ncbot", "logs", "inspect", str(out)],
                             capture_output=True, text=True, check=True).stdout
    assert "sessions 3  games 3" in printed


def test_serve_cli_rejects_bad_input_with_one_line(tmp_path):
    bad_yaml = tmp_path / "conditions.yaml"
    bad_yaml.write_text("base: office\nlight_intensity: [0.3, 0.5]\nglitter: 3\n")
    for args in ([str(tmp_path / "missing.pt")], ["--game", "chess"], ["--idle-seconds", "0"],
                 ["--conditions", "basement"], ["--conditions", str(bad_yaml)], ["--answer-seconds", "0"],
                 ["--moves", "telepathy"]):
        result = subprocess.run([sys.executable, "-m", "ncbot", "robot", "serve", *args],
                                capture_output=True, text=True, timeout=60)
        assert result.returncode == 2, result.stderr
        assert result.stderr.strip().startswith("ncbot: error:") and len(result.stderr.strip().splitlines()) == 1


def test_serve_prints_its_url_once_it_listens(tmp_path):
    """The URL line comes when the socket accepts connections (after the scene's warm-up), so it can be opened at
    once; a checkpoint is the positional CHECKPOINT, whose game is served."""
    import os
    import select

    import httpx

    from tests.serve.helpers import free_port

    port = free_port()
    env = {**os.environ, "VK_ICD_FILENAMES": os.environ.get("VK_ICD_FILENAMES", "/usr/share/vulkan/icd.d/lvp_icd.json")}
    process = subprocess.Popen([sys.executable, "-m", "ncbot", "robot", "serve", "--port", str(port),
                                "--out", str(tmp_path / "study")], stderr=subprocess.PIPE, text=True, env=env)
    try:
        ready, _, _ = select.select([process.stderr], [], [], 240)
        assert ready, "no URL line within 240 s"
        line = process.stderr.readline()
        assert line.startswith(f"ncbot robot serve: http://127.0.0.1:{port}/"), line
        assert httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=5).status_code == 200  # listening already
    finally:
        process.terminate()
        process.wait(timeout=60)
