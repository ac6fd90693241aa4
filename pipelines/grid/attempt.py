"""One try of one planned run, wherever it executes (a local pool thread, a Ray task, a Slurm job).

A try: skip a run another process finished; wait for, or break, a lock its own dying predecessor left
(pipelines/grid/attempts.py); record where it starts; run `ncbot train` tied to this process's life
(pipelines/grid/tether.py) with its output appended to RUN/train.log; beat the heartbeat while it trains; and say how
it ended as an `Outcome`: finished, died (killed by a signal: retried by the grid), failed (ncbot's own error: the
same on a retry, so not retried), held (another process trains it) or stopped (the grid was stopping).
"""
from __future__ import annotations

import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from ncbot.pipelines.grid import attempts

# a retry waits this long for the lock of its predecessor's `ncbot train` (killed with its parent: the kernel drops
# the lock at once on a local disk; a shared folder's lock server may take its lease time) before calling it held
LOCK_WAIT_S = attempts.STALE_AFTER_S + 30.0
IN_USE = "is in use by another ncbot train"  # RunLock's refusal, when a writer took the folder after our probe


@dataclass(frozen=True)
class Outcome:
    """How one try of a run ended (module doc)."""

    name: str
    kind: str  # finished | died | failed | held | stopped
    why: str = ""


class Children:
    """The `ncbot train` processes this process has running, so a stopped grid stops them too.

    Why: the local pool's threads block waiting for their child; without this, Ctrl-C or SIGTERM on `ncbot ablate`
    would wait for the running trainings and then start every queued one (an executor drains its queue on shutdown).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running: set[subprocess.Popen] = set()
        self.stopping = False

    def start(self, command: list[str], log: IO[Any]) -> subprocess.Popen | None:
        from ncbot.pipelines.grid.tether import tethered

        with self._lock:
            if self.stopping:
                return None
            child = subprocess.Popen(tethered(command), stdout=log, stderr=subprocess.STDOUT)
            self._running.add(child)
            return child

    def finished(self, child: subprocess.Popen) -> None:
        with self._lock:
            self._running.discard(child)

    def stop(self, grace_s: float = 60.0) -> None:
        """SIGTERM every running training (each saves nothing half-written and exits 143, resumable), then wait
        (polling: a signal handler may call this while the waiting thread holds the child's wait lock)."""
        with self._lock:
            self.stopping = True
            running = list(self._running)
        for child in running:
            child.terminate()
        deadline = time.monotonic() + grace_s
        while any(child.poll() is None for child in running) and time.monotonic() < deadline:
            time.sleep(0.2)
        for child in running:
            if child.poll() is None:
                child.kill()


def exit_outcome(name: str, code: int, run_dir: Path) -> Outcome:
    """The outcome of an `ncbot train` that exited with ``code`` (Popen's: negative for a signal)."""
    if code == 0:
        if (run_dir / "eval.json").is_file():
            return Outcome(name, "finished")
        return Outcome(name, "failed", "ncbot train exited 0 without writing eval.json")
    signals = {130: signal.SIGINT, 137: signal.SIGKILL, 143: signal.SIGTERM}
    if code < 0 or code in signals:
        number = -code if code < 0 else signals[code]
        try:
            label = signal.Signals(number).name
        except ValueError:
            label = f"signal {number}"
        return Outcome(name, "died", f"ncbot train killed by {label}")
    last = last_line(run_dir / "train.log")
    if IN_USE in last:
        return Outcome(name, "held", last)
    return Outcome(name, "failed", f"ncbot train exited {code}: {last}" if last else f"ncbot train exited {code}")


def last_line(log: Path, limit: int = 300) -> str:
    """The last non-empty line of a log (its error line, for an `ncbot train` that stopped), capped."""
    try:
        with open(log, "rb") as handle:
            handle.seek(0, 2)
            handle.seek(max(0, handle.tell() - 8192))
            lines = [line.strip() for line in handle.read().decode("utf-8", "replace").splitlines() if line.strip()]
    except OSError:
        return ""
    return lines[-1][:limit] if lines else ""


def claim(run: Any, *, retry: bool, lock_wait_s: float = LOCK_WAIT_S) -> Outcome | None:
    """None when the run may start here; else why not: finished meanwhile, or held by a live process.

    A retry waits for its predecessor's lock (module doc of attempts: killed with its parent, it goes at once on a
    local disk) and breaks it once stale; a first try never waits."""
    from ncbot.pipelines.run_folder import lock_holder

    deadline = time.monotonic() + (lock_wait_s if retry else 0.0)
    while True:
        if run.finished:
            return Outcome(run.name, "finished", "finished by another process")
        holder = lock_holder(run.run_dir)
        if holder is None:
            return None
        stale = attempts.stale_lock(run.run_dir, holder)
        if stale is not None:
            aside = attempts.break_lock(run.run_dir)
            with open(run.run_dir / "train.log", "a") as log:
                log.write(f"ncbot grid: the run folder's lock was stale ({stale}); moved to {aside.name}\n")
            return None
        if time.monotonic() >= deadline:
            return Outcome(run.name, "held", f"another ncbot train (pid {holder}) holds its folder")
        time.sleep(1.0)


def run_attempt(run: Any, *, backend: str, try_number: int = 1, node: str | None = None,
                children: Children | None = None) -> Outcome:
    """One try of ``run`` (a `PlannedRun`) in this process (module doc); ``children``: the local pool's registry (a
    Ray task or a Slurm job, alone in its process, gets its own)."""
    from ncbot.pipelines.checkpoint import periodic_checkpoints, periodic_frames

    children = children if children is not None else Children()
    refused = claim(run, retry=try_number > 1)
    if refused is not None:
        return refused
    run.run_dir.mkdir(parents=True, exist_ok=True)
    found = periodic_checkpoints(run.run_dir)
    attempts.begin_attempt(run.run_dir, backend=backend, try_number=try_number, node=node,
                           from_frames=periodic_frames(found[-1]) if found else 0)
    with open(run.run_dir / "train.log", "a") as log:
        log.write(f"ncbot grid: try {try_number} of {run.name} ({backend}"
                  f"{', node ' + node if node else ''}) at {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
        log.flush()
        child = children.start(run.command(), log)
        if child is None:
            return Outcome(run.name, "stopped", "the grid was stopping")
        attempts.set_train_pid(run.run_dir, child.pid)
        try:
            code = _wait_with_heartbeat(child, run.run_dir)
        finally:
            children.finished(child)
    return exit_outcome(run.name, code, run.run_dir)


def _wait_with_heartbeat(child: subprocess.Popen, run_dir: Path) -> int:
    """Wait for the training, beating the try's heartbeat; polling, so a signal handler (a Slurm job's checkpoint)
    may stop the child meanwhile."""
    beat = time.monotonic()
    while (code := child.poll()) is None:
        time.sleep(0.5)
        if time.monotonic() - beat >= attempts.HEARTBEAT_S:
            attempts.heartbeat(run_dir)
            beat = time.monotonic()
    return code
