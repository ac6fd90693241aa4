"""One browser tab's game with the simulated robot: its own SAPIEN scene, game thread, MCAP log and event stream.

Why a thread per session: `ncbot.robot_sim.play.RobotGameRunner` is a blocking loop (policy, speech, motion, and
inside the env's step the human's turn). The person's click reaches it through the runner's `human_cell`
hook: the thread waits for the click, the simulated hand draws that mark into the scene, and the robot learns
the move only through its camera and the move recogniser, exactly as in `ncbot robot play`. The person's
answers (buttons, typed words) reach it through the runner's `user_reply` hook and go through the env as the
user's dialogue act (`ncbot.pipelines.serve.answers`). Sessions render in parallel (each has its own SAPIEN scene and
render world; `ServeConfig.parallel`), or, with `parallel=False`, one at a time under one process-wide lock.
"""
from __future__ import annotations

import asyncio
import queue
import secrets
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.pipelines.serve.state import (PERSON_SIDE, SEAT_CHOICES, ServeConfig, SessionClosed,  # noqa: F401
                                         SessionError, Snapshot)

#: Serial mode (`parallel=False`): serialises every SAPIEN / policy call of every session in this process.
SIM_LOCK = threading.Lock()
#: Parallel mode: the policy is one object shared by every session, so its calls still take turns (~ms each).
POLICY_LOCK = threading.Lock()

class Session:
    """A person's session: create, `start(first)`, `move(cell)` per turn, `again()`, `close()`."""

    def __init__(self, config: ServeConfig, policy: Callable, agent_name: str, participant: str = "") -> None:
        self.id = secrets.token_hex(8)
        self.config = config
        self.policy = policy
        self.agent_name = agent_name
        self.participant = participant[:64]
        self.created = self.last_seen = time.monotonic()
        self.snapshot = Snapshot()
        self.view = "overview"
        self.latest_jpeg: bytes | None = None
        self.latencies: list[float] = []  # accepted click -> the robot's next utterance (server side)
        self.outcomes: list[str] = []
        self.dialogue: list[dict[str, Any]] = []
        self._moves: queue.Queue[int | None] = queue.Queue()
        self._answers: queue.Queue[dict[str, Any] | None] = queue.Queue()
        self._taps: queue.Queue[int | None] = queue.Queue()
        self._answer_model = None  # pipelines.serve.answers.EnvAnswers of the game being played
        self._answer_type = 0  # the act type the person is answering
        self._sim = SIM_LOCK if not config.parallel else threading.Lock()
        self._commands: queue.Queue[str | None] = queue.Queue()
        self._awaiting = False
        self._legal: list[int] = []
        self._click_time: float | None = None
        self._last_frame_push = 0.0
        self._listeners: list[tuple[asyncio.AbstractEventLoop, asyncio.Queue]] = []
        self._lock = threading.Lock()
        self.closed = threading.Event()
        self.dir = Path(config.out) / f"session-{self.id}"
        self._thread: threading.Thread | None = None
        self._runner = None
        self._voice = None
        from ncbot.envs.games import make_game

        self.rules = make_game(config.game)  # the cells' names and, with gravity, which square a column click takes

    # ------------------------------------------------------------------ what clients call (event-loop thread)
    def subscribe(self, loop: asyncio.AbstractEventLoop) -> asyncio.Queue:
        """A queue of outgoing messages for one connected tab (bounded: slow tabs lose frames, never state)."""
        out: asyncio.Queue = asyncio.Queue(maxsize=64)
        with self._lock:
            self._listeners.append((loop, out))
        return out

    def unsubscribe(self, out: asyncio.Queue) -> None:
        with self._lock:
            self._listeners = [(loop, q) for loop, q in self._listeners if q is not out]

    def touch(self) -> None:
        self.last_seen = time.monotonic()

    def idle_for(self, now: float) -> float:
        """Seconds the session has waited for the person (0 while the robot acts or waits for the simulator)."""
        waiting = (self._awaiting or self.snapshot.answering or self.snapshot.tablet
                   or self.snapshot.screen in ("start", "over"))
        return now - self.last_seen if waiting else 0.0

    def start(self, first: Any, participant: Any = "") -> None:
        """Begin the first game (who opens: robot or human); `participant` is the person's optional code."""
        if first not in SEAT_CHOICES:
            raise SessionError(f"first must be one of {', '.join(SEAT_CHOICES)}; got {str(first)[:40]!r}")
        if not isinstance(participant, str):
            raise SessionError("participant must be a string")
        if self._thread is not None:
            raise SessionError("this session has already started; use 'again' after a game ends")
        self._first = first
        self.participant = participant[:64] or self.participant
        self._thread = threading.Thread(target=self._run, name=f"session-{self.id}", daemon=True)
        self._thread.start()
        self._commands.put("play")

    def again(self) -> None:
        """Play another game once the last one is over."""
        if self.snapshot.screen != "over":
            raise SessionError("a new game can start only when the current game is over")
        self.snapshot = replace(self.snapshot, screen="game", status="The robot is setting up a new game.", outcome=None)
        self._publish_state()
        self._commands.put("play")

    def _check_cell(self, cell: Any) -> None:
        cells = self.rules.n_cells
        if isinstance(cell, bool) or not isinstance(cell, int):
            raise SessionError(f"cell must be an integer in [0, {cells}); got {cell!r}")
        if not 0 <= cell < cells:
            raise SessionError(f"cell {cell} is out of range; cells are 0 to {cells - 1}")

    def _in_column(self, cell: int, legal: list[int]) -> int:
        """Gravity: a click anywhere in a column plays its lowest empty square (SessionError when it is full)."""
        if not getattr(self.rules, "gravity", False):
            return cell
        from ncbot.pipelines.serve.board import column_drop

        drop = column_drop(cell, legal, self.rules.cols)
        if drop is None:
            raise SessionError(f"column {self.rules.cell_name(cell)[0]} is full; click another column")
        return drop

    def tap(self, cell: Any) -> None:
        """The person touches a cell on the robot's chest tablet (only when the robot asked): the cell they drew in."""
        self._check_cell(cell)
        with self._lock:
            if not self.snapshot.tablet:
                raise SessionError("the robot is not asking for a touch on its tablet now")
            cell = self._in_column(cell, self.snapshot.legal)
            if cell not in self.snapshot.legal:
                raise SessionError(f"cell {self.rules.cell_name(cell)} is already taken on the robot's board; "
                                   "touch the cell you drew in")
            self.snapshot = replace(self.snapshot, tablet=False, legal=[], status="The robot takes your touch.")
        self._publish_state()
        self._taps.put(cell)

    def move(self, cell: Any) -> None:
        """The person's click: validated against the TRUE board; the game thread then draws it."""
        self._check_cell(cell)
        with self._lock:  # two tabs of one session may click at once: only one click is taken
            if not self._awaiting:
                raise SessionError("it is not your turn; wait for the robot")
            cell = self._in_column(cell, self._legal)
            if cell not in self._legal:
                taken = self.snapshot.board[cell] if self.snapshot.board else ""
                name = self.rules.cell_name(cell)  # what the person reads on the board
                raise SessionError(f"cell {name} is taken" if taken else
                                   f"cell {name} is not playable now (Ultimate: play in the board the last move points to)")
            self._awaiting = False
        self._click_time = time.perf_counter()
        self.snapshot = replace(self.snapshot, your_turn=False, legal=[], status="Drawing your mark; the robot is watching.")
        self._publish_state()
        self._moves.put(cell)

    def act(self, name: Any) -> None:
        """An answer button: the user act it stands for goes through the env (only buttons that fit now)."""
        from ncbot.pipelines.serve.answers import BUTTONS

        if not isinstance(name, str) or name not in BUTTONS:
            raise SessionError(f"unknown dialogue act {str(name)[:40]!r}; acts: {', '.join(BUTTONS)}")
        with self._lock:
            self._check_answering()
            if name not in self.snapshot.acts:
                raise SessionError(f"{name!r} does not answer what the robot said; answers now: {', '.join(self.snapshot.acts)}")
            utterance = self._answer_model.button_utterance(name)
            self._take_answer({"input": "button", "text": name, "utterance": utterance})

    def say(self, text: Any) -> None:
        """A typed answer: understood on the server (words the env does not know: silence, not an error)."""
        from ncbot.pipelines.serve.answers import MAX_TYPED

        if not isinstance(text, str):
            raise SessionError("text must be a string")
        text = " ".join(text.split())
        if len(text) > MAX_TYPED:
            raise SessionError(f"the answer is too long ({len(text)} characters; at most {MAX_TYPED})")
        with self._lock:
            self._check_answering()
            utterance = self._answer_model.understand(text, self._answer_type) if text else None
            self._take_answer({"input": "typed", "text": text, "utterance": utterance})

    def _check_answering(self) -> None:
        if not self.snapshot.answering or self._answer_model is None:
            raise SessionError("the robot is not waiting for an answer now")

    def _take_answer(self, answer: dict[str, Any]) -> None:
        """(holding self._lock) Close the answer window and hand the answer to the game thread."""
        self.snapshot = replace(self.snapshot, answering=False, acts=[], status="The robot is listening.")
        self._answers.put(answer)

    def set_view(self, view: Any) -> None:
        if view not in ("overview", "mouth"):
            raise SessionError(f"view must be overview or mouth; got {view!r}")
        self.view = view

    def close(self) -> None:
        """Stop the game (if the robot waits for the person) and finish the log; safe to call twice."""
        if self.closed.is_set():
            return
        self.closed.set()
        self._moves.put(None)
        self._answers.put(None)
        self._taps.put(None)
        self._commands.put(None)
        self.snapshot = replace(self.snapshot, screen="closed", status="This session was closed.", your_turn=False)
        self._publish_state()
        if self._thread is None:
            return
        self._thread.join(timeout=60)

    def state_message(self) -> dict[str, Any]:
        return {"type": "state", "session": self.id, "game": self.config.game, "view": self.view,
                **self.snapshot.__dict__}

    # ------------------------------------------------------------------ publishing (any thread)
    def _publish(self, message: Any, droppable: bool = False) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for loop, out in listeners:
            def put(out=out) -> None:
                if out.full():
                    if droppable:
                        return
                    try:  # make room for state: drop the oldest message (a frame, most likely)
                        out.get_nowait()
                    except asyncio.QueueEmpty:
                        pass
                out.put_nowait(message)
            try:
                loop.call_soon_threadsafe(put)
            except RuntimeError:  # the loop is gone (server shutting down)
                pass

    def _publish_state(self) -> None:
        self._publish(self.state_message())

    # ------------------------------------------------------------------ the game thread
    def _run(self) -> None:
        import torch

        from ncbot.logs import EpisodeLogger
        from ncbot.pipelines.serve.voice import BroadcastSpeaker, Voice
        from ncbot.robot_sim.human import HumanConfig
        from ncbot.robot_sim.play import RobotGameRunner, RobotPlayConfig

        torch.set_num_threads(1)
        config = RobotPlayConfig(game=self.config.game, games=1, seed=self.config.seed, first=self._first,
                                 camera_width=self.config.camera_width, camera_height=self.config.camera_height,
                                 human=HumanConfig(), agent_name=self.agent_name, conditions=self.config.conditions,
                                 weights=self.config.weights, **self.config.perception())
        from ncbot.pipelines.online.serving import session_learning  # --learn: this person's learning, else None

        learning = session_learning(self.config, self.participant or f"session-{self.id}",
                                    None if self._sim is SIM_LOCK else POLICY_LOCK)
        self.policy = learning.policy if learning is not None and learning.policy is not None else self.policy
        tags = {"session": self.id, "participant": self.participant}
        logger = EpisodeLogger(self.dir, run_info={"robot_serve": {**tags, "game": self.config.game,
                                                                   "agent": self.agent_name,
                                                                   "conditions": self.config.conditions}})
        if self.config.audio:
            self._voice = Voice(self.dir / "audio", f"/audio/{self.id}",
                                lambda url, seq: self._publish({"type": "audio", "url": url, "seq": seq}))
        index = 0
        try:
            with torch.no_grad(), self._sim:
                runner = RobotGameRunner(config, self._policy, out_dir=self.dir, logger=logger,
                                         human_cell=self._wait_for_click, on_frame=self._frame,
                                         episode_tags=tags, user_reply=self._wait_for_answer, network=self.policy,
                                         tablet=self._wait_for_tap)
                runner.speaker = BroadcastSpeaker(self.utterance, self.config.audio)
                self._runner = runner
                if learning is not None:
                    learning.attach(runner)
                while self._command() is not None and not self.closed.is_set():
                    self._play_one(runner, index, learning)
                    index += 1
        except SessionClosed:
            pass
        except Exception as error:  # a broken game must end this session, never the server
            traceback.print_exc()  # the server's log keeps the cause; the page gets one line
            self.snapshot = replace(self.snapshot, screen="over", status=f"The robot failed: {error}. Outcome: unfinished",
                                    outcome="unfinished", your_turn=False, answering=False, acts=[])
            self._publish_state()
        finally:
            with self._sim:
                logger.close()
            if self._voice is not None:
                self._voice.close()

    def _policy(self, td):
        if self._sim is SIM_LOCK:
            return self.policy(td)
        with POLICY_LOCK:
            return self.policy(td)

    def _command(self) -> str | None:
        """The next command (`play`), the simulator given up while the person is on the end screen."""
        self._sim.release()
        try:
            return self._commands.get()
        finally:
            self._sim.acquire()

    def _play_one(self, runner, index: int, learning=None) -> None:
        robot_mark = "x" if self._first == "robot" else "o"
        person_mark = "o" if robot_mark == "x" else "x"
        self.snapshot = replace(self.snapshot, screen="game", board=[""] * self.rules.n_cells, outcome=None,
                                status="The robot's turn.", your_turn=False, mark=person_mark, heard="")
        self._publish_state()
        record = runner.play_game(index)
        self._push_frame(runner, force=True)
        runner.logger.flush()  # the finished game is on disk now, not when the session closes
        if learning is not None:
            learning.after_game(runner, record)
        outcome = PERSON_SIDE[record.outcome]
        self.outcomes.append(outcome)
        self._refresh_board(runner)
        self.touch()
        self.snapshot = replace(self.snapshot, screen="over", outcome=outcome, your_turn=False, answering=False, acts=[],
                                games=self.snapshot.games + 1, status=f"Game over. Outcome: {outcome}")
        self._publish_state()

    def _wait(self, source: queue.Queue) -> Any:
        """Give up the simulator and wait for the person's next item on `source` (None: the session closed). On
        the answers' queue, after `answer_seconds` without an answer the person said nothing (a silence answer)."""
        self._sim.release()
        waited = 0.0
        try:
            while True:
                try:
                    item = source.get(timeout=1.0)
                except queue.Empty:
                    if self.closed.is_set():
                        raise SessionClosed(self.id) from None
                    waited += 1.0
                    if source is self._answers and waited >= self.config.answer_seconds:
                        with self._lock:
                            if self.snapshot.answering:  # nobody answered meanwhile: silence
                                self._take_answer({"input": "timeout", "text": "", "utterance": None})
                    continue
                if item is None:
                    raise SessionClosed(self.id)
                return item
        finally:
            self._sim.acquire()

    def _wait_for_click(self, true_state, human_mark: int) -> int:
        """The runner's `human_cell` hook: publish 'your turn', give up the simulator, wait for a valid click."""
        runner = self._runner
        self._legal = list(runner.rules.legal(true_state))
        self._refresh_board(runner, true_state)
        self._push_frame(runner, force=True)
        self._awaiting = True
        self.touch()  # idle time counts from the robot's last action, not the person's last click
        where = "a column" if getattr(self.rules, "gravity", False) else "a cell"
        self.snapshot = replace(self.snapshot, your_turn=True, status=f"Your turn: click {where}.", legal=list(self._legal))
        self._publish_state()
        try:
            return self._wait(self._moves)
        finally:
            self._awaiting = False

    def _wait_for_tap(self, legal: np.ndarray) -> int:
        """The runner's `tablet` hook: after a missed move, any cell free on the robot's board may be touched."""
        self._refresh_board(self._runner)
        self.touch()
        with self._lock:
            self.snapshot = replace(self.snapshot, tablet=True, your_turn=False, legal=np.flatnonzero(legal).tolist(),
                                    status="Touch the robot's tablet: click the cell you drew in.")
        self._publish_state()
        return self._wait(self._taps)  # `tap` closed the request

    def _wait_for_answer(self, env, action: int) -> None:
        """The runner's `user_reply` hook: the person answers the robot's utterance; the env hears it as the user."""
        from ncbot.pipelines.serve.answers import EnvAnswers, act_type_of, answer_turn, needs_answer

        if self._answer_model is None or self._answer_model.replies.model is not env.model:
            self._answer_model = EnvAnswers(env)  # a new game: a new env
        model, act_type = self._answer_model, act_type_of(env, action)
        if not needs_answer(act_type):
            model.set_without_asking(act_type)
            return
        self._answer_type = act_type
        self.touch()
        with self._lock:
            self.snapshot = replace(self.snapshot, answering=True, acts=model.buttons_for(act_type), your_turn=False,
                                    status="Answer the robot: press a button or type, or say nothing.")
        self._publish_state()
        answer = self._wait(self._answers)
        model.set(act_type, answer["utterance"])
        record = getattr(self._runner, "_record", None)  # the game being played: its index is the log's episode id
        turn, heard = answer_turn(model, answer, record)
        turn.update(session=self.id, t=round(time.monotonic() - self.created, 3))
        self.snapshot = replace(self.snapshot, heard=heard, status="The robot's turn.")
        self._publish_state()
        self.dialogue.append(turn)
        self._runner.logger.log_dialogue(turn)

    def _refresh_board(self, runner, state=None) -> None:
        state = state if state is not None else runner.true_state
        marks = {0: "", 1: "x", 2: "o"}
        self.snapshot = replace(self.snapshot, board=[marks[int(v)] for v in state.board])

    def _frame(self, frame: np.ndarray, t: float) -> None:
        """The runner's `on_frame` hook (game thread, simulator held): push a JPEG to the tab now and then."""
        if self._runner is not None and time.perf_counter() - self._last_frame_push >= self.config.frame_interval:
            self._push_frame(self._runner, frame=frame)

    def _push_frame(self, runner, frame: np.ndarray | None = None, force: bool = False) -> None:
        import cv2

        if not self._listeners and not force:
            return
        if self.view == "overview":
            image = runner.scene.render_overview(self.config.overview_width, self.config.overview_height)
        else:
            image = frame if frame is not None else runner.last_frame
        if image is None:
            return
        ok, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(image[:, :, ::-1]), [cv2.IMWRITE_JPEG_QUALITY, 75])
        if ok:
            self.latest_jpeg = jpeg.tobytes()
            self._last_frame_push = time.perf_counter()
            self._publish({"type": "frame", "jpeg": self.latest_jpeg}, droppable=True)

    def utterance(self, text: str) -> None:
        """The robot said `text`: show it, time the reply to the last click, queue its audio."""
        if self._click_time is not None:
            self.latencies.append(time.perf_counter() - self._click_time)
            self._click_time = None
        self._refresh_board(self._runner)
        self.snapshot = replace(self.snapshot, robot_says=text, says_seq=self.snapshot.says_seq + 1,
                                status="The robot's turn.", your_turn=False)
        self._publish_state()
        self.dialogue.append({"speaker": "robot", "text": text, "t": round(time.monotonic() - self.created, 3)})
        if self._voice is not None:
            self._voice.say(text, self.snapshot.says_seq)
