"""`ncbot ablate`: run a grid of training runs in parallel processes (local pool or Ray), skipping finished ones.

Each run is a separate `ncbot train` process (its own torch thread, its own crash domain), so a failing run does
not take the grid down and an interrupted grid resumes: runs with `eval.json` are skipped, runs with periodic
checkpoints but no `eval.json` are continued with `--resume`. Several `ncbot ablate` processes may work on one runs
folder (two terminals, two machines sharing it): just before a run starts, one that another process has finished or
is training (its folder's lock is held) is skipped. `--status` says where every run of the grid stands.
"""
from __future__ import annotations

import itertools
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


GRID_AXES = ("suite", "game", "agent", "temporal", "lookahead")


@dataclass
class PlannedRun:
    """One cell of the grid: where it goes and how `ncbot train` is called for it."""

    name: str
    run_dir: Path
    config: Path
    overrides: list[str] = field(default_factory=list)

    def command(self) -> list[str]:
        if (self.run_dir / "checkpoints").is_dir() and any((self.run_dir / "checkpoints").glob("step-*.pt")):
            return [sys.executable, "-m", "ncbot", "train", "--resume", str(self.run_dir), "--no-progress"]
        return [sys.executable, "-m", "ncbot", "train", str(self.config), *self.overrides,
                "--out", str(self.run_dir), "--no-progress", "--overwrite"]  # no checkpoint yet: start it again

    @property
    def finished(self) -> bool:
        return (self.run_dir / "eval.json").is_file()

    def state(self) -> tuple[str, str]:
        """(where the run stands, a detail): finished (robot-first / robot-second task success), training now (the
        pid holding its folder, its newest checkpoint), stopped (the checkpoint it resumes from) or not started."""
        import json

        from ncbot.pipelines.checkpoint import periodic_checkpoints, periodic_frames
        from ncbot.pipelines.run_folder import lock_holder

        if self.finished:
            try:
                report = json.loads((self.run_dir / "eval.json").read_text(encoding="utf-8"))
                return "finished", (f"task success {report['first']['task_success']:.4f} robot first, "
                                    f"{report['second']['task_success']:.4f} robot second")
            except (OSError, ValueError, KeyError, TypeError):
                return "finished", "eval.json unreadable"
        found = periodic_checkpoints(self.run_dir)  # oldest first
        at = f"checkpoint at {periodic_frames(found[-1]):,} frames" if found else "no checkpoint yet"
        holder = lock_holder(self.run_dir)
        if holder is not None:
            return "training now", f"pid {holder if holder > 0 else '?'}, {at}{self._pace(found)}"
        return ("stopped", f"resumes from the {at}") if found else ("not started", "")

    def _pace(self, found: list[Path]) -> str:
        """", N frames/s, about H:MM:SS left" from the checkpoints the training process wrote (`checkpoint_rate`) and
        the run's collector.total_frames (an estimate: evaluations and a games cap are not foreseen); "" where either
        is missing."""
        from ncbot.pipelines.checkpoint import periodic_frames
        from ncbot.pipelines.progress import duration

        total, every = self._frame_settings()
        if not found or total is None:
            return ""
        if periodic_frames(found[-1]) >= total:
            return ", every frame trained: the final evaluation"
        pace = self._rate_and_left(found, total, every)
        if pace is None:
            return ""
        rate, left = pace
        return f", {rate:,.0f} frames/s, about {duration(left)} left of {total:,} frames"

    def _rate_and_left(self, found: list[Path], total: int, every: int | None) -> tuple[float, float] | None:
        """(frames/s of the process training the run now, seconds it has left), or None before it wrote 2 checkpoints.

        The time since the newest checkpoint counts as progress at that rate, but never past the next checkpoint
        (``every``: checkpoint.every_frames of its config), which would have been written: a run that slowed down or
        was paused is not estimated as done."""
        import time

        from ncbot.pipelines.checkpoint import checkpoint_rate, periodic_frames
        from ncbot.pipelines.run_folder import lock_taken_at

        rate = checkpoint_rate(found, since=lock_taken_at(self.run_dir))
        if rate is None:
            return None
        newest = periodic_frames(found[-1])
        left = (total - newest) / rate - (time.time() - found[-1].stat().st_mtime)
        if every is not None:
            left = max(left, (total - min(total, newest + every)) / rate)
        return rate, max(0.0, left)

    @property
    def cell(self) -> str:
        """The run's grid cell: its name without the seed (seeds of one cell cost about the same)."""
        return self.name.rsplit("/", 1)[0]

    def wall_time(self) -> float | None:
        """A finished run's training wall time (eval.json's train_wall_time_s); None otherwise."""
        import json

        try:
            seconds = json.loads((self.run_dir / "eval.json").read_text(encoding="utf-8"))["train_wall_time_s"]
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return float(seconds) if isinstance(seconds, (int, float)) else None

    def seconds_left(self, typical: float | None) -> float | None:
        """Training time this run still needs: its own pace while it trains, else ``typical`` (a finished seed's of
        its cell) scaled by the frames its checkpoint has left; None where neither is known."""
        from ncbot.pipelines.checkpoint import periodic_checkpoints, periodic_frames
        from ncbot.pipelines.run_folder import lock_holder

        if self.finished:
            return 0.0
        found = periodic_checkpoints(self.run_dir)
        total, every = self._frame_settings() if found else (None, None)
        if found and total:
            done = min(1.0, periodic_frames(found[-1]) / total)
            pace = self._rate_and_left(found, total, every) if lock_holder(self.run_dir) is not None else None
            if pace is not None:
                return pace[1]
            return None if typical is None else typical * (1.0 - done)
        return typical

    def _saved_config(self) -> Any:
        """The config.yaml `ncbot train` wrote into the run folder, as read (one-line errors from `read_yaml`)."""
        from ncbot.fileio.yaml_file import read_yaml

        return read_yaml(self.run_dir / "config.yaml", "run config", "the config.yaml ncbot train wrote")

    def _frame_settings(self) -> tuple[int | None, int | None]:
        """(collector.total_frames, checkpoint.every_frames) of the run's saved config.yaml, read once; each None if
        unreadable or not there."""
        try:
            saved = self._saved_config()
        except (OSError, ValueError):
            return None, None

        def setting(section: str, key: str) -> int | None:
            block = saved.get(section) if isinstance(saved, dict) else None
            value = block.get(key) if isinstance(block, dict) else None
            return value if isinstance(value, int) else None

        every = setting("checkpoint", "every_frames")
        return setting("collector", "total_frames"), every if every is not None and every > 0 else None

    def settings(self) -> tuple[str, int, str]:
        """(name, train.num_threads, train.device) of the run as it will start: its folder's config.yaml when it
        resumes, else its config and overrides (what a Ray task asks for: pipelines/train/ray_backend.py)."""
        from ncbot.pipelines.config import config_from_dict, load_config

        if "--resume" in self.command() and (self.run_dir / "config.yaml").is_file():
            config = config_from_dict(self._saved_config())
        else:
            config = load_config(self.config, self.overrides)
        return self.name, config.train.num_threads, config.train.device


def load_grid(path: str | Path) -> dict[str, Any]:
    """The ablation grid, read through the one safe YAML loader and checked shape by shape (one line each)."""
    from ncbot.fileio.yaml_file import read_yaml
    from ncbot.pipelines.config import shipped_config

    path = shipped_config(path)
    expected = "a YAML mapping with 'suites' and 'grid', e.g. pipelines/configs/ablation.yaml"
    grid = read_yaml(path, "ablation grid", expected)
    if not isinstance(grid, dict):
        raise ValueError(f"ablation grid {str(path)!r} must be {expected}")
    unknown = set(grid) - {"runs_dir", "suites", "grid", "baselines_with_temporal"}
    if unknown:
        raise ValueError(f"unknown key '{sorted(map(str, unknown))[0]}' in ablation grid; allowed: runs_dir, suites, grid, baselines_with_temporal")
    for key in ("suites", "grid"):
        if not isinstance(grid.get(key), dict):
            raise ValueError(f"ablation grid {str(path)!r} needs a '{key}' mapping")
    if not isinstance(grid.get("runs_dir", ""), str):
        raise ValueError(f"ablation grid {str(path)!r}: 'runs_dir' must be a folder name")
    bad_axes = set(grid["grid"]) - set(GRID_AXES)
    if bad_axes:
        raise ValueError(f"unknown grid axis '{sorted(map(str, bad_axes))[0]}'; allowed: {', '.join(GRID_AXES)}")
    for axis, values in grid["grid"].items():
        if not isinstance(values, list) or not values or not all(v is None or isinstance(v, (str, int, float))
                                                                   for v in values):
            raise ValueError(f"grid axis '{axis}' must be a non-empty list of names or flags (e.g. {axis}: [a, b]), got {values!r}")
    for suite, rows in grid["suites"].items():
        if not isinstance(rows, dict):
            raise ValueError(f"suite {suite!r} must map game rows to {{config: FILE, overrides: [...]}}, got {rows!r}")
        for row, entry in rows.items():
            if not isinstance(entry, dict) or not isinstance(entry.get("config"), str):
                raise ValueError(f"suite {suite!r} row {row!r} needs 'config: FILE' (a YAML run config), got {entry!r}")
            overrides = entry.get("overrides", [])
            if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
                raise ValueError(f"suite {suite!r} row {row!r}: 'overrides' must be a list of key=value strings")
    return grid


CELL_KEYS = ("agent.name", "env.temporal", "agent.lookahead", "train.seed")  # what each grid cell sets itself


def plan_runs(grid_path: str | Path, *, seeds: int, runs_dir: str | Path | None = None,
              overrides: list[str] | None = None) -> list[PlannedRun]:
    """Every (suite, game, agent, temporal, look-ahead, seed) cell of the grid, validated before anything runs.

    ``overrides`` (key=value) apply to every run, after its suite's own overrides; the keys a cell sets itself
    (``CELL_KEYS``) are refused, since they would make the cells one run.
    """
    from ncbot.pipelines.config import load_config

    common = list(overrides or [])
    for override in common:
        key = override.partition("=")[0].strip()
        if "=" not in override or not key:
            raise ValueError(f"override {override!r} is not key=value (e.g. optim.lr=0.0005)")
        if key in CELL_KEYS:
            raise ValueError(f"override {override!r} sets {key}, which each grid cell sets itself; change the grid "
                             "file's axes instead")

    from ncbot.pipelines.config import shipped_config

    grid_path = shipped_config(grid_path)
    grid = load_grid(grid_path)
    if not 0 < seeds <= 1000:
        raise ValueError(f"--seeds must be a positive number (at most 1000), got {seeds}")
    runs_dir = Path(runs_dir or grid.get("runs_dir", "runs/ablation"))
    axes = grid["grid"]
    values = {axis: axes.get(axis, [None]) for axis in GRID_AXES}
    planned = []
    for suite, game, agent, temporal, lookahead in itertools.product(*(values[a] for a in GRID_AXES)):
        if not isinstance(suite, str) or suite not in grid["suites"]:
            raise ValueError(f"grid suite {suite!r} is not defined under 'suites' ({', '.join(grid['suites'])})")
        entry = grid["suites"][suite].get(game)
        if entry is None:
            raise ValueError(f"suite {suite!r} has no config for game row {game!r}")
        if agent != "proposed" and temporal and not grid.get("baselines_with_temporal", False):
            continue
        config = (grid_path.parent / entry["config"]).resolve()
        overrides = list(entry.get("overrides", [])) + common + [f"agent.name={agent}", f"env.temporal={str(bool(temporal)).lower()}"]
        if lookahead is not None:
            overrides.append(f"agent.lookahead={lookahead}")
        cell = f"{agent}-{'temporal' if temporal else 'notemporal'}" + (f"-{lookahead}" if lookahead else "")
        for seed in range(seeds):
            load_config(config, overrides + [f"train.seed={seed}"])  # fail early, with the key, before any run starts
            planned.append(PlannedRun(
                name=f"{suite}/{game}/{cell}/seed{seed}", run_dir=runs_dir / suite / game / cell / f"seed{seed}",
                config=config, overrides=overrides + [f"train.seed={seed}"],
            ))
    return planned


class _Children:
    """The `ncbot train` processes the local pool has running, so a stopped grid stops them too.

    Why: the pool's worker threads block in `wait()`; without this, Ctrl-C or SIGTERM on `ncbot ablate` would wait
    for the running trainings and then start every queued one (the executor drains its queue on shutdown).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running: set[subprocess.Popen] = set()
        self.stopping = False

    def start(self, command: list[str], log) -> subprocess.Popen | None:
        with self._lock:
            if self.stopping:
                return None
            child = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
            self._running.add(child)
            return child

    def finished(self, child: subprocess.Popen) -> None:
        with self._lock:
            self._running.discard(child)

    def stop(self, grace_s: float = 60.0) -> None:
        """SIGTERM every running training (each saves nothing half-written and exits 143, resumable), then wait."""
        with self._lock:
            self.stopping = True
            running = list(self._running)
        for child in running:
            child.terminate()
        for child in running:
            try:
                child.wait(timeout=grace_s)
            except subprocess.TimeoutExpired:
                child.kill()


STOPPED = -15  # the code a run reports when the grid was stopped before it started
HELD = -16  # the code of a run another ncbot process is training (its folder's lock is held): skipped, not failed


def _run_local(run: PlannedRun, children: _Children | None = None) -> tuple[str, int]:
    """One `ncbot train` subprocess; its output goes to the run's train.log. ``children``: the local pool's
    registry (a Ray task, alone in its worker, gets its own). A run another process finished or is training since
    the grid was planned is not started (0, or ``HELD``)."""
    from ncbot.pipelines.run_folder import lock_holder

    children = children if children is not None else _Children()
    if run.finished:
        return run.name, 0
    if lock_holder(run.run_dir) is not None:
        return run.name, HELD
    run.run_dir.mkdir(parents=True, exist_ok=True)
    with open(run.run_dir / "train.log", "a") as log:
        child = children.start(run.command(), log)
        if child is None:
            return run.name, STOPPED
        try:
            code = child.wait()
        finally:
            children.finished(child)
    return run.name, code


def check_backend(backend: str, workers: int, address: str | None = None) -> None:
    """One-line ValueError for a backend, worker count or address that cannot run (before anything is planned)."""
    from ncbot.pipelines.extras import require

    if backend not in ("local", "ray"):
        raise ValueError(f"unknown backend {backend!r}; expected 'local' or 'ray'")
    if address is not None and backend != "ray":
        raise ValueError(f"--address {address} needs --backend ray (it is the Ray cluster's HOST:PORT)")
    if backend == "ray":
        require("ray", "ray", what="--backend ray")
    if not 0 < workers <= 256:
        raise ValueError(f"--workers must be a positive number of parallel runs (at most 256), got {workers}")


def execute_runs(todo: list[PlannedRun], *, workers: int, backend: str = "local", address: str | None = None,
                 runs_dir: str | Path | None = None, desc: str = "ablate", gpus_per_run: float = 1.0,
                 held: list[str] | None = None) -> list[str]:
    """Run the planned runs, ``workers`` at a time, in local processes or as Ray tasks; returns the failed runs' names
    (and appends to ``held`` the runs skipped because another process is training them).

    Ray (pipelines/train/ray_backend.py): ``address`` None starts a local instance, else joins the cluster at HOST:PORT;
    every node must see ``runs_dir`` at the same absolute path (checked before any run starts). Each Ray task asks for
    its run's `train.num_threads` CPUs and, when it runs on CUDA, ``gpus_per_run`` GPUs (a fraction shares one).
    """
    from ncbot.pipelines.progress import progress_bar
    from ncbot.pipelines.train.ray_backend import run_on_ray

    check_backend(backend, workers, address)
    failed: list[str] = []
    bar = progress_bar(total=len(todo), unit="run", desc=desc)

    def done(name: str, code: int) -> None:
        if code == HELD:
            if held is not None:
                held.append(name)
        elif code != 0:
            failed.append(name)
        bar.update(1)

    if backend == "local":
        children = _Children()
        pool = ThreadPoolExecutor(max_workers=workers)
        try:
            for future in as_completed([pool.submit(_run_local, run, children) for run in todo]):
                done(*future.result())
        except BaseException:  # Ctrl-C, SIGTERM (pipelines.errors.Terminated), a bug: stop, leave runs resumable
            pool.shutdown(wait=False, cancel_futures=True)
            children.stop()
            raise
        pool.shutdown()
    elif todo:
        root = Path(runs_dir or todo[0].run_dir.parent).resolve()
        absolute = [PlannedRun(run.name, run.run_dir.resolve(), run.config.resolve(), list(run.overrides)) for run in todo]
        outside = [run.name for run in absolute if root not in run.run_dir.parents]
        if outside:
            raise ValueError(f"run {outside[0]} is not under the runs folder {root} that the Ray nodes share")
        run_on_ray(absolute, _run_local, workers=workers, address=address, runs_dir=root, on_done=done,
                   settings=PlannedRun.settings, gpus_per_run=gpus_per_run)
    bar.close()
    return failed


def planned_runs(grid_path: str | Path, *, seeds: int, out: str | Path | None = None, only: str | None = None,
                 overrides: list[str] | None = None) -> list[PlannedRun]:
    """The grid's runs (``plan_runs``), kept to those whose name holds ``only``; a filter that keeps none is a
    ValueError naming a few runs."""
    planned = plan_runs(grid_path, seeds=seeds, runs_dir=out, overrides=overrides)
    if only is not None:
        kept = [run for run in planned if only in run.name]
        if not kept:
            examples = ", ".join(run.name for run in planned[:3]) + (", ..." if len(planned) > 3 else "")
            raise ValueError(f"--only {only!r} matches none of the {len(planned)} runs of the grid (e.g. {examples})")
        planned = kept
    return planned


def grid_status(grid_path: str | Path, *, seeds: int = 3, out: str | Path | None = None, only: str | None = None,
                overrides: list[str] | None = None) -> tuple[list[tuple[str, str, str]], TimeLeft]:
    """(run name, where it stands, a detail) for every run of the grid (``PlannedRun.state``), and the training time
    left (``grid_time_left``); nothing starts."""
    runs = planned_runs(grid_path, seeds=seeds, out=out, only=only, overrides=overrides)
    return [(run.name, *run.state()) for run in runs], grid_time_left(runs)


@dataclass(frozen=True)
class TimeLeft:
    """The grid's training time still to run, summed over its runs (``PlannedRun.seconds_left``)."""

    seconds: float  # over the runs with an estimate
    estimated: int  # unfinished runs with an estimate
    unknown: int  # unfinished runs whose cell has no finished seed yet (and no pace of their own)


def grid_time_left(runs: list[PlannedRun]) -> TimeLeft:
    """What is left of the grid, in training time: each unfinished run at its own pace, or at the median training
    time of its cell's finished seeds. Seeds of one cell cost about the same; a shared machine's load does not."""
    import statistics

    typical: dict[str, list[float]] = {}
    for run in runs:
        if (seconds := run.wall_time()) is not None:
            typical.setdefault(run.cell, []).append(seconds)
    medians = {cell: statistics.median(times) for cell, times in typical.items()}
    seconds, estimated, unknown = 0.0, 0, 0
    for run in runs:
        if run.finished:
            continue
        left = run.seconds_left(medians.get(run.cell))
        if left is None:
            unknown += 1
        else:
            seconds, estimated = seconds + left, estimated + 1
    return TimeLeft(seconds, estimated, unknown)


def run_ablation(grid_path: str | Path, *, seeds: int = 3, workers: int = 2, backend: str = "local",
                 out: str | Path | None = None, only: str | None = None, address: str | None = None,
                 overrides: list[str] | None = None, gpus_per_run: float = 1.0) -> dict[str, Any]:
    """Run every unfinished cell of the grid with `workers` in parallel; returns counts and the runs folder.

    ``only``: keep the runs whose name holds this text (``planned_runs``). ``overrides``: key=value applied to every
    run (``plan_runs``). A run another process is training is skipped and counted as held."""
    check_backend(backend, workers, address)
    planned = planned_runs(grid_path, seeds=seeds, out=out, only=only, overrides=overrides)
    todo = [run for run in planned if not run.finished]
    runs_dir = Path(out) if out else Path(load_grid(grid_path).get("runs_dir", "runs/ablation"))
    held: list[str] = []
    failed = execute_runs(todo, workers=workers, backend=backend, address=address, runs_dir=runs_dir,
                          gpus_per_run=gpus_per_run, held=held)
    return {"done": len(todo) - len(failed) - len(held), "skipped": len(planned) - len(todo), "held": len(held),
            "failed": len(failed), "failed_runs": failed, "runs_dir": str(runs_dir)}
