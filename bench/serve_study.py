"""A scripted study against a running `ncbot robot serve`: simulated people play through the same websocket
protocol as the page, and the click-to-reply latency is timed on the client side.

Why: the human evaluation needs a rehearsal (does the kit log what the analysis needs?) and a load figure
(several people at once) without recruiting anyone. Each scripted person clicks a random free cell (seeded),
answers the robot with the first button that fits (a cooperative person: yes, hello, name, good game, ...),
and plays `games` games in one session.

    python bench/serve_study.py --url http://127.0.0.1:8000 --sessions 10 --games 3 --parallel 4
"""
from __future__ import annotations

import argparse
import asyncio
import json
import random
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this tree's packages, not an installed copy

from ncbot.pipelines.serve.answers import PREFERRED_ACTS
from ncbot.pipelines.serve.latency import latency_stats


async def play_session(url: str, games: int, seed: int, first: str = "robot", timeout: float = 600.0) -> dict[str, Any]:
    """One scripted person: create a session, play `games` games, return outcomes and click-to-reply latencies."""
    import httpx
    import websockets

    rng = random.Random(seed)
    async with httpx.AsyncClient(base_url=url, timeout=30) as client:
        created = (await client.post("/api/session", json={})).json()
    if "session" not in created:
        raise RuntimeError(f"the server did not open a session: {created.get('error', created)}")
    sid = created["session"]
    ws_url = url.replace("http", "ws", 1) + f"/ws/{sid}"
    latencies: list[float] = []
    outcomes: list[str] = []
    clicked: tuple[float, int] | None = None
    answered = -1  # the utterance last answered (a state is sent more than once per utterance)
    deadline = time.monotonic() + timeout
    async with websockets.connect(ws_url, max_size=None) as ws:
        await ws.send(json.dumps({"type": "start", "first": first, "participant": f"scripted-{seed}"}))
        while len(outcomes) < games:
            if time.monotonic() > deadline:
                raise TimeoutError(f"session {sid} did not finish {games} games in {timeout} s")
            raw = await asyncio.wait_for(ws.recv(), timeout=timeout)
            if isinstance(raw, bytes):
                continue
            message = json.loads(raw)
            if message["type"] == "error":
                raise RuntimeError(f"session {sid}: the server refused a scripted request: {message['error']}")
            if message["type"] != "state":
                continue
            if message["status"].startswith("The robot failed"):
                raise RuntimeError(f"session {sid}: {message['status']}")
            if message["screen"] == "closed":
                raise RuntimeError(f"session {sid} was closed by the server before {games} games were played")
            if clicked is not None and message["says_seq"] > clicked[1]:
                latencies.append(time.perf_counter() - clicked[0])
                clicked = None
            if message["screen"] == "over" and len(outcomes) < message["games"]:
                outcomes.append(message["outcome"])
                if len(outcomes) < games:
                    await ws.send(json.dumps({"type": "again"}))
            elif message.get("answering") and message["says_seq"] != answered:
                answered = message["says_seq"]
                act = next(a for a in PREFERRED_ACTS if a in message["acts"])
                await ws.send(json.dumps({"type": "act", "act": act}))
            elif message["screen"] == "game" and message["your_turn"]:
                free = message.get("legal") or [i for i, mark in enumerate(message["board"]) if not mark]
                clicked = (time.perf_counter(), message["says_seq"])
                await ws.send(json.dumps({"type": "move", "cell": rng.choice(free)}))
        await ws.send(json.dumps({"type": "close"}))  # leave: the server finishes this session's log now
        await _until_closed(ws)
    return {"session": sid, "outcomes": outcomes, "latencies": latencies}


async def _until_closed(ws, timeout: float = 60.0) -> None:
    import websockets

    try:
        while True:
            raw = await asyncio.wait_for(ws.recv(), timeout=timeout)
            if not isinstance(raw, bytes) and json.loads(raw).get("screen") == "closed":
                return
    except websockets.ConnectionClosed:
        return


async def run_study(url: str, sessions: int, games: int, parallel: int, seed: int = 0,
                    timeout: float = 600.0) -> dict[str, Any]:
    """`sessions` scripted people, at most `parallel` at once; returns per-session results and latency stats."""
    gate = asyncio.Semaphore(parallel)

    async def one(index: int) -> dict[str, Any]:
        async with gate:
            return await play_session(url, games, seed + index, first="robot" if index % 2 == 0 else "human",
                                      timeout=timeout)

    started = time.perf_counter()
    results = await asyncio.gather(*(one(i) for i in range(sessions)))
    every = [x for r in results for x in r["latencies"]]
    return {"sessions": sessions, "games": games, "parallel": parallel, "wall_seconds": round(time.perf_counter() - started, 1),
            "click_to_reply_seconds": latency_stats(every),
            "outcomes": [o for r in results for o in r["outcomes"]], "per_session": results}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", default="http://127.0.0.1:8000")
    parser.add_argument("--sessions", type=int, default=10)
    parser.add_argument("--games", type=int, default=3)
    parser.add_argument("--parallel", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    report = asyncio.run(run_study(args.url.rstrip("/"), args.sessions, args.games, args.parallel, args.seed))
    report.pop("per_session")
    print(json.dumps(report))


if __name__ == "__main__":
    main()
