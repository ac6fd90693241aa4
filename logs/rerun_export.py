"""`ncbot logs to-rerun`: an ncbot MCAP log as a rerun recording (.rrd), for the rerun viewer.

We convert ourselves instead of relying on rerun's MCAP importer because our own channels are JSON, which
that importer keeps as opaque blobs. Timelines: `step` (one tick per robot action across the exported
episodes), `episode` (the episode id) and `log_time` (the MCAP log time, also used for camera frames and
joint states, which are not tied to a step).
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Iterable

from ncbot.fileio import atomic_path
import ncbot.logs.schemas as schemas
from ncbot.logs.board_image import board_png, changed_cell
from ncbot.logs.names import NameTables
from ncbot.logs.reader import EpisodeRecord, LogReader, read_episode_records


def parse_episode_spec(spec: str | None) -> set[int] | None:
    """'3,7,10-12' -> {3, 7, 10, 11, 12}; None/'' -> None (all)."""
    if not spec:
        return None
    chosen: set[int] = set()
    for part in spec.split(","):
        part = part.strip()
        try:
            if "-" in part:
                low, high = (int(v) for v in part.split("-", 1))
                if high < low:
                    raise ValueError
                chosen.update(range(low, high + 1))
            elif part:
                chosen.add(int(part))
        except ValueError:
            raise ValueError(f"bad --episodes value {spec!r}: expected ids and ranges like '3,7,10-12'") from None
    return chosen


def export_to_rerun(path: str | Path, output: str | Path, episodes: Iterable[int] | None = None,
                    max_episodes: int = 200, progress: Callable[..., Any] | None = None) -> dict[str, Any]:
    """Write the chosen episodes (default: the last `max_episodes`) and any camera/joint/tf messages in their
    time range to `output` (.rrd, atomically). Returns counts of what was written."""
    import rerun as rr

    output = Path(output)
    if output.suffix != ".rrd":
        raise ValueError(f"rerun recordings end in .rrd; got output path {output}")
    reader = LogReader(path, progress=progress)
    if episodes is None:  # pick ids from the cheap summaries first so a long run is never loaded whole
        ids = [m.data["episode"] for m in reader.messages([schemas.EPISODE_TOPIC])]
        episodes = ids[-max_episodes:] if ids else None
    records = read_episode_records(path, episodes, reader=reader)
    reader.require_ncbot()
    if episodes is not None:
        missing = sorted(set(episodes) - set(records))
        if missing and not records:
            raise ValueError(f"none of the requested episodes ({_short(missing)}) are in {path}")
    chosen = [records[key] for key in sorted(records)][-max_episodes:]
    if not chosen:
        raise ValueError(f"{path} holds no episodes to export")
    names = NameTables.from_metadata(reader.names())

    counts = {"episodes": 0, "steps": 0, "camera_frames": 0, "joint_states": 0, "transforms": 0}
    with atomic_path(output) as temporary:
        recording = rr.RecordingStream("ncbot", recording_id=f"ncbot-{Path(path).resolve().name}")
        recording.save(temporary)
        tick = 0
        for record in chosen:
            tick = _log_episode(recording, rr, record, names, tick)
            counts["episodes"] += 1
            counts["steps"] += len(record.steps)
        _log_robot_streams(recording, rr, reader, chosen, counts)
        recording.flush()
        recording.disconnect()
    counts["bytes"] = output.stat().st_size
    return counts


def _log_episode(recording: Any, rr: Any, record: EpisodeRecord, names: NameTables, tick: int) -> int:
    turns_by_step: dict[int, list[dict]] = {}
    for turn in record.dialogue:
        turns_by_step.setdefault(int(turn["step"]), []).append(turn)
    boards = {int(board["step"]): board for board in record.boards}
    summary = record.summary or {}
    total = 0.0
    previous_cells = None
    for step, log_time in zip(record.steps, record.step_times):
        recording.set_time("step", sequence=tick)
        recording.set_time("episode", sequence=record.episode)
        recording.set_time("log_time", timestamp=log_time / 1e9)
        index = int(step["step"])
        reward = float(step.get("reward", 0.0))
        total += reward
        recording.log("reward", rr.Scalars([reward]))
        recording.log("return_so_far", rr.Scalars([total]))
        for act, value in zip(step.get("mask", []), step.get("q") or []):
            recording.log(f"q/{_entity(names.action_name(int(act)))}", rr.Scalars([float(value)]))
        for turn in turns_by_step.get(index, []):
            speaker = "ROBOT" if turn["speaker"] == "robot" else "USER"
            text = turn.get("text") or turn.get("act_name", "")
            if turn.get("command"):
                text += f" [{turn['command']}]"
            if turn.get("words"):
                text += "  words: " + ", ".join(f"{w}:{c:.2f}" for w, c in turn["words"])
            recording.log("dialogue", rr.TextLog(f"{speaker}: {text}", level="INFO" if speaker == "ROBOT" else "DEBUG"))
        board = boards.get(index)
        if board is not None:
            last = changed_cell(previous_cells, board["cells"])
            recording.log("board", rr.EncodedImage(contents=board_png(board["cells"], last, names.cols), media_type="image/png"))
            previous_cells = board["cells"]
        tick += 1
    if summary:
        recording.log("episode/summary", rr.TextLog(
            f"episode {record.episode} {summary.get('phase')} {summary.get('agent')}: outcome {summary.get('outcome')}, "
            f"return {summary.get('return')}, length {summary.get('length')}", level="WARN"))
        recording.log("episode/return", rr.Scalars([float(summary.get("return", 0.0))]))
        recording.log("episode/task_success", rr.Scalars([1.0 if summary.get("task_success") else 0.0]))
    return tick


def _log_robot_streams(recording: Any, rr: Any, reader: LogReader, chosen: list[EpisodeRecord], counts: dict) -> None:
    """Camera frames, joint states and transforms inside the exported episodes' time range, on log_time."""
    times = [t for record in chosen for t in record.step_times]
    if not times:
        return
    start, end = min(times) - int(60e9), max(times) + int(60e9)
    topics = [schemas.CAMERA_TOPIC, schemas.JOINT_STATES_TOPIC, schemas.TRANSFORM_TOPIC]
    recording.reset_time()
    for message in reader.messages(topics):
        if not start <= message.log_time <= end or isinstance(message.data, (bytes, bytearray)):
            continue
        recording.set_time("log_time", timestamp=message.log_time / 1e9)
        if message.topic == schemas.CAMERA_TOPIC:
            media = "image/png" if message.data.format == "png" else "image/jpeg"
            recording.log("camera", rr.EncodedImage(contents=message.data.data, media_type=media))
            counts["camera_frames"] += 1
        elif message.topic == schemas.JOINT_STATES_TOPIC:
            for joint in message.data.joints:
                recording.log(f"joints/{_entity(joint.name)}", rr.Scalars([joint.position]))
            counts["joint_states"] += 1
        elif message.topic == schemas.TRANSFORM_TOPIC:
            t, q = message.data.translation, message.data.rotation
            recording.log(f"tf/{_entity(message.data.parent_frame_id)}/{_entity(message.data.child_frame_id)}",
                          rr.Transform3D(translation=[t.x, t.y, t.z], quaternion=rr.Quaternion(xyzw=[q.x, q.y, q.z, q.w])))
            counts["transforms"] += 1


def _entity(name: str) -> str:
    """An entity-path-safe version of an action or joint name."""
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in name).strip("_") or "unnamed"


def _short(ids: list[int]) -> str:
    return ", ".join(map(str, ids[:10])) + (" ..." if len(ids) > 10 else "")
