"""`ncbot ablate --status` reads a grid's state from the runs folder alone: the tries each run took and why the
earlier ones died, a failed run with its error, runs queued while a grid drives them, the driver; `--json` holds
the same facts in one object."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from ncbot.pipelines.grid import attempts
from ncbot.pipelines.grid.plan import plan_runs
from ncbot.pipelines.grid.runner import DRIVER_NAME
from ncbot.pipelines.grid.status import grid_status, status_lines
from tests.grid.test_retries import grid
from tests.learning_helpers import ncbot


def test_status_names_tries_failures_queued_runs_and_the_driver(tmp_path: Path) -> None:
    path = grid(tmp_path)
    retried, failed = plan_runs(path, seeds=2)
    for run in (retried, failed):
        run.run_dir.mkdir(parents=True)
    attempts.begin_attempt(retried.run_dir, backend="ray", try_number=1, node="3bd618a1d084", from_frames=0)
    attempts.end_attempt(retried.run_dir, "died", "its Ray node was lost (NodeDiedError)", try_number=1,
                         backend="ray")
    (retried.run_dir / "eval.json").write_text(json.dumps({"first": {"task_success": 0.99},
                                                           "second": {"task_success": 0.9}}))
    attempts.end_attempt(failed.run_dir, "failed", "ncbot train exited 2: ncbot: error: disk full", try_number=1,
                         backend="slurm")
    (tmp_path / "runs" / DRIVER_NAME).write_text(json.dumps(
        {"host": "head-1", "pid": 812, "backend": "ray", "workers": 4, "retries": 3, "runs": 2,
         "started": time.time(), "ended": None}))
    statuses, left, record = grid_status(path, seeds=2)
    assert [(s.state, s.tries, s.died) for s in statuses] == [
        ("finished", 1, ("its Ray node was lost (NodeDiedError)",)),
        ("failed", 1, ())]
    assert statuses[1].detail == "ncbot train exited 2: ncbot: error: disk full"
    assert record["alive"] and record["backend"] == "ray"
    lines = status_lines(statuses, left, record, workers=4)
    assert lines[0].endswith("[try 1; died before: its Ray node was lost (NodeDiedError)]")
    assert lines[2] == "2 runs: 1 finished, 1 failed; 1 retried (1 try died)"
    assert lines[3].startswith("grid driver: pid 812 on head-1, backend ray, 4 workers, --retries 3: running")

    (failed.run_dir / attempts.ATTEMPTS_NAME).unlink()  # no failed try: waiting its turn while the driver lives
    assert grid_status(path, seeds=2)[0][1].state == "queued"
    old = time.time() - 3600
    os.utime(tmp_path / "runs" / DRIVER_NAME, (old, old))  # the driver went silent: nothing is queued any more
    statuses, _, record = grid_status(path, seeds=2)
    assert statuses[1].state == "not started" and not record["alive"]

    result = ncbot("ablate", str(path), "--seeds", "2", "--status", "--json")
    assert result.returncode == 0, result.stderr
    status = json.loads(result.stdout)  # stdout is exactly one JSON object
    assert status["counts"] == {"finished": 1, "not started": 1} and status["retried"] == [retried.name]
    assert status["runs"][0]["died"] == ["its Ray node was lost (NodeDiedError)"]
