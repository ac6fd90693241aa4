"""The closed loop: Pepper plays whole games in the simulator against the simulated human.

The robot perceives only through rendered mouth-camera frames (the vision package's move recogniser, Algorithm 1 of
the paper) and the dialogue: with `speech: real` it speaks its templates and hears the simulated person's spoken
replies through the real recogniser (`ncbot.robot_sim.speech`), with `speech: text` the env's simulated ASR gives it
the words said at random confidences. It decides with a policy over the SAME dialogue env state the agent was trained
on, and acts through the simulator. The glue is an "external" opponent handed to the env: when the env needs the
human's move, the simulated person draws on the sheet (choosing on the TRUE board), the recogniser watches the frames,
and the cell it reports is what the env, and therefore the robot's state, believes. Wins, draws and losses are judged
on the true board; every move the recogniser got wrong is counted.

One game = one episode: everything goes through `ncbot.logs.EpisodeLogger` (camera frames as
`foxglove.CompressedImage`, joint states, transforms, dialogue, with real speech every utterance's audio as
`foxglove.RawAudio` on `/audio/robot` and `/audio/user` and what was heard on `/dialogue`, the believed board per
step, and the true board per step in the episode summary); a PNG snapshot of the camera view closes each game."""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.robot_sim.conditions import sample_handwriting
from ncbot.robot_sim.game_config import RobotPlayConfig
from ncbot.robot_sim.human import SimulatedHuman
from ncbot.robot_sim.localise import localise_sheet
from ncbot.robot_sim.motion import RobotMotion
from ncbot.robot_sim.perceived import PerceivedHumanOpponent, rgb_to_bgr as _rgb_to_bgr, write_png_atomic as _write_png_atomic
from ncbot.robot_sim.report import GameRecord, annotated_snapshot, count_repeat, games_report, write_report
from ncbot.robot_sim.reach import check_reach
from ncbot.robot_sim.scene import PepperScene, SceneConfig, check_game, placed_by_hand
from ncbot.robot_sim.settlement import moves_from_boards
from ncbot.robot_sim.sheet import MARK_OF_PLAYER, ROBOT_INK, MarkSpec
from ncbot.robot_sim.speech import GameSpeech, Speaker, SpeechLog, aim, speech_summary
from ncbot.robot_sim.where import ASK_TABLET, ASK_WHERE, LOOK_AGAIN, ask_where, count_settled

__all__ = ["RobotPlayConfig", "RobotGameRunner", "play_robot_games"]  # the config is here for `ncbot robot play`
ROBOT_PEN_MM = 2.0  # the robot writes with a felt-tip marker


class RobotGameRunner:
    """Plays `config.games` games with `policy` (a callable TensorDict -> TensorDict writing `action`)."""

    def __init__(self, config: RobotPlayConfig, policy: Callable, out_dir: str | Path | None = None,
                 logger: Any = None, human_cell: Callable[[Any, int], int] | None = None,
                 on_frame: Callable[[np.ndarray, float], None] | None = None,
                 episode_tags: dict[str, Any] | None = None,
                 user_reply: Callable[[Any, int], None] | None = None, network: Any = None,
                 tablet: Callable[[np.ndarray], int] | None = None) -> None:
        """`human_cell(true_state, human_mark)` lets a real person choose the cell the simulated hand draws
        (`ncbot robot serve`: a click in the browser) instead of the simulated opponent model; the robot still
        learns the move only through its camera. `on_frame` sees every rendered mouth-camera frame;
        `episode_tags` go into every logged `/episode` summary (e.g. the browser session id).
        `user_reply(env, action)` runs after each robot act and before the env steps, so a real person's answer
        (serve: a button or typed words) replaces the env's simulated user's reply; its words are then heard
        at confidence 1 (as `ncbot play` does for typed text). `network`: the module behind `policy` when `policy`
        wraps it (serve's locked call); a recurrent one (agent.memory) gets its hidden state carried through each
        game's dialogue by the env (`modules.networks.recurrent.memory_env`), from zero at every game.
        `tablet(legal)`: the cell a real person touches on the robot's chest tablet (serve: a tap on the page) when
        the robot asks after a move its camera missed; without it the simulated person touches the cell drawn."""
        config.validate()
        self.tablet = tablet
        self.human_cell = human_cell
        self.user_reply = user_reply
        self.on_frame = on_frame
        self.episode_tags = dict(episode_tags or {})
        self.config = config
        self.policy = policy
        self.network = policy if network is None else network
        self.out_dir = Path(out_dir) if out_dir is not None else None
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        self.logger = logger
        self._ranges = config.condition_ranges()
        self.speech = GameSpeech.for_play(config) if config.speech == "real" else None
        self.speaker = Speaker.for_robot(self.out_dir / "speech" if (config.audio and self.out_dir) else None, self.speech)
        self.records: list[GameRecord] = []
        from ncbot.envs.games import make_game
        from ncbot.vision.recogniser import MoveRecogniser

        self.rules = make_game(config.game, config.free_move)
        self.grid = check_game(config.game)
        from ncbot.vision.classifier import load_classifier

        self.recogniser = MoveRecogniser(grid=self.grid, tau=config.recogniser_tau,
                                         classifier=load_classifier(config.weights) if config.weights else None)
        self.last_frame: np.ndarray | None = None
        self.on_view: Callable[[np.ndarray, int], None] | None = None  # (BGR frame, moves made) of every look after a move

    # ------------------------------------------------------------------ logging of sensor streams
    def _log_frame(self, frame: np.ndarray, t: float) -> None:
        self.last_frame = frame
        self._record.frames += 1
        if self.on_frame is not None:
            self.on_frame(frame, t)
        if self.logger is None:
            return
        import cv2

        ok, jpeg = cv2.imencode(".jpg", _rgb_to_bgr(frame), [cv2.IMWRITE_JPEG_QUALITY, self.config.jpeg_quality])
        if ok:
            self.logger.log_camera(jpeg.tobytes(), t=t)
        scene = self.scene
        self.logger.log_joint_states(scene.joint_names, scene.qpos.tolist(), t=t)
        x, y, yaw = scene.base_pose()
        self.logger.log_transform("world", "base_footprint", (x, y, 0.0), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)), t=t)
        cam = scene.links["CameraBottom_frame"].entity_pose
        w, qx, qy, qz = (float(v) for v in cam.q)
        self.logger.log_transform("world", "CameraBottom", tuple(float(v) for v in cam.p), (qx, qy, qz, w), t=t)

    # ------------------------------------------------------------------ the human's turn, as the robot sees it
    def _perceive_human_move(self, legal: np.ndarray) -> int:
        """Run the simulated human's move in the scene and return the cell the recogniser reports."""
        started = time.perf_counter()
        record = self._record
        if self.rules.is_over(self.true_state):
            # Only after a perception error: the env believes the game goes on, the real one is over.
            self._diverged = True
            return int(np.flatnonzero(legal)[0])
        human_mark = 1 if self._robot_mark == 2 else 2
        chooser = self.human_cell or self.human.choose
        true_cell = chooser(self.true_state, human_mark)
        kind = MARK_OF_PLAYER["x" if human_mark == 1 else "o"]
        known = [0 if ok else 1 for ok in legal]  # only legal cells can hold the new move
        # the robot's last look from its home posture (at its own mark, or the game's first frame): no hand on the sheet
        self.recogniser.reset(reference=None if self._home_frame is None else _rgb_to_bgr(self._home_frame))
        found: list = []
        streak: list = []

        def watch(frame: np.ndarray, t: float) -> None:
            self._log_frame(frame, t)
            if found:
                return
            result = self.recogniser.update(_rgb_to_bgr(frame), known)
            if result.status != "move":
                streak.clear()
                return
            if streak and (streak[-1].move, streak[-1].label) != (result.move, result.label):
                streak.clear()
            streak.append(result)
            if len(streak) >= self.config.confirm_frames:
                found.append(result)

        self.human.draw(true_cell, kind, watch)
        self._watch_still(watch, found)
        self.true_state = self.rules.play(self.true_state, true_cell)
        self._true_boards.append(self._true_digits())
        record.human_moves += 1
        if not found:
            record.unseen_moves += 1
            self._keep_evidence(f"unseen-{record.human_moves:02d}-true{true_cell}")
            if self.speech is None and self.tablet is not None:  # a person at the tablet (serve): their touch
                self._say(ASK_TABLET)
                cell = int(self.tablet(legal))
                record.tablet_fallbacks += 1
            elif self.speech is None:  # text: the robot asks and the person's answer comes through the dialogue
                self._say(ASK_WHERE)
                cell = true_cell
            else:
                cell = self._ask_where(true_cell, legal, watch, found)
        if found:
            cell = int(found[0].move)
            label = found[0].label
            if cell != true_cell or label != ("x" if human_mark == 1 else "o"):
                record.misrecognised_moves += 1
                self._keep_evidence(f"misread-{record.human_moves:02d}-true{true_cell}-saw{cell}{label}")
        if not legal[cell]:  # cannot happen (known marks every illegal cell), kept as a guard for the env
            cell = int(np.flatnonzero(legal)[0])
        record.human_turn_seconds.append(time.perf_counter() - started)
        self._note_view(self.last_frame)
        return cell

    def _watch_still(self, watch: Callable[[np.ndarray, float], None], found: list) -> None:
        """Watch the sheet (the scene going on, nobody drawing) until the move is found or the frames run out."""
        for _ in range(self.config.max_perception_frames):
            if found:
                break
            self.scene.step(self.config.human.frame_period)
            watch(self.scene.render(), self.scene.time)

    def _ask_where(self, true_cell: int, legal: np.ndarray, watch: Callable[[np.ndarray, float], None],
                   found: list) -> int | None:
        """Real speech, after an unseen move: the cell the person's spoken answers settle (robot_sim.where: by
        confidence, a touch on the tablet settles what they do not); when every cell is confirmed and the answers
        settle nothing, the robot says so and looks again (None: that look found a move, now in `found`), and
        failing that takes the cell drawn, as text mode does."""
        record = self._record
        touch = self.tablet or (lambda legal: true_cell)  # the simulated person touches the cell they drew
        settled = ask_where(true_cell, legal, self._answer_ears, self._say,
                            lambda answer, question: self._speech_log.answer(answer, question, self.scene.time),
                            self.speech.thresholds, touch)
        if count_settled(record, settled, true_cell):
            return settled.cell
        record.answer_fallbacks += 1
        self._say(LOOK_AGAIN)
        self._watch_still(watch, found)
        return None if found else true_cell

    def _keep_evidence(self, what: str) -> None:
        """With --out, keep the last camera frame of a move the robot got wrong or missed (input for vision)."""
        if self.out_dir is not None and self.last_frame is not None:
            path = self.out_dir / f"game-{self._record.index:03d}-{what}.png"
            _write_png_atomic(path, _rgb_to_bgr(self.last_frame))
            self._record.evidence.append(str(path))

    def _true_digits(self) -> str:
        """True board in the env's convention (1 robot, 2 human) as a digit string."""
        return "".join("0" if v == 0 else ("1" if v == self._robot_mark else "2") for v in self.true_state.board)

    # ------------------------------------------------------------------ the robot's turn
    def _act(self, action: int, env) -> None:
        """Say the act's template and do its command: a gesture, or the game move in the scene."""
        self._say(env.templates[action])
        command = env.robot_commands[action]
        if action < env.cells:
            record = self._record
            record.robot_moves += 1
            legal = self.rules.legal(self.true_state)
            kind = MARK_OF_PLAYER["x" if self._robot_mark == 1 else "o"]
            if action in legal:
                self.true_state = self.rules.play(self.true_state, action)
            else:
                self._diverged = True  # the robot believed a cell empty that is not: belief and truth diverged
            mark = MarkSpec(action, kind, int(self._mark_rng.integers(2**31)), ROBOT_INK, 0.6,
                            ROBOT_PEN_MM / (1000.0 * self.scene.sheet_side))
            # Where is the sheet now? From the latest frame (people nudge it), else the last estimate.
            self.motion.settle(0.1)
            frame = self.scene.render()  # a fresh look from the home posture (not a frame from mid-gesture)
            self._log_frame(frame, self.scene.time)
            estimate = localise_sheet(self.scene, frame)
            self._sheet_estimate = estimate or self._sheet_estimate
            believed = self._sheet_estimate.canvas_to_world(*self.scene.canvas.cell_pixel(action))
            record.cell_localisation_error = max(record.cell_localisation_error,
                                                 float(np.linalg.norm(believed - self.scene.cell_world(action))))
            if not self.rules.subgrids or self.config.ultimate_robot_draws:  # Ultimate: the robot points (paper)
                self.motion.draw_mark(mark, self._sheet_estimate.canvas_to_world)
            else:
                self.motion.point_at(believed)
                self.human.draw_for_robot(action, kind, self._log_frame, ROBOT_INK)
            self._true_boards.append(self._true_digits())
        elif command in ("hello", "please", "happy", "no", "think", "asr", "read"):
            self.motion.gesture(command)

    # ------------------------------------------------------------------ speech
    def _say(self, text: str) -> None:
        samples = self.speaker.say(text)
        if samples is not None:  # synthesised just now: its time is the speaker's last entry
            self._record.robot_tts_seconds += self.speaker.tts_seconds[-1]
            self._speech_log.utterance("robot", samples, text, self.scene.time)

    def _timed_render(self, render: Callable[[], np.ndarray]) -> Callable[[], np.ndarray]:
        """`scene.render`, adding its wall time to the game's render clock (where a turn's time goes)."""
        def timed() -> np.ndarray:
            started = time.perf_counter()
            frame = render()
            self._render_seconds += time.perf_counter() - started
            return frame
        return timed

    # ------------------------------------------------------------------ one game
    def play_game(self, index: int) -> GameRecord:
        from ncbot.envs import make_env
        from ncbot.modules.networks.recurrent import memory_env
        from torchrl.envs.utils import step_mdp

        cfg = self.config
        seed = cfg.seed * 1000 + index
        self.scene = PepperScene(SceneConfig(game=cfg.game, camera_width=cfg.camera_width,
                                             camera_height=cfg.camera_height,
                                             meshes_dir=cfg.meshes_dir, conditions=self._ranges,
                                             conditions_seed=seed))
        self._render_seconds = 0.0
        if not placed_by_hand(cfg.game):  # a plain grid's drawing positions were derived: every cell reachable?
            check_reach(self.scene, self.rules.cell_name)
        self.scene.render = self._timed_render(self.scene.render)  # every frame of the game goes through it
        self.motion = RobotMotion(self.scene, on_frame=self._log_frame, frame_period=cfg.robot_frame_period)
        handwriting = sample_handwriting(self._ranges, seed)
        self.human = SimulatedHuman(self.scene, self.rules, cfg.human, seed=seed, handwriting=handwriting)
        self._mark_rng = np.random.default_rng(seed + 17)
        self._home_frame: np.ndarray | None = None
        opponent = PerceivedHumanOpponent(self._perceive_human_move)
        first = cfg.first
        if first == "alternate":
            first = "robot" if index % 2 == 0 else "human"
        hearing = self.speech.game_hearing(seed, self.scene) if self.speech is not None else None
        heard = {"asr_confidence": (1.0, 1.0)} if self.user_reply is not None else {}
        if hearing is not None:
            heard["hearing"] = hearing
        self._answer_ears = self.speech.answer_ears(seed, hearing) if hearing is not None else None
        env = make_env(cfg.game, batch_size=(1,), seed=seed, first=first, free_move=cfg.free_move, opponent=opponent,
                       **heard)
        stepper = memory_env(env, self.network)  # the env itself for the MLP and the look-ahead policy
        td = stepper.reset()
        robot_first = bool(td["robot_first"].item())
        self._robot_mark = 1 if robot_first else 2
        self.true_state = self.rules.new()
        self._true_boards: list[str] = []
        self._diverged = False
        self._record = record = GameRecord(index=index, outcome="unfinished", robot_first=robot_first, actions=0,
                                           conditions={**self.scene.conditions.summary(), "handwriting": handwriting})
        if hearing is not None:
            record.conditions = {**record.conditions, "speech": speech_summary(hearing)}
        self._speech_log = SpeechLog(self.logger, record)
        self._log_frame(self.scene.render(), self.scene.time)
        self._home_frame = self.last_frame  # the sheet as the robot sees it from home, nobody's hand over it
        self._sheet_estimate = localise_sheet(self.scene, self.last_frame)
        if self._sheet_estimate is None:
            raise ValueError("the mouth camera cannot see the game sheet at the home posture; check the scene configuration")
        aim(hearing, self._sheet_estimate)  # the person plays across the sheet the camera found
        previous, understood = -1, True  # understood: every reply of the last step was understood as said
        while True:
            started, cpu_started = time.perf_counter(), time.process_time()
            render_started, tts_started = self._render_seconds, record.robot_tts_seconds
            td = self.policy(td)
            action = int(td["action"].reshape(-1)[0])
            count_repeat(record, action == previous and action >= env.cells, understood)  # the same question again
            previous = action
            self._act(action, env)
            if action < env.cells:
                self._check_own_mark(action)
                record.robot_move_seconds.append(time.perf_counter() - started)
                record.robot_move_cpu_seconds.append(time.process_time() - cpu_started)
                record.robot_move_render_seconds.append(self._render_seconds - render_started)
                record.robot_move_tts_seconds.append(record.robot_tts_seconds - tts_started)
            else:
                record.dialogue_act_seconds.append(time.perf_counter() - started)
            if self.user_reply is not None:
                self.user_reply(env, action)
            heard_before = len(hearing.log) if hearing is not None else 0
            td = stepper.step(td)
            if hearing is not None:
                understood = self._speech_log.heard(hearing, hearing.log[heard_before:], self.scene.time)
            self._speech_log.flush()
            record.actions += 1
            if self.logger is not None:
                done = bool(td["next", "done"].item())
                extra = self._episode_extra(record) if done else None
                self.logger.record_steps(td, phase="robot", agent=cfg.agent_name, seed=seed, env=env, extra=extra)
            if bool(td["next", "done"].item()) or self._diverged:
                break
            td = step_mdp(td)
        if self._diverged and self.logger is not None:  # cut off: the env never ended it, so its summary is written here
            self.logger.cut_off("robot", cfg.agent_name, seed, extra=self._episode_extra(record))
        record.outcome = self._true_outcome()
        record.ik_failures = self.motion.stats.ik_failures
        if self.out_dir is not None and self.last_frame is not None:
            path = self.out_dir / f"game-{index:03d}.png"
            _write_png_atomic(path, annotated_snapshot(_rgb_to_bgr(self.last_frame), record))
            record.snapshot = str(path)
            # A third-person view for people reading the run (the robot never sees it).
            _write_png_atomic(self.out_dir / f"game-{index:03d}-overview.png", _rgb_to_bgr(self.scene.render_overview()))
        return record

    def _check_own_mark(self, cell: int) -> None:
        """After drawing, look at the sheet once (the robot's own check that its mark landed in the cell)."""
        from ncbot.vision.grid import read_page

        frame = self._home_frame = self.scene.render()
        self._log_frame(frame, self.scene.time)
        self._note_view(frame)
        try:
            reading = read_page(_rgb_to_bgr(frame), self.grid, self.recogniser.classifier)
            missed = reading.cells[cell] == ""
        except ValueError:
            missed = True
        self._record.own_mark_misreads += int(missed)

    def _note_view(self, frame: np.ndarray) -> None:
        """A look at the sheet after a settled move: its time to the log (`ncbot learn` finds it), frame to `on_view`."""
        self._record.view_times.append((round(float(self.scene.time), 6), len(self._true_boards)))
        if self.on_view is not None:
            self.on_view(_rgb_to_bgr(frame), len(self._true_boards))

    def settle(self) -> list[tuple[int, int]]:
        """The game's (cell, player) moves as both sides agree on them at its end (`robot_sim.settlement`)."""
        if self._record.settled_moves is None:
            self._record.settled_moves = self.human.settle(moves_from_boards(self._true_boards), self.rules.n_cells)
        return self._record.settled_moves

    def _true_outcome(self) -> str:
        if self._diverged:
            return "unfinished"
        result = self.rules.outcome(self.true_state)
        if result is None:
            return "unfinished"
        if result == "draw":
            return "draw"
        return "win" if (result == "x") == (self._robot_mark == 1) else "loss"

    def _episode_extra(self, record: GameRecord) -> dict[str, Any]:
        return {"true_boards": list(self._true_boards), "true_outcome": self._true_outcome(),
                "misrecognised_moves": record.misrecognised_moves, "unseen_moves": record.unseen_moves,
                "robot_first": record.robot_first, "conditions": record.conditions,
                "human_turn_seconds": [round(s, 3) for s in record.human_turn_seconds],
                "robot_move_seconds": [round(s, 3) for s in record.robot_move_seconds],
                "robot_move_cpu_seconds": [round(s, 3) for s in record.robot_move_cpu_seconds],
                "views": [list(v) for v in record.view_times], "settled_moves": [list(m) for m in self.settle()],
                **({"utterances": record.utterances, "asr_words": record.asr_words,
                    "asr_word_errors": record.asr_word_errors} if self.speech is not None else {}), **self.episode_tags}

    # ------------------------------------------------------------------ many games
    def run(self, progress: Callable[..., Any] | None = None, after_game: Callable | None = None, first_game: int = 0) -> dict[str, Any]:
        """Play the games from `first_game` on; `progress` is a bar factory with tqdm's signature (pipelines.progress.
        progress_bar); `after_game(runner, record)` runs after each game (`ncbot.pipelines.online` learns from it)."""
        bar = progress(total=self.config.games, initial=first_game, desc="robot games", unit="game") if progress else None
        for index in range(first_game, self.config.games):
            self.records.append(self.play_game(index))
            if after_game is not None:
                after_game(self, self.records[-1])
            if bar is not None:
                bar.update(1)
                bar.set_postfix(outcome=self.records[-1].outcome,
                                misrec=sum(r.misrecognised_moves for r in self.records))
        if bar is not None:
            bar.close()
        return self.report()

    def report(self) -> dict[str, Any]:
        """The JSON report of `ncbot robot play` (`ncbot.robot_sim.report.games_report`)."""
        return games_report(self.records, self.config)


def play_robot_games(config: RobotPlayConfig, policy: Callable | None = None, out_dir: str | Path | None = None,
                     log_mcap: bool = True, progress: Callable[..., Any] | None = None, attach: Callable | None = None) -> dict[str, Any]:
    """Play the games, logging to `out_dir` (MCAP + PNG snapshots + report.json) when given; return the report.
    `attach(runner)` -> (after_game hook, first game): a run that learns from its games (ncbot.pipelines.online)."""
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy

    config.validate()
    if policy is None:
        policy = LookaheadOnlyPolicy(seed=config.seed)
    logger = None
    if out_dir is not None and log_mcap:
        from ncbot.logs import EpisodeLogger

        logger = EpisodeLogger(out_dir, run_info={"robot_play": asdict(config)})
    try:
        runner = RobotGameRunner(config, policy, out_dir=out_dir, logger=logger)
        after_game, first_game = attach(runner) if attach is not None else (None, 0)
        report = runner.run(progress=progress, after_game=after_game, first_game=first_game)
    finally:
        if logger is not None:
            logger.close()
    if out_dir is not None:
        write_report(report, out_dir)
    return report
