"""The web app of `ncbot robot serve` (FastAPI + uvicorn): the page, one websocket per tab, sessions, idle reaper.

Protocol (JSON text frames from the page, each may carry `"session"`; a mismatch is an error):
`{"type": "start", "first": "robot"|"human"}`, `{"type": "move", "cell": N}`, `{"type": "tap", "cell": N}` (a touch on
the robot's chest tablet, when it asks after missing a move), `{"type": "act", "act": NAME}` (an
answer button), `{"type": "say", "text": "..."}` (a typed answer), `{"type": "view", "view": "overview"|"mouth"}`, `{"type": "again"}`, `{"type": "close"}`. The server sends
`{"type": "state", ...}` (the whole page state), `{"type": "audio", "url": ...}`, `{"type": "error", "error": ...}` and camera frames
as binary JPEG messages. Any bad request gets an error and changes nothing; the server never dies from a client.
"""
from __future__ import annotations

import asyncio
import contextlib
import html
import json
import re
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fastapi import FastAPI, HTTPException, Request, WebSocket, WebSocketDisconnect
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response

from ncbot.pipelines.serve.board import board_layout, layout_script
from ncbot.pipelines.serve.session import SIM_LOCK, ServeConfig, Session, SessionError

PAGE = Path(__file__).with_name("page.html")
MAX_MESSAGE_BYTES = 4096
AUDIO_NAME = re.compile(r"^utterance-\d{4}\.wav$")
SESSION_ID = re.compile(r"^[0-9a-f]{16}$")


def load_policy(config: ServeConfig) -> tuple[Callable, str]:
    """The robot's policy: a trained checkpoint, or the paper's look-ahead filter alone."""
    if config.checkpoint is None:
        from ncbot.modules.policies.masks import LookaheadOnlyPolicy

        return LookaheadOnlyPolicy(seed=config.seed), "lookahead"
    from ncbot.pipelines.agents import load_agent

    agent_config, policy = load_agent(config.checkpoint)
    if agent_config.env.game != config.game:
        raise ValueError(f"checkpoint {config.checkpoint} was trained on {agent_config.env.game!r}, not "
                         f"{config.game!r}; pass --game {agent_config.env.game}")
    return policy, f"{agent_config.agent.name}:{config.checkpoint}"


def warm_up(config: ServeConfig) -> None:
    """Build and render one scene so the first person does not wait for shader start-up (seconds on lavapipe)."""
    from ncbot.robot_sim.conditions import load_conditions
    from ncbot.robot_sim.scene import PepperScene, SceneConfig

    with SIM_LOCK:
        scene = PepperScene(SceneConfig(game=config.game, camera_width=config.camera_width,
                                        camera_height=config.camera_height,
                                        conditions=load_conditions(config.conditions), conditions_seed=config.seed))
        scene.render()
        scene.render_overview(config.overview_width, config.overview_height)


class Sessions:
    """The live sessions of this server, with the idle reaper's rule."""

    def __init__(self, config: ServeConfig, policy: Callable, agent_name: str) -> None:
        self.config, self.policy, self.agent_name = config, policy, agent_name
        self.live: dict[str, Session] = {}
        self.closed: dict[str, Session] = {}  # kept for /api/stats

    def create(self, participant: str = "") -> Session:
        if len(self.live) >= self.config.max_sessions:
            raise SessionError(f"the server is full ({self.config.max_sessions} sessions); try again later")
        session = Session(self.config, self.policy, self.agent_name, participant)
        self.live[session.id] = session
        return session

    def get(self, session_id: Any) -> Session:
        if not isinstance(session_id, str) or session_id not in self.live:
            raise SessionError(f"unknown or closed session {str(session_id)[:40]!r}; start a new one")
        return self.live[session_id]

    def close(self, session_id: str) -> None:
        session = self.live.pop(session_id, None)
        if session is not None:
            self.closed[session_id] = session
            session.close()

    def idle(self) -> list[str]:
        now = time.monotonic()
        return [sid for sid, s in self.live.items() if s.idle_for(now) > self.config.idle_seconds]


def create_app(config: ServeConfig):
    """The FastAPI app; sessions live in `app.state.sessions`."""
    policy, agent_name = load_policy(config)
    sessions = Sessions(config, policy, agent_name)
    ready = threading.Event()

    async def reaper() -> None:
        while True:
            await asyncio.sleep(max(0.2, min(5.0, config.idle_seconds / 4)))
            for sid in sessions.idle():
                await asyncio.to_thread(sessions.close, sid)

    @contextlib.asynccontextmanager
    async def lifespan(app):
        await asyncio.to_thread(warm_up, config)
        ready.set()
        task = asyncio.create_task(reaper())
        yield
        task.cancel()
        for sid in list(sessions.live):
            await asyncio.to_thread(sessions.close, sid)

    app = FastAPI(title="ncbot robot serve", lifespan=lifespan)
    app.state.sessions = sessions

    @app.exception_handler(SessionError)
    async def session_error(request: Request, error: SessionError):
        return JSONResponse({"type": "error", "error": str(error)}, status_code=400)

    @app.get("/", response_class=HTMLResponse)
    async def page() -> str:
        layout = board_layout(config.game)
        return (PAGE.read_text().replace("__BOARD__", layout_script(config.game))
                .replace("__GAME__", html.escape(layout["name"])).replace("__TITLE__", html.escape(layout["title"]))
                .replace("__RULES__", html.escape(layout["rules"])))

    @app.get("/healthz")
    async def health() -> dict[str, Any]:
        return {"ok": True, "ready": ready.is_set(), "sessions": len(sessions.live), "game": config.game,
                "agent": agent_name, "conditions": config.conditions, "parallel": config.parallel}

    @app.post("/api/session")
    async def new_session(request: Request) -> dict[str, Any]:
        body = await _json_body(request)
        participant = body.get("participant", "") if isinstance(body, dict) else ""
        if not isinstance(participant, str):
            raise SessionError("participant must be a string")
        session = sessions.create(participant)
        return session.state_message()

    @app.get("/api/session/{session_id}")
    async def session_state(session_id: str) -> dict[str, Any]:
        return sessions.get(session_id).state_message()

    @app.get("/api/stats")
    async def stats() -> dict[str, Any]:
        return _stats(sessions)

    @app.get("/audio/{session_id}/{name}")
    async def audio(session_id: str, name: str):
        return FileResponse(_utterance(sessions, session_id, name), media_type="audio/wav")

    @app.get("/frame/{session_id}.jpg")
    async def frame(session_id: str):
        session = sessions.get(session_id)
        if session.latest_jpeg is None:
            raise HTTPException(404, "no frame yet")
        return Response(session.latest_jpeg, media_type="image/jpeg")

    @app.websocket("/ws/{session_id}")
    async def socket(websocket: WebSocket, session_id: str) -> None:
        await websocket.accept()
        session = sessions.live.get(session_id) if SESSION_ID.match(session_id) else None
        if session is None:
            await websocket.send_json({"type": "error", "error": f"unknown or closed session {session_id[:40]!r}; start a new one",
                                       "fatal": True})
            await websocket.close()
            return
        outbox = session.subscribe(asyncio.get_running_loop())
        session.touch()
        await websocket.send_json(session.state_message())
        if session.latest_jpeg is not None:
            await websocket.send_bytes(session.latest_jpeg)
        sender = asyncio.create_task(_send_loop(websocket, outbox))
        try:
            while True:
                raw = await websocket.receive()
                if raw.get("type") == "websocket.disconnect":
                    break
                reply = await asyncio.to_thread(_handle, sessions, session, raw)
                if reply is not None:
                    await outbox.put(reply)
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            sender.cancel()
            session.unsubscribe(outbox)

    return app


def _stats(sessions: Sessions) -> dict[str, Any]:
    """Every session's click-to-reply latencies and outcomes, live or closed."""
    every = {**sessions.closed, **sessions.live}
    return {"sessions": {sid: {"latencies": [round(x, 4) for x in s.latencies], "outcomes": s.outcomes,
                               "live": sid in sessions.live} for sid, s in every.items()}}


def _utterance(sessions: Sessions, session_id: str, name: str) -> Path:
    """The path of a session's spoken utterance `name` (404 for an unknown session or name)."""
    session = sessions.live.get(session_id) or sessions.closed.get(session_id)
    if session is None or not AUDIO_NAME.match(name) or not (session.dir / "audio" / name).is_file():
        raise HTTPException(404, "no such utterance")
    return session.dir / "audio" / name


async def _send_loop(websocket, outbox: asyncio.Queue) -> None:
    with contextlib.suppress(Exception):
        while True:
            message = await outbox.get()
            if message.get("type") == "frame":
                await websocket.send_bytes(message["jpeg"])
            else:
                await websocket.send_json(message)


async def _json_body(request) -> Any:
    raw = await request.body()
    if not raw:
        return {}
    if len(raw) > MAX_MESSAGE_BYTES:
        raise SessionError(f"request too large ({len(raw)} bytes; at most {MAX_MESSAGE_BYTES})")
    try:
        return json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        raise SessionError("the request body is not JSON") from None


def _handle(sessions: Sessions, session: Session, raw: dict[str, Any]) -> dict[str, Any] | None:
    """One websocket message: do it, or return an error (nothing changed). Runs off the event loop."""
    request = "?"
    try:
        text = raw.get("text")
        if text is None:
            raise SessionError("send JSON text messages, not binary")
        if len(text) > MAX_MESSAGE_BYTES:
            raise SessionError(f"message too large ({len(text)} characters; at most {MAX_MESSAGE_BYTES})")
        try:
            message = json.loads(text)
        except ValueError:
            raise SessionError("the message is not JSON") from None
        if not isinstance(message, dict):
            raise SessionError("the message must be a JSON object with a 'type'")
        request = str(message.get("type"))[:40]
        if "session" in message and message["session"] != session.id:
            raise SessionError("this message names another session than this connection's; nothing was done")
        if session.closed.is_set():
            raise SessionError("this session is closed; start a new one")
        session.touch()
        kind = message.get("type")
        if kind == "start":
            session.start(message.get("first", "robot"), message.get("participant", ""))
        elif kind == "move":
            session.move(message.get("cell"))
        elif kind == "tap":
            session.tap(message.get("cell"))
        elif kind == "act":
            session.act(message.get("act"))
        elif kind == "say":
            session.say(message.get("text"))
        elif kind == "view":
            session.set_view(message.get("view"))
            return session.state_message()
        elif kind == "again":
            session.again()
        elif kind == "close":  # the person leaves: end the game and finish the log now
            sessions.close(session.id)
            return None
        elif kind == "ping":
            return {"type": "pong"}
        else:
            raise SessionError(f"unknown message type {str(kind)[:40]!r}; types: start, move, tap, act, say, view, again, close, ping")
        return None
    except SessionError as error:
        return {"type": "error", "error": str(error), "request": request}
    except Exception as error:  # never let one client's message take the server down
        return {"type": "error", "error": f"internal error: {type(error).__name__}", "request": request}


def serve(config: ServeConfig, host: str = "127.0.0.1", port: int = 8000, on_listening=None) -> None:
    """Run the app with uvicorn until interrupted; `on_listening()` is called once the socket accepts connections
    (after the simulator's warm-up, which takes seconds), so a URL printed there can be opened at once."""
    import uvicorn

    server = uvicorn.Server(uvicorn.Config(create_app(config), host=host, port=port, ws="websockets-sansio",
                                           log_level="warning"))
    startup = server.startup

    async def startup_then_announce(sockets=None) -> None:
        await startup(sockets=sockets)
        if server.started and on_listening is not None:
            on_listening()

    server.startup = startup_then_announce
    server.run()
