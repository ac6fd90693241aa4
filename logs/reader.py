"""Read ncbot MCAP logs back, including files cut off by a crash.

The reader streams records in file order rather than using the summary section: it works the same on a
finished file and on one whose writer was killed (no summary, a half-written last chunk). It stops at the
first incomplete record and reports how many bytes were cut off.
"""
from __future__ import annotations

import json
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import ncbot.logs.packed as packed
import ncbot.logs.schemas as schemas
from ncbot.logs.names import NameTables
from ncbot.logs.steps import expand_episode

MCAP_MAGIC = b"\x89MCAP0\r\n"
FILE_PATTERN = re.compile(r"^episodes-(\d{4,})\.mcap$")  # the files an EpisodeLogger writes in a run folder
PROGRESS_MIN_BYTES = 16 * 2**20

# Foxglove protobuf types the logger writes, decoded by schema name.
_PROTOBUF_TYPES = {
    "foxglove.CompressedImage": ("foxglove_schemas_protobuf.CompressedImage_pb2", "CompressedImage"),
    "foxglove.JointStates": ("foxglove_schemas_protobuf.JointStates_pb2", "JointStates"),
    "foxglove.FrameTransform": ("foxglove_schemas_protobuf.FrameTransform_pb2", "FrameTransform"),
    "foxglove.RawImage": ("foxglove_schemas_protobuf.RawImage_pb2", "RawImage"),
    "foxglove.RawAudio": ("foxglove_schemas_protobuf.RawAudio_pb2", "RawAudio"),
}


@dataclass
class FileScan:
    """What reading one file found: channels, counts, time span, and whether (and how much) it was cut off."""

    path: Path
    size: int
    channels: dict[str, tuple[str, str]] = field(default_factory=dict)  # topic -> (schema name, encoding)
    counts: Counter = field(default_factory=Counter)
    start_ns: int | None = None
    end_ns: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    complete: bool = False
    good_bytes: int = 0
    error: str | None = None

    @property
    def truncated(self) -> bool:
        return not self.complete

    @property
    def cut_bytes(self) -> int:
        """Bytes after the last record that could be read (0 for a finished file)."""
        return 0 if self.complete else self.size - self.good_bytes


@dataclass
class LogMessage:
    """One decoded message: JSON channels give a dict, Foxglove channels a protobuf message."""

    topic: str
    log_time: int
    data: Any
    path: Path


def list_log_files(path: str | Path) -> list[Path]:
    """The MCAP files of a log: the file itself, or a run directory's `*.mcap` files in name order."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist; expected an .mcap file or a run directory holding episodes-NNNN.mcap")
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix == ".mcap" and p.is_file())
        if not files:
            raise ValueError(f"{path} holds no .mcap files; expected a run directory with episodes-NNNN.mcap")
        return files
    return [path]


def check_mcap_file(path: Path) -> None:
    """Fail with one clear sentence on an empty or non-MCAP file."""
    size = path.stat().st_size
    if size == 0:
        raise ValueError(f"{path} is empty (0 bytes); expected an MCAP file written by ncbot")
    with open(path, "rb") as handle:
        head = handle.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC[: len(head)] or len(head) < len(MCAP_MAGIC):
        raise ValueError(f"{path} is not an MCAP file (it does not start with the MCAP magic bytes)")


class LogReader:
    """Streams the messages of one MCAP file or a run directory, recording a `FileScan` per file.

    `messages()` can be called several times; each call re-reads the files. After a full pass,
    `scans` holds the per-file findings and `require_ncbot()` rejects a foreign MCAP.
    """

    def __init__(self, path: str | Path, progress: Callable[..., Any] | None = None) -> None:
        self.path = Path(path)
        # a bar factory with tqdm's signature (the CLI passes pipelines.progress.progress_bar): bytes read, rate and
        # ETA for logs of PROGRESS_MIN_BYTES or more; None = silent
        self.progress = progress
        self.files = list_log_files(path)
        for file in self.files:
            check_mcap_file(file)
        self.scans: dict[Path, FileScan] = {}

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[LogMessage]:
        """Every message on `topics` (all if None), file by file in log order; JSON is decoded."""
        wanted = None if topics is None else frozenset(topics)
        total = sum(file.stat().st_size for file in self.files)
        bar = None
        if self.progress is not None and total >= PROGRESS_MIN_BYTES:
            bar = self.progress(total=total, unit="B", unit_scale=True, desc=f"reading {self.path.name}", leave=False)
        try:
            for file in self.files:
                yield from self._file_messages(file, wanted, bar)
        finally:
            if bar is not None:
                bar.close()

    def scan(self) -> list[FileScan]:
        """Read everything once (counts, time span, truncation) without keeping messages."""
        for _ in self.messages(topics=()):
            pass
        return [self.scans[file] for file in self.files]

    def require_ncbot(self) -> None:
        """Raise ValueError if no file has any of ncbot's channels (an MCAP from another tool)."""
        if not self.scans:
            self.scan()
        topics = {topic for scan in self.scans.values() for topic in scan.channels}
        ours = any("ncbot.run" in scan.metadata for scan in self.scans.values())  # also a file killed early
        if not (topics & set(schemas.NCBOT_TOPICS) or ours):
            if not topics and all(scan.truncated for scan in self.scans.values()):
                raise ValueError(f"{self.path} was cut off before any record could be read "
                                 f"({sum(scan.size for scan in self.scans.values())} bytes); nothing to recover")
            found = ", ".join(sorted(topics)) or "no channels"
            raise ValueError(f"{self.path} is an MCAP file without ncbot channels ({found}); expected "
                             f"{', '.join(schemas.NCBOT_TOPICS)} as written by logs.EpisodeLogger")

    def names(self) -> dict[str, str]:
        """The last `ncbot.names` metadata seen so far (name tables of acts, utterances, features); the same
        dict object until newer names are read, so callers can cache what they derive from it."""
        found: dict[str, str] = {}
        for scan in self.scans.values():
            found = scan.metadata.get("ncbot.names", found)
        return found

    def _file_messages(self, file: Path, wanted: frozenset[str] | None, bar: Any) -> Iterator[LogMessage]:
        from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
        from mcap.stream_reader import StreamReader, breakup_chunk

        scan = FileScan(path=file, size=file.stat().st_size)
        self.scans[file] = scan
        schema_of: dict[int, tuple[str, str, bytes]] = {}
        channel_of: dict[int, tuple[str, str, str]] = {}
        decoders: dict[int, Any] = {}
        with open(file, "rb") as handle:
            reader = StreamReader(handle, emit_chunks=True)
            records = iter(reader.records)
            while True:
                try:
                    record = next(records)
                    inner = breakup_chunk(record) if isinstance(record, Chunk) else [record]
                except StopIteration:
                    break
                except Exception as error:  # a cut-off record: stop here, keep what was complete
                    scan.error = f"{type(error).__name__}: {error}".strip()
                    break
                if bar is not None:
                    bar.update(handle.tell() - scan.good_bytes)
                scan.good_bytes = handle.tell()
                for item in inner:
                    if isinstance(item, Message):
                        channel = channel_of.get(item.channel_id)
                        if channel is None:
                            continue
                        topic = channel[0]
                        scan.counts[topic] += 1
                        scan.start_ns = item.log_time if scan.start_ns is None else min(scan.start_ns, item.log_time)
                        scan.end_ns = item.log_time if scan.end_ns is None else max(scan.end_ns, item.log_time)
                        if wanted is not None and topic not in wanted:
                            continue
                        decoder = decoders.get(item.channel_id)
                        if decoder is None:
                            decoder = decoders[item.channel_id] = _decoder(channel, schema_of)
                        yield LogMessage(topic, item.log_time, decoder(item.data), file)
                    elif isinstance(item, Schema):
                        schema_of[item.id] = (item.name, item.encoding, item.data)
                    elif isinstance(item, Channel):
                        schema_name = schema_of.get(item.schema_id, ("", "", b""))[0]
                        channel_of[item.id] = (item.topic, item.message_encoding, schema_name)
                        scan.channels[item.topic] = (schema_name, item.message_encoding)
                    elif isinstance(item, Metadata):
                        scan.metadata[item.name] = dict(item.metadata)
                    elif isinstance(item, (DataEnd, Footer)):
                        scan.complete = scan.complete or isinstance(item, Footer)
        if scan.complete:
            scan.good_bytes = scan.size


def _decoder(channel: tuple[str, str, str], schema_of: dict) -> Any:
    _, encoding, schema_name = channel
    if encoding == "json":
        return lambda data: json.loads(data)
    if encoding == "protobuf" and schema_name == packed.SCHEMA_NAME:
        return packed.message_class().FromString
    if encoding == "protobuf" and schema_name in _PROTOBUF_TYPES:
        import importlib

        module_name, class_name = _PROTOBUF_TYPES[schema_name]
        message_type = getattr(importlib.import_module(module_name), class_name)
        return message_type.FromString
    return lambda data: data


# --------------------------------------------------------------------------- convenience readers
def read_episodes(path: str | Path, require_ncbot: bool = True,
                  progress: Callable[..., Any] | None = None) -> list[dict[str, Any]]:
    """All `/episode` summaries of a file or run directory, in log order (ValueError on a foreign MCAP)."""
    reader = LogReader(path, progress=progress)
    episodes = [message.data for message in reader.messages([schemas.EPISODE_TOPIC])]
    if require_ncbot:
        reader.require_ncbot()
    return episodes


@dataclass
class EpisodeRecord:
    """Everything logged about one episode, for replay and export."""

    episode: int
    summary: dict[str, Any] | None
    steps: list[dict[str, Any]] = field(default_factory=list)
    dialogue: list[dict[str, Any]] = field(default_factory=list)
    boards: list[dict[str, Any]] = field(default_factory=list)
    step_times: list[int] = field(default_factory=list)


def read_episode_records(path: str | Path, episode_ids: Iterable[int] | None = None,
                         reader: LogReader | None = None) -> dict[int, EpisodeRecord]:
    """Steps, dialogue turns, boards and summaries grouped by episode id (only `episode_ids` if given)."""
    reader = reader or LogReader(path)
    wanted = None if episode_ids is None else set(int(e) for e in episode_ids)
    records: dict[int, EpisodeRecord] = {}
    tables: tuple[int, NameTables] = (-1, NameTables())
    for message in reader.messages(list(schemas.NCBOT_TOPICS)):
        episode_id = message.data.get("episode") if isinstance(message.data, dict) else \
            int(message.data.episode) if message.topic == schemas.EPISODE_STEPS_TOPIC else None
        if episode_id is None or (wanted is not None and episode_id not in wanted):
            continue
        record = records.setdefault(episode_id, EpisodeRecord(episode_id, None))
        if message.topic == schemas.EPISODE_TOPIC:
            record.summary = message.data
        elif message.topic == schemas.EPISODE_STEPS_TOPIC:
            _, rows, present = packed.decode(message.data)
            metadata = reader.names()
            if tables[0] != id(metadata):
                tables = (id(metadata), NameTables.from_metadata(metadata))
            steps, dialogue, boards = expand_episode(episode_id, rows, present, tables[1])
            record.steps.extend(steps)
            record.dialogue.extend(dialogue)
            record.boards.extend(boards)
            record.step_times.extend(message.log_time + index for index in range(len(steps)))
        elif message.topic == schemas.STEP_TOPIC:
            record.steps.append(message.data)
            record.step_times.append(message.log_time)
        elif message.topic == schemas.DIALOGUE_TOPIC:
            record.dialogue.append(message.data)
        elif message.topic == schemas.BOARD_TOPIC:
            record.boards.append(message.data)
    return records


def episode_file_name(index: int) -> str:
    return f"episodes-{index:04d}.mcap"


def next_episode_id(run_dir: Path, existing: list[int]) -> int:
    """Continue after the largest episode id of the run. A finished file says it in its `ncbot.end` metadata
    (read through the summary index); otherwise (a crashed writer) the newest file holding an episode is
    read with crash recovery: ids grow with the file index."""
    for index in reversed(existing):
        path = run_dir / episode_file_name(index)
        with open(path, "rb") as handle:
            handle.seek(max(0, path.stat().st_size - len(MCAP_MAGIC)))
            complete = handle.read() == MCAP_MAGIC
            if complete:
                from mcap.reader import make_reader

                handle.seek(0)
                for record in make_reader(handle).iter_metadata():
                    if record.name == "ncbot.end":
                        return int(record.metadata["next_episode"])
        ids = [int(summary["episode"]) for summary in read_episodes(path, require_ncbot=False)]
        if ids:
            return max(ids) + 1
    return 0
