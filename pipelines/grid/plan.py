"""The grid planner of `ncbot ablate` / `ncbot reproduce`: every cell of a grid file as a `PlannedRun`.

A planned run is a folder and the `ncbot train` command that fills it: a fresh run (`--overwrite`, nothing worth
keeping is there yet) or, once the folder holds a periodic checkpoint, `--resume` from it. So a run interrupted
anywhere (Ctrl-C, a killed process, a lost node) is continued by running its command again, whatever backend runs it
(pipelines/grid/runner.py). Planning validates every run's config before anything starts.
"""
from __future__ import annotations

import itertools
import sys
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

    def _saved_config(self) -> Any:
        """The config.yaml `ncbot train` wrote into the run folder, as read (one-line errors from `read_yaml`)."""
        from ncbot.fileio.yaml_file import read_yaml

        return read_yaml(self.run_dir / "config.yaml", "run config", "the config.yaml ncbot train wrote")

    def frame_settings(self) -> tuple[int | None, int | None]:
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
        resumes, else its config and overrides (what a Ray task or a Slurm job asks for)."""
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


def grid_runs_dir(grid_path: str | Path, out: str | Path | None) -> Path:
    """The grid's runs folder: ``out``, else the grid file's runs_dir, else runs/ablation."""
    return Path(out) if out else Path(load_grid(grid_path).get("runs_dir", "runs/ablation"))
