"""A training run folder with an identity: checked before any work, locked while a run writes, never mixed.

Why: two runs writing one folder deleted each other's checkpoints and interleaved one log, and a fresh run into an
old folder resumed the old run's state after a kill. So:
- `ncbot.pipelines.outputs.check_writable_dir` refuses an output that is a file or cannot be written, before any work;
- `RunFolder.open` takes an exclusive `flock` on RUN/.lock (a second writer gets one line and exit 2; the kernel
  drops the lock when a run dies, so a killed run's lock is taken over without a stale-pid dance), then either
  checks a fresh folder (refusing one that holds another run unless `overwrite`), or, to resume, picks the newest
  periodic checkpoint of THIS run (run.json's id) that loads, falling back past damaged ones and saying which;
- `RunFolder.claim` makes the folder the run's (clearing an overwritten run, writing run.json) once training has
  built its parts: a run refused while it is built (no room on the disk) leaves the folder as it was;
- stray temp files of killed writers (`ncbot.fileio.TEMP_GLOB`) anywhere in the folder are removed once the lock is ours;
- the MCAP log is rolled at every checkpoint (`EpisodeLogger.roll`), the checkpoint records the first file written
  after it, and a resume deletes the files from there on: the log keeps exactly the episodes the counters count.
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ncbot.fileio import TEMP_GLOB, atomic_write_text
from ncbot.pipelines.outputs import check_writable_dir

IDENTITY_NAME = "run.json"
LOCK_NAME = ".lock"
# what an ncbot train run writes into its folder (all removed by --overwrite; anything else is left alone)
RUN_FILES = ("checkpoint.pt", "eval.json", "config.yaml", IDENTITY_NAME, "learning_curve.png")
RUN_FOLDERS = ("checkpoints", "scalars")
MCAP_GLOB = "episodes-*.mcap"


def holds_run(path: Path) -> bool:
    """Does the folder hold (part of) an ncbot train run?"""
    return path.is_dir() and (any((path / name).exists() for name in RUN_FILES)
                              or any((path / name).exists() for name in RUN_FOLDERS)
                              or any(path.glob(MCAP_GLOB)))


def remove_stray_temp_files(run_dir: str | os.PathLike) -> list[Path]:
    """Delete the temp files `ncbot.fileio.atomic_path` leaves when a writer is killed mid-write, anywhere in the run
    folder; only for a folder whose lock we hold (no other writer)."""
    stray = [p for p in Path(run_dir).rglob(TEMP_GLOB) if p.is_file()]
    for path in stray:
        path.unlink(missing_ok=True)
    return stray


def clear_run(path: Path) -> None:
    """Remove what an earlier run wrote (`--overwrite`); files that are not ncbot's stay."""
    for name in RUN_FILES:
        (path / name).unlink(missing_ok=True)
    for name in RUN_FOLDERS:
        shutil.rmtree(path / name, ignore_errors=True)
    for log in path.glob(MCAP_GLOB):
        log.unlink(missing_ok=True)


def drop_logs_after(path: Path, next_file: int | None) -> list[Path]:
    """Delete MCAP files numbered `next_file` or later: episodes played after the checkpoint a run resumes from."""
    if next_file is None:
        return []
    from ncbot.logs.reader import FILE_PATTERN

    dropped = [p for p in path.glob(MCAP_GLOB) if (m := FILE_PATTERN.match(p.name)) and int(m.group(1)) >= next_file]
    for log in dropped:
        log.unlink(missing_ok=True)
    return dropped


def lock_holder(path: Path) -> int | None:
    """The pid of the `ncbot train` holding RUN/.lock now (-1 if it wrote none yet), or None when nobody holds it.

    A shared, non-blocking probe, released at once: a writer taking the lock in that same instant would be refused
    as if another run held it, so the probe is for status and scheduling, never for a run's own claim."""
    import fcntl

    lock = path / LOCK_NAME
    if not lock.is_file():
        return None
    fd = os.open(lock, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError as error:
        if error.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise
        holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        return int(holder) if holder.isdigit() else -1
    finally:
        os.close(fd)  # closing the descriptor drops the probe's shared lock
    return None


def lock_taken_at(path: Path) -> float | None:
    """When the current or last holder took RUN/.lock (epoch seconds), or None without one: `RunLock` rewrites the
    file with its pid on taking it, so its modification time is the holder's start."""
    try:
        return (path / LOCK_NAME).stat().st_mtime
    except OSError:
        return None


class RunLock:
    """An exclusive `flock` on RUN/.lock for as long as the run writes; the kernel releases it if the run dies."""

    def __init__(self, path: Path) -> None:
        import fcntl

        self.created_folder = not path.exists()  # made here: a run refused before it claimed it leaves nothing
        path.mkdir(parents=True, exist_ok=True)
        self.path = path / LOCK_NAME
        self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            holder = os.pread(self._fd, 32, 0).decode("ascii", "replace").strip() or "?"
            os.close(self._fd)
            if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise ValueError(f"run folder {str(path)!r} is in use by another ncbot train (pid {holder}); "
                                 "wait for it to finish or choose another --out") from None
            raise
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, f"{os.getpid()}\n".encode(), 0)

    def release(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)  # closing the descriptor drops the flock
            self._fd = -1


@dataclass
class RunFolder:
    """A locked run folder: its identity and, when resuming, the training state to continue from."""

    path: Path
    run_id: str
    state: dict[str, Any] | None = None
    state_path: Path | None = None
    notes: list[str] = field(default_factory=list)
    lock: RunLock | None = None
    fresh: bool = False  # a new run: `claim` writes its identity (and clears an overwritten run first)
    overwrite: bool = False
    claimed: bool = False

    @classmethod
    def open(cls, path: str | os.PathLike, *, resume: bool, overwrite: bool,
             validate: Callable[[dict[str, Any], Path], None] | None = None, claim: bool = True) -> RunFolder:
        """Lock the folder and pick the state to resume, or check that a fresh run may take it; one-line errors
        otherwise. With `claim` (else call `claim()` once the run is built) the folder becomes this run's."""
        path = check_writable_dir(path, "--out" if not resume else "--resume")
        if resume and not path.is_dir():
            raise FileNotFoundError(f"run folder {str(path)!r} not found (expected the --out folder of an earlier "
                                    "ncbot train)")
        lock = RunLock(path)
        try:
            if resume:
                run = cls._resume(path, validate)
            else:
                if holds_run(path) and not overwrite:
                    raise ValueError(f"run folder {str(path)!r} holds another run; continue it with --resume "
                                     f"{str(path)!r}, replace it with --overwrite, or choose another --out")
                run = cls(path, uuid.uuid4().hex, fresh=True, overwrite=overwrite)
            removed = remove_stray_temp_files(path)
            if removed:
                run.notes.append(f"removed {len(removed)} temp file(s) of an interrupted write")
            run.lock = lock
            if claim:
                run.claim()
        except BaseException:
            lock.release()
            raise
        return run

    def claim(self) -> None:
        """Make the folder this run's: an overwritten run's files go, and a fresh run (or a folder of an ncbot
        older than run ids) gets its identity, run.json."""
        self.claimed = True
        if self.fresh and self.overwrite:
            clear_run(self.path)
        if self.fresh or read_run_id(self.path) is None:
            atomic_write_text(json.dumps({"run_id": self.run_id, "created": time.time()}) + "\n",
                              self.path / IDENTITY_NAME)

    @classmethod
    def _resume(cls, path: Path, validate: Callable[[dict[str, Any], Path], None] | None) -> RunFolder:
        from ncbot.pipelines.checkpoint import MCAP_KEY, newest_resumable, periodic_checkpoints

        run_id = read_run_id(path)

        def check(state: dict[str, Any], candidate: Path) -> None:
            if run_id is not None and state.get("run_id") not in (None, run_id):
                raise ValueError(f"checkpoint {str(candidate)!r} belongs to another run (id {state.get('run_id')}, "
                                 f"this folder's is {run_id})")
            if validate is not None:
                validate(state, candidate)

        if not periodic_checkpoints(path):  # killed before (or during) its first checkpoint: start it again
            for log in path.glob(MCAP_GLOB):
                log.unlink(missing_ok=True)
            shutil.rmtree(path / "scalars", ignore_errors=True)
            return cls(path, run_id or uuid.uuid4().hex, None, None,
                       ["no periodic checkpoint yet: starting this run again from frame 0"])
        state, chosen, notes = newest_resumable(path, check)
        drop_logs_after(path, state.get(MCAP_KEY))
        notes.append(f"resuming from {chosen.name} ({state['frames']} frames)")
        return cls(path, run_id or state.get("run_id") or uuid.uuid4().hex, state, chosen, notes)

    def release(self) -> None:
        """Drop the lock; a folder this run made and never claimed (refused before it started: no room for a
        checkpoint, a bad part) goes again, so a refusal leaves nothing behind."""
        if self.lock is not None:
            self.lock.release()
            if not self.claimed and self.lock.created_folder:
                self.lock.path.unlink(missing_ok=True)
                try:
                    self.path.rmdir()
                except OSError:  # something else was written there meanwhile: keep it
                    pass


def read_run_id(path: Path) -> str | None:
    """The run id in RUN/run.json; None for a folder written before run identities existed."""
    identity = path / IDENTITY_NAME
    if not identity.is_file():
        return None
    try:
        data = json.loads(identity.read_text())
        return str(data["run_id"])
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise ValueError(f"{str(identity)!r} is damaged; expected the JSON ncbot train writes with a 'run_id'") from None


def finished_report(config: Any, path: str | os.PathLike) -> dict[str, Any] | None:
    """The eval.json of a run that has nothing left to train under `config` (the run's own config, logging aside, with
    its frames, games or game cap reached), else None: `ncbot train --resume` of a finished run shows it instead of
    evaluating and rewriting it again."""
    path = Path(path)
    try:
        report = json.loads((path / "eval.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not _same_run(config, path):  # overrides that change the run: the checks of a real resume apply
        return None
    if not isinstance(report, dict) or not {"frames", "episodes", "first", "second"} <= set(report):
        return None
    if report["frames"] == 0:  # no learning (the uniform choice): its evaluation is the whole run
        return report if config.agent.name == "uniform" else None
    if not (path / "checkpoint.pt").is_file():
        return None
    train = config.train
    if train.max_games is not None and report["episodes"] >= train.max_games:
        return report
    if train.episodes is not None:
        return report if report["episodes"] >= train.episodes else None
    return report if report["frames"] >= config.collector.total_frames else None


def _same_run(config: Any, path: Path) -> bool:
    """Whether `config` is the run's own config.yaml, its logging and budget aside."""
    from ncbot.fileio.yaml_file import read_yaml
    from ncbot.pipelines.config import config_from_dict

    try:
        saved = config_from_dict(read_yaml(path / "config.yaml", "run config", "the config.yaml of a run")).to_dict()
    except (OSError, ValueError):
        return False
    mine = config.to_dict()
    for data in (saved, mine):
        data.pop("logger", None)
        data.get("collector", {}).pop("total_frames", None)
        data.get("train", {}).pop("episodes", None)
        data.get("train", {}).pop("max_games", None)
    return saved == mine
