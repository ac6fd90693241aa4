"""Each run's tries, kept in its own folder (RUN/grid-attempts.json): where a try ran, since when, how it ended.

Why in the run folder: any machine that shares the runs folder reads the same state, whatever backend ran the try
(`ncbot ablate --status`). The process that runs a try (a local pool thread, a Ray task, a Slurm job) writes where it
started (host, node, the `ncbot train` pid) and keeps the file's modification time fresh while the training lives (the
heartbeat, every `HEARTBEAT_S`); the grid's driver writes how the try ended, since a task lost with its node cannot
say it itself.

A stale lock: `ncbot train` holds RUN/.lock with `flock`, which the kernel drops when the process dies, so on a local
disk a dead run never holds its folder. On a shared folder the lock server may keep a lost node's lock until that
node's lease expires (NFSv4: about 90 s), or forever where it does not see the node go. So a held lock is stale when
its holder is the `ncbot train` of this run's last try, ran on another machine (on this one, the kernel holds a flock
only for a live process) and that try's heartbeat stopped `STALE_AFTER_S` ago. A stale lock file is renamed aside
(RUN/.lock.stale-TIME); the next `ncbot train` takes a new one.
"""
from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text

ATTEMPTS_NAME = "grid-attempts.json"
HEARTBEAT_S = 10.0
# several missed heartbeats, and longer than NFS's attribute cache (actimeo: up to 60 s) can make a fresh one look old
STALE_AFTER_S = 150.0


def boot_id() -> str:
    """This machine's boot: its host name and, on Linux, the kernel's boot id (a reboot gives new pids)."""
    try:
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        boot = ""
    return f"{socket.gethostname()}/{boot}"


def read_attempts(run_dir: Path) -> list[dict[str, Any]]:
    """The run's tries, oldest first ([] where none was recorded or the file is unreadable)."""
    try:
        data = json.loads((Path(run_dir) / ATTEMPTS_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    tries = data.get("attempts") if isinstance(data, dict) else None
    return [entry for entry in tries if isinstance(entry, dict)] if isinstance(tries, list) else []


def _write(run_dir: Path, tries: list[dict[str, Any]]) -> None:
    atomic_write_text(json.dumps({"attempts": tries}, indent=1) + "\n", Path(run_dir) / ATTEMPTS_NAME)


def begin_attempt(run_dir: Path, *, backend: str, try_number: int, node: str | None, from_frames: int) -> None:
    """Record a try that starts now in this process (its `ncbot train` pid follows with `set_train_pid`)."""
    tries = read_attempts(run_dir)
    tries.append({"try": try_number, "backend": backend, "host": socket.gethostname(), "boot": boot_id(),
                  "node": node, "worker_pid": os.getpid(), "train_pid": None, "started": time.time(),
                  "from_frames": from_frames, "ended": None, "outcome": "running", "why": ""})
    _write(run_dir, tries)


def set_train_pid(run_dir: Path, pid: int) -> None:
    tries = read_attempts(run_dir)
    if tries and tries[-1].get("outcome") == "running":
        tries[-1]["train_pid"] = pid
        _write(run_dir, tries)


def end_attempt(run_dir: Path, outcome: str, why: str, *, try_number: int, backend: str) -> None:
    """How try ``try_number`` ended; a try lost before it could record its start gets a record of its own."""
    tries = read_attempts(run_dir)
    last = tries[-1] if tries else None
    if last is None or last.get("try") != try_number or last.get("ended") is not None:
        last = {"try": try_number, "backend": backend, "host": None, "node": None, "started": None,
                "from_frames": None}
        tries.append(last)
    last.update(ended=time.time(), outcome=outcome, why=why)
    Path(run_dir).mkdir(parents=True, exist_ok=True)
    _write(run_dir, tries)


def heartbeat(run_dir: Path) -> None:
    """The try is alive: the record's modification time is now."""
    touch(Path(run_dir) / ATTEMPTS_NAME)


def touch(path: Path) -> None:
    """Set a record's modification time to now (a heartbeat)."""
    try:
        os.utime(path)
    except OSError:
        pass  # a shared folder briefly away; the next beat tries again


def heartbeat_age(run_dir: Path) -> float | None:
    try:
        return time.time() - (Path(run_dir) / ATTEMPTS_NAME).stat().st_mtime
    except OSError:
        return None


def stale_lock(run_dir: Path, holder: int, *, stale_after_s: float = STALE_AFTER_S) -> str | None:
    """Why the held RUN/.lock is stale (module doc), or None when its holder may still be training."""
    tries = read_attempts(run_dir)
    last = tries[-1] if tries else None
    if last is None or holder <= 0 or last.get("train_pid") != holder:
        return None  # not held by this grid's last try (an `ncbot train` started by hand, another grid): never broken
    if last.get("boot") == boot_id():
        return None  # the kernel of this machine holds the flock: its holder lives (in this or another pid namespace)
    age = heartbeat_age(run_dir)
    if age is not None and age > stale_after_s:
        where = last.get("node") or last.get("host") or "?"
        return f"its holder, pid {holder} on {where}, sent no heartbeat for {age:.0f} s"
    return None


def break_lock(run_dir: Path) -> Path:
    """Rename a stale RUN/.lock aside; the next `ncbot train` creates and takes a fresh one."""
    from ncbot.pipelines.run_folder import LOCK_NAME

    aside = Path(run_dir) / f"{LOCK_NAME}.stale-{int(time.time())}"
    os.replace(Path(run_dir) / LOCK_NAME, aside)
    return aside
