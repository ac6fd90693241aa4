"""`EpisodeLogger`: every training, evaluation and robot episode of a run into size-rolled MCAP files.

One logger per run directory writes `episodes-0000.mcap`, `episodes-0001.mcap`, ... Chunks are zstd
compressed and closed (written to the OS) at least every `flush_interval_s` seconds and on `flush()`, so a
process killed with SIGKILL leaves every closed chunk readable and loses only the chunk in progress.
Log times come from one clock per logger, anchored to wall time and strictly increasing, so the files
play back in the order things happened.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

import ncbot.logs.foxglove as foxglove
import ncbot.logs.packed as packed
import ncbot.logs.schemas as schemas
from ncbot.envs.games import built_in_of_cells
from ncbot.fileio import fsync_folder
from ncbot.logs.board_image import board_png, changed_cell
from ncbot.logs.names import NameTables
from ncbot.logs.reader import FILE_PATTERN, episode_file_name, next_episode_id
from ncbot.logs.steps import EpisodeAssembler, FinishedEpisode, expand_episode, step_arrays

DEFAULT_MAX_FILE_BYTES = 256 * 2**20
DEFAULT_STEP_DETAIL = {"train": "packed", "eval": "packed", "robot": "per_action", "play": "per_action"}
MESSAGE_RECORD_OVERHEAD = 31  # MCAP Message record header: opcode, length, channel, sequence, two times


class EpisodeLogger:
    """Writes ncbot episodes to MCAP. Use as a context manager (or call `close()`).

    Typical use from a training loop (the env's step output or a collector batch)::

        with EpisodeLogger(run_dir, run_info={"config": cfg_dict}) as log:
            for batch in collector:                      # (B, T) TensorDict with ("next", ...) keys
                log.record_steps(batch, phase="train", agent="proposed", seed=0,
                                 epsilon=eps, env_steps=frames, env=env)

    `record_steps` follows each batch index's episode across calls. Training and evaluation episodes are
    written when they end, as one packed `/episode/steps` message; robot games stream `/step`,
    `/dialogue` and `/board` messages per action as they happen; every episode ends with an `/episode`
    summary. The robot simulator uses the same call with `phase="robot"` and adds `log_camera`,
    `log_joint_states` and `log_transform`. Lower-level `log_step`/`log_dialogue`/`log_board`/`log_episode`
    take dicts that follow the JSON Schemas in `ncbot.logs.schemas` for producers that are not TorchRL envs.

    Args:
        run_dir: directory of the run; created if missing. Existing `episodes-NNNN.mcap` files are kept and
            numbering (files and episode ids) continues after them, so eval in a second process appends.
        run_info: JSON-serialisable facts about the run (config, git commit, ...), stored as MCAP metadata
            `ncbot.run` in every file.
        max_file_bytes: start a new file once the current one is this large (checked at episode ends, so a
            file overshoots by at most one episode).
        step_detail: per phase, how its steps are written: "per_action" (one `/step`, `/dialogue` and
            `/board` message per action, written as it happens: what Foxglove plays and plots over time),
            "packed" (one `/episode/steps` message of binary step rows per episode: ~13x cheaper in time,
            ~4x smaller; the reader expands it to the same step dicts) or "none" (only the `/episode`
            summary). Default: packed for train and eval (thousands of games), per action for robot games.
        board_image_phases: phases whose boards are also drawn as PNG on `/board/image`
            (`foxglove.CompressedImage`) so Foxglove shows the game. Default: robot games only. An image per
            move costs ~0.4 KB and ~0.1 ms, which would break the 2 KB-per-training-episode budget and slow
            the thousands of periodic evaluation games; every phase still has the board as text on `/board`,
            and `ncbot logs to-rerun` draws images from it. Pass ("eval", "robot") for a standalone eval log.
        flush_interval_s: close the open chunk when it is older than this; bounds what a kill -9 loses.
        chunk_bytes: also close a chunk when its uncompressed size passes this.
    """

    def __init__(self, run_dir: str | os.PathLike, run_info: dict[str, Any] | None = None, *,
                 max_file_bytes: int = DEFAULT_MAX_FILE_BYTES,
                 step_detail: Mapping[str, str] | None = None,
                 board_image_phases: Iterable[str] = ("robot", "play"),
                 flush_interval_s: float = 1.0, chunk_bytes: int = 2**20) -> None:
        if max_file_bytes <= 0:
            raise ValueError(f"max_file_bytes must be positive, got {max_file_bytes}")
        if flush_interval_s < 0:
            raise ValueError(f"flush_interval_s must be >= 0, got {flush_interval_s}")
        self.run_dir = Path(run_dir)
        if self.run_dir.exists() and not self.run_dir.is_dir():
            raise NotADirectoryError(f"run_dir {self.run_dir} is a file; expected a directory for episodes-NNNN.mcap")
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.run_info = dict(run_info or {})
        try:
            self._run_info_json = json.dumps(self.run_info, default=str)
        except (TypeError, ValueError) as error:
            raise ValueError(f"run_info must be JSON-serialisable: {error}") from None
        self.max_file_bytes = int(max_file_bytes)
        self.board_image_phases = frozenset(board_image_phases)
        self.step_detail = {**DEFAULT_STEP_DETAIL, **(step_detail or {})}
        for phase, detail in self.step_detail.items():
            schemas.check_phase(phase)
            if detail not in schemas.STEP_DETAIL_CHOICES:
                raise ValueError(f"step_detail for {phase} must be one of {', '.join(schemas.STEP_DETAIL_CHOICES)}, "
                                 f"got {detail!r}")
        for phase in self.board_image_phases:
            schemas.check_phase(phase)
        self.flush_interval_s = float(flush_interval_s)
        self.chunk_bytes = int(chunk_bytes)

        self._names = NameTables()
        self._names_source: int | None = None
        self._assemblers: dict[tuple, EpisodeAssembler] = {}
        self._open_episodes: dict[tuple, dict[int, list]] = {}  # per-action phases: ids of running episodes
        self._dialogue_notes: dict[str, dict[str, Any]] = {}  # speaker -> fields for its next /dialogue turn
        self._clock_anchor_ns = time.time_ns() - time.monotonic_ns()
        self._opened = time.monotonic()
        self._last_log_time = 0
        self._last_flush = time.monotonic()
        self._pending_bytes = 0  # uncompressed bytes in the open chunk (upper bound of what it adds to the file)
        self._file = None
        self._writer = None
        self._channels: dict[str, int] = {}
        self._closed = False
        existing = sorted(int(m.group(1)) for p in self.run_dir.iterdir() if (m := FILE_PATTERN.match(p.name)))
        self._file_index = existing[-1] + 1 if existing else 0
        self._next_episode = next_episode_id(self.run_dir, existing)
        self.files: list[Path] = []
        self._open_file()

    # ----------------------------------------------------------------- high level: TensorDicts
    def record_steps(self, td: Any, *, phase: str, agent: str, seed: int, epsilon: float | None = None,
                     env_steps: int | None = None, env: Any = None, game: str | None = None,
                     extra: dict[str, Any] | None = None, active: Any = None) -> list[int]:
        """Log one env step (batch (B,)) or a collector batch (B, T); return ids of the episodes that ended.

        `td` holds the env keys of docs/design.md (root = state the robot decided in, plus `action` and
        ("next", ...)) and optionally `action_value` (B, A) Q-values. Steps wait in a per-batch-index buffer
        until their episode's `done`; batches must therefore come from the same env stream for a given
        (phase, agent, seed) and batch index. `env` (once is enough) supplies the names of acts, utterances,
        robot commands and features; `epsilon`, `env_steps` and `extra` go into each `/episode` summary.
        `active` (bool (B,)) logs only those batch rows, e.g. the slots still playing their first test game
        in an evaluation that counts one game per slot (extra games would bias the logged results).
        """
        schemas.check_phase(phase)
        if env is not None and id(env) != self._names_source:
            self.set_names(NameTables.from_env(env))
            self._names_source = id(env)
        arrays = step_arrays(td)
        key = (phase, agent, seed)
        assembler = self._assemblers.setdefault(key, EpisodeAssembler())
        rows = None
        if active is not None:
            rows = np.asarray(active.cpu() if hasattr(active, "cpu") else active, dtype=bool).reshape(-1)
            if rows.shape[0] != arrays["action"].shape[0]:
                raise ValueError(f"active must have one flag per batch row ({arrays['action'].shape[0]}), got {rows.shape[0]}")
        detail = self.step_detail[phase]
        ids_at_end = self._stream_steps(key, arrays, rows, phase in self.board_image_phases) \
            if detail == "per_action" else {}
        finished = assembler.add(arrays, self._names, detail=detail == "packed", active=rows)
        if game is None:  # the env's game when its names were given, else the built-in game of this board size
            game = self._names.game or built_in_of_cells(arrays["next.board"].shape[-1])
        ids = [self._write_episode(episode, phase=phase, agent=agent, seed=seed, epsilon=epsilon,
                                   env_steps=env_steps, game=game, extra=extra,
                                   episode_id=ids_at_end.get((episode.batch_index, episode.end_t)))
               for episode in finished]
        self._maybe_flush()
        return ids

    def cut_off(self, phase: str, agent: str, seed: int, extra: dict[str, Any] | None = None) -> int | None:
        """End the running episode of batch row 0 that its env never ended (a robot game stopped when the robot's
        belief and the true board parted): its `/episode` summary with outcome "none", under the id its per-action
        steps were written with. Returns that id, None when no episode was running."""
        assembler = self._assemblers.get((phase, agent, seed))
        if assembler is None or len(assembler.length) == 0 or assembler.length[0] == 0:
            return None
        running = self._open_episodes.get((phase, agent, seed), {}).pop(0, None)
        episode = FinishedEpisode(None, None, [], 0, 0, int(assembler.length[0]),
                                  "first" if assembler.robot_first[0] else "second", "none", float(assembler.total[0]), False)
        assembler.length[0] = 0  # the row's next step starts a new episode
        return self._write_episode(episode, phase=phase, agent=agent, seed=seed, epsilon=None, env_steps=None,
                                   game=self._names.game or "standard", extra=extra,
                                   episode_id=None if running is None else running[0])

    def set_names(self, names: NameTables) -> None:
        """Use these name tables for utterances from now on (also stored as metadata `ncbot.names`)."""
        self._names = names
        self._writer.add_metadata("ncbot.names", names.to_metadata())

    def _write_episode(self, episode: FinishedEpisode, *, phase: str, agent: str, seed: int,
                       epsilon: float | None, env_steps: int | None, game: str,
                       extra: dict[str, Any] | None, episode_id: int | None = None) -> int:
        if episode_id is None:
            episode_id = self.new_episode_id()
        if episode.rows is not None:
            self._write_packed(episode_id, episode)
        summary = {"episode": episode_id, "phase": phase, "game": game, "agent": agent, "seed": int(seed),
                   "seat": episode.seat, "outcome": episode.outcome, "return": round(episode.total_reward, 4),
                   "length": episode.length, "task_success": episode.outcome in ("win", "draw"),
                   "truncated": episode.truncated,
                   "epsilon": None if epsilon is None else round(float(epsilon), 5),
                   "env_steps": None if env_steps is None else int(env_steps),
                   "wall_time": round(time.monotonic() - self._opened, 3)}
        if extra:
            summary["extra"] = extra
        self._write_json(schemas.EPISODE_TOPIC, summary)
        self._maybe_roll()
        return episode_id

    def _stream_steps(self, key: tuple, arrays: dict[str, np.ndarray], active: np.ndarray | None,
                      draw: bool) -> dict[tuple[int, int], int]:
        """Write `/step`, `/dialogue`, `/board` (and board images) for each step now, in time order, so a
        robot game plays back in step with its camera frames. An episode gets its id at its first step;
        returns {(b, t): id} of the episodes that ended in this batch."""
        rows, present = packed.batch_rows(arrays, self._names)
        batch, steps = rows.shape
        done = arrays["next.done"].reshape(batch, steps)
        turn = arrays["turn"].reshape(batch, steps) if "turn" in arrays else None
        open_episodes = self._open_episodes.setdefault(key, {})  # b -> [episode id, last board]
        ended: dict[tuple[int, int], int] = {}
        for t in range(steps):
            for b in range(batch):
                if (active is not None and not active[b]) or (turn is not None and turn[b, t] == 0):
                    open_episodes.pop(b, None)  # not logged, or a new episode begins here
                if active is not None and not active[b]:
                    continue
                if b not in open_episodes:
                    open_episodes[b] = [self.new_episode_id(), None]
                episode_id, previous = open_episodes[b]
                step_dicts, turns, boards = expand_episode(episode_id, rows[b, t:t + 1], present, self._names)
                self._write_json(schemas.STEP_TOPIC, step_dicts[0])
                for turn_dict in turns:
                    turn_dict.update(self._dialogue_notes.pop(turn_dict["speaker"], {}))
                    self._write_json(schemas.DIALOGUE_TOPIC, turn_dict)
                if "user" in self._dialogue_notes:  # a reply heard as nothing the env understood: still logged
                    self._write_json(schemas.DIALOGUE_TOPIC, {"episode": episode_id, "step": step_dicts[0]["step"],
                                                              "speaker": "user", "act": -1, "act_name": "not understood",
                                                              **self._dialogue_notes.pop("user")})
                self._dialogue_notes.clear()  # notes belong to this step's turns only
                self._write_json(schemas.BOARD_TOPIC, boards[0])
                if draw:
                    self.log_board_image(boards[0]["cells"], last_move=changed_cell(previous, boards[0]["cells"]),
                                         frame_id=f"episode{episode_id}")
                open_episodes[b][1] = boards[0]["cells"]
                if done[b, t]:
                    ended[(b, t)] = episode_id
                    del open_episodes[b]
        return ended

    # ----------------------------------------------------------------- low level: dicts per schema
    def new_episode_id(self) -> int:
        """A fresh run-wide episode id (for producers that call `log_episode` themselves)."""
        episode_id = self._next_episode
        self._next_episode += 1
        return episode_id

    def log_step(self, step: dict[str, Any]) -> None:
        """Write one `/step` message (keys per `schemas.STEP_SCHEMA`)."""
        self._write_json(schemas.STEP_TOPIC, schemas.checked_message(step, schemas.STEP_SCHEMA))

    def log_dialogue(self, turn: dict[str, Any]) -> None:
        """Write one `/dialogue` message (keys per `schemas.DIALOGUE_SCHEMA`)."""
        self._write_json(schemas.DIALOGUE_TOPIC, schemas.checked_message(turn, schemas.DIALOGUE_SCHEMA))

    def note_dialogue(self, speaker: str, **fields: Any) -> None:
        """Fields (per `schemas.DIALOGUE_SCHEMA`, e.g. what the recogniser heard, the audio's place) merged into
        `speaker`'s `/dialogue` turn of the next streamed step (one game, B = 1): the robot game knows them, the
        env's TensorDict does not. A user note without a user turn (heard as silence) is written as act -1."""
        if speaker not in ("robot", "user"):
            raise ValueError(f"speaker must be robot or user, got {speaker!r}")
        self._dialogue_notes.setdefault(speaker, {}).update(fields)

    def log_board(self, board: dict[str, Any], image: bool = False) -> None:
        """Write one `/board` message (keys per `schemas.BOARD_SCHEMA`), and its picture if `image`."""
        self._write_json(schemas.BOARD_TOPIC, schemas.checked_message(board, schemas.BOARD_SCHEMA))
        if image:
            self.log_board_image(board["cells"], frame_id=f"episode{board['episode']}")

    def log_episode(self, summary: dict[str, Any]) -> None:
        """Write one `/episode` summary (keys per `schemas.EPISODE_SCHEMA`); may start a new file after it."""
        summary = schemas.checked_message(summary, schemas.EPISODE_SCHEMA)
        schemas.check_phase(summary["phase"])
        if summary["outcome"] not in schemas.OUTCOMES:
            raise ValueError(f"outcome must be one of {', '.join(schemas.OUTCOMES)}, got {summary['outcome']!r}")
        summary.setdefault("wall_time", round(time.monotonic() - self._opened, 3))
        self._write_json(schemas.EPISODE_TOPIC, summary)
        self._maybe_roll()
        self._maybe_flush()

    # ----------------------------------------------------------------- Foxglove types (protobuf)
    def log_board_image(self, cells: Any, last_move: int = -1, frame_id: str = "board", t: float | None = None) -> None:
        """Draw the board and write it as a PNG `foxglove.CompressedImage` on `/board/image`."""
        self.log_camera(board_png(cells, last_move, self._names.cols), image_format="png", frame_id=frame_id, t=t,
                        topic=schemas.BOARD_IMAGE_TOPIC)

    def log_camera(self, image: bytes, *, image_format: str = "jpeg", frame_id: str = "CameraBottom",
                   t: float | None = None, topic: str = schemas.CAMERA_TOPIC) -> None:
        """Write an encoded camera frame (JPEG/PNG bytes) as `foxglove.CompressedImage`.

        `t` is the producer's own time in seconds (e.g. simulation time) and goes into the message
        timestamp; the MCAP log time always comes from the logger's clock.
        """
        self._write_protobuf(topic, foxglove.compressed_image(image, image_format, frame_id), t)

    def log_audio(self, audio: Any, *, topic: str, t: float | None = None) -> None:
        """Write a `foxglove.RawAudio` message (e.g. `ncbot.speech.audio.raw_audio(samples)`) on `topic`
        (`/audio/robot`, `/audio/user`); `t` is the producer's time of the sound's start, as in `log_camera`."""
        if getattr(getattr(type(audio), "DESCRIPTOR", None), "full_name", None) != "foxglove.RawAudio":
            raise ValueError(f"log_audio needs a foxglove.RawAudio message, got {type(audio).__name__}")
        if not topic.startswith("/audio/"):
            raise ValueError(f"audio topics live under /audio/, got {topic!r}")
        self._write_protobuf(topic, audio, t)

    def log_joint_states(self, names: Sequence[str], positions: Sequence[float],
                         velocities: Sequence[float] | None = None, efforts: Sequence[float] | None = None,
                         t: float | None = None) -> None:
        """Write joint positions (rad or m) as `foxglove.JointStates` on `/joint_states`."""
        self._write_protobuf(schemas.JOINT_STATES_TOPIC, foxglove.joint_states(names, positions, velocities, efforts), t)

    def log_transform(self, parent: str, child: str, translation: Sequence[float],
                      rotation_xyzw: Sequence[float] = (0.0, 0.0, 0.0, 1.0), t: float | None = None) -> None:
        """Write a `foxglove.FrameTransform` (child pose in the parent frame) on `/tf`."""
        self._write_protobuf(schemas.TRANSFORM_TOPIC, foxglove.frame_transform(parent, child, translation, rotation_xyzw), t)

    # ----------------------------------------------------------------- files, chunks, time
    def flush(self) -> None:
        """Close the open chunk and hand it to the OS: everything logged so far survives a kill -9."""
        if self._writer is not None:
            self._writer.flush()
            self._file.flush()
        self._pending_bytes = 0
        self._last_flush = time.monotonic()

    def roll(self) -> int:
        """Finish the current file and open the next; returns the new file's index.

        Why: a training checkpoint rolls the log, so everything logged up to it sits in finished files and the
        checkpoint can record where its episodes end; `--resume` drops the files from that index on, and the
        log then holds exactly the episodes the resumed counters count (pipelines/run_folder.py).
        """
        self._require_open()
        self._finish_file()
        self._file_index += 1
        self._open_file()
        return self._file_index

    def close(self) -> None:
        """Finish the current file (summary + index), close it. Unfinished episodes are dropped."""
        if self._closed:
            return
        self._closed = True
        self._finish_file()

    def __enter__(self) -> "EpisodeLogger":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def current_file(self) -> Path:
        return self.files[-1]

    def _now_ns(self) -> int:
        now = self._clock_anchor_ns + time.monotonic_ns()
        if now <= self._last_log_time:
            now = self._last_log_time + 1
        self._last_log_time = now
        return now

    def _open_file(self) -> None:
        from mcap.writer import CompressionType, Writer

        path = self.run_dir / episode_file_name(self._file_index)
        self._file = open(path, "xb")
        self._writer = Writer(self._file, chunk_size=self.chunk_bytes, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="ncbot")
        self._writer.add_metadata("ncbot.run", {"schema_version": str(schemas.SCHEMA_VERSION),
                                                "file_index": str(self._file_index),
                                                "first_episode": str(self._next_episode),
                                                "run_info": self._run_info_json})
        if self._names.action_names or self._names.feature_names:
            self._writer.add_metadata("ncbot.names", self._names.to_metadata())
        self._channels = {}  # registered on first use, so a file lists only the channels it has
        self.files.append(path)
        self._file.flush()

    def _finish_file(self) -> None:
        if self._writer is not None:
            # indexed in the summary: the next logger on this run continues ids without reading the file
            self._writer.add_metadata("ncbot.end", {"next_episode": str(self._next_episode)})
            self._writer.finish()
            self._file.flush()
            os.fsync(self._file.fileno())  # a finished file survives a power loss with its summary and index
            self._file.close()
            fsync_folder(self.run_dir)
            self._writer = None
            self._file = None

    def _maybe_roll(self) -> None:
        if self._file is None:
            return
        if self._file.tell() + self._pending_bytes >= self.max_file_bytes:
            self.flush()  # the open chunk might push the file over: write it to learn the real size
        if self._file.tell() >= self.max_file_bytes:
            self._finish_file()
            self._file_index += 1
            self._open_file()

    def _maybe_flush(self) -> None:
        if time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()

    def _write_json(self, topic: str, message: dict[str, Any]) -> None:
        self._require_open()
        log_time = self._now_ns()
        data = json.dumps(message, separators=(",", ":")).encode()
        self._pending_bytes += len(data) + MESSAGE_RECORD_OVERHEAD
        channel = self._channels.get(topic)
        if channel is None:
            schema = schemas.JSON_SCHEMAS[topic]
            schema_id = self._writer.register_schema(schema["title"], "jsonschema", schemas.schema_bytes(schema))
            channel = self._channels[topic] = self._writer.register_channel(topic, "json", schema_id)
        self._writer.add_message(channel, log_time=log_time, data=data, publish_time=log_time)

    def _write_packed(self, episode_id: int, episode: FinishedEpisode) -> None:
        self._require_open()
        if schemas.EPISODE_STEPS_TOPIC not in self._channels:
            schema_id = self._writer.register_schema(packed.SCHEMA_NAME, "protobuf", packed.descriptor_set())
            self._channels[schemas.EPISODE_STEPS_TOPIC] = self._writer.register_channel(
                schemas.EPISODE_STEPS_TOPIC, "protobuf", schema_id)
        data = packed.encode(episode_id, episode.length, episode.row_dtype, episode.rows, episode.present)
        self._pending_bytes += len(data) + MESSAGE_RECORD_OVERHEAD
        log_time = self._now_ns()
        self._writer.add_message(self._channels[schemas.EPISODE_STEPS_TOPIC], log_time=log_time, data=data,
                                 publish_time=log_time)

    def _write_protobuf(self, topic: str, message: Any, t: float | None) -> None:
        from mcap_protobuf.schema import register_schema

        self._require_open()
        log_time = self._now_ns()
        stamp = log_time if t is None else int(round(float(t) * 1e9))
        message.timestamp.FromNanoseconds(stamp)
        if topic not in self._channels:
            schema_id = register_schema(self._writer, type(message))
            self._channels[topic] = self._writer.register_channel(topic, "protobuf", schema_id)
        data = message.SerializeToString()
        self._pending_bytes += len(data) + MESSAGE_RECORD_OVERHEAD
        self._writer.add_message(self._channels[topic], log_time=log_time, data=data, publish_time=log_time)
        self._maybe_flush()

    def _require_open(self) -> None:
        if self._closed:
            raise ValueError("the EpisodeLogger is closed; open a new one to log more")
