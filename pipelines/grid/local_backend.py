"""`--backend local`: the grid's runs as `ncbot train` processes of this machine, ``workers`` at a time.

Each run is its own process (its own torch threads, its own crash domain): a failing run does not take the grid down.
A try that died is queued again (the ledger decides, pipelines/grid/runner.py) and resumes from its last checkpoint.
Ctrl-C or SIGTERM on the grid stops every running training (each exits resumable) and starts no queued one.
"""
from __future__ import annotations

from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from typing import Any

from ncbot.pipelines.grid.attempt import Children, Outcome, run_attempt


def run_local(todo: list[Any], ledger: Any) -> None:
    """Run every planned run through ``ledger`` (its next_try / settle), ``ledger.cluster.workers`` at a time."""
    children = Children()
    pool = ThreadPoolExecutor(max_workers=ledger.cluster.workers)
    waiting = list(todo)
    pending: dict[Future, Any] = {}

    def submit(run: Any) -> None:
        number = ledger.next_try(run)
        pending[pool.submit(run_attempt, run, backend="local", try_number=number, children=children)] = run

    try:
        while waiting or pending:
            while waiting and len(pending) < ledger.cluster.workers:
                submit(waiting.pop(0))
            done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            for future in done:
                run = pending.pop(future)
                try:
                    outcome = future.result()
                except OSError as error:  # the run folder cannot be written (a full or lost disk): not retried
                    outcome = Outcome(run.name, "failed", f"cannot run it: {error}")
                if ledger.settle(run, outcome):
                    waiting.insert(0, run)  # its retry goes first: it resumes from a checkpoint
    except BaseException:  # Ctrl-C, SIGTERM (pipelines.errors.Terminated), a bug: stop, leave runs resumable
        pool.shutdown(wait=False, cancel_futures=True)
        children.stop()
        raise
    pool.shutdown()
