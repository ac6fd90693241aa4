"""The configs shipped in the package go by name (`ncbot train default`, `ncbot ablate ablation`), a path still
works, and `ncbot configs` lists them or prints one."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ncbot.pipelines.config import load_config, shipped_config, shipped_configs

CONFIGS = Path(__file__).resolve().parents[2] / "pipelines" / "configs"


def _ncbot(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True, cwd=cwd)


def test_every_shipped_yaml_has_a_name_and_names_resolve_outside_a_checkout(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # no pipelines/ folder here
    names = shipped_configs()
    assert set(names) == {p.relative_to(CONFIGS).with_suffix("").as_posix() for p in CONFIGS.rglob("*.yaml")}
    assert {"default", "ultimate", "ablation", "paper/ultimate100_proposed_temporal"} <= set(names)
    assert shipped_config("default") == shipped_config("default.yaml") == CONFIGS / "default.yaml"
    assert shipped_config("pipelines/configs/paper/standard_original.yaml") == CONFIGS / "paper" / "standard_original.yaml"
    assert load_config("ultimate", ["train.seed=3"]) == load_config(CONFIGS / "ultimate.yaml", ["train.seed=3"])


def test_a_local_file_wins_over_a_shipped_name_or_path(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "default").write_text("env:\n  game: ultimate\n")
    assert shipped_config("default") == Path("default")
    assert load_config("default").env.game == "ultimate"
    local = tmp_path / "pipelines" / "configs" / "default.yaml"
    local.parent.mkdir(parents=True)
    local.write_text("agent: {name: dqn_variant}\n")
    assert shipped_config("pipelines/configs/default.yaml") == Path("pipelines/configs/default.yaml")
    assert load_config("pipelines/configs/default.yaml").agent.name == "dqn_variant"
    with pytest.raises(FileNotFoundError, match="nosuch.yaml"):
        load_config("pipelines/configs/nosuch.yaml")


def test_an_unknown_name_lists_the_shipped_ones(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"'defualt' is neither a file nor a shipped config; shipped: ablation, .*default.*ncbot configs"):
        shipped_config("defualt")
    assert shipped_config("missing.yaml") == Path("missing.yaml")  # a file path: the reader's own not-found error


def test_ablate_plans_a_shipped_grid_by_name(tmp_path: Path, monkeypatch) -> None:
    from ncbot.pipelines.grid.plan import plan_runs

    monkeypatch.chdir(tmp_path)
    runs = plan_runs("ablation", seeds=1, runs_dir=tmp_path / "runs")
    assert runs and all(run.config.is_file() and CONFIGS in run.config.parents for run in runs)


def test_ncbot_configs_lists_prints_and_refuses(tmp_path: Path) -> None:
    listed = _ncbot("configs", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    rows = {line.split()[0]: line.split()[1] for line in listed.stdout.splitlines()[1:]}
    assert rows.keys() == shipped_configs().keys()
    assert rows["default"] == "run" and rows["ablation"] == "grid" and rows["screening"] == "grid"
    printed = _ncbot("configs", "paper/standard_original", cwd=tmp_path)
    assert printed.stdout == (CONFIGS / "paper" / "standard_original.yaml").read_text()
    refused = _ncbot("configs", "nope", cwd=tmp_path)
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    assert refused.stderr.startswith("ncbot: error: no shipped config named 'nope'; shipped: ablation")


def test_train_takes_a_name_and_names_its_run_after_it(tmp_path: Path) -> None:
    done = _ncbot("train", "default", "collector.total_frames=1024", "collector.init_random_frames=512", "eval.games=10",
                  "eval.periodic_games=10", "train.eval_every_frames=1024", "--no-log", "--no-progress", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "runs" / "default" / "checkpoint.pt").is_file()


def test_a_reader_that_leaves_early_stops_ncbot_quietly(tmp_path: Path) -> None:
    """`ncbot configs | head -1`: no 'Broken pipe' error line, the exit status of a writer killed by SIGPIPE."""
    process = subprocess.Popen([sys.executable, "-m", "ncbot", "configs"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, cwd=tmp_path)
    process.stdout.close()  # before the child has written anything (it is still importing)
    assert process.wait(timeout=60) == 141
    assert process.stderr.read() == b""


def test_every_shipped_grid_plans_runs_whose_configs_load(tmp_path: Path, monkeypatch) -> None:
    """A grid's suites name configs and overrides that only `ncbot train` would read: a typo there would surface
    hours into a grid. Every run of every shipped grid loads with its overrides now."""
    import yaml

    from ncbot.pipelines.grid.plan import plan_runs

    monkeypatch.chdir(tmp_path)
    grids = [name for name in shipped_configs()
             if "grid" in (yaml.safe_load(shipped_config(name).read_text(encoding="utf-8")) or {})]
    assert {"ablation", "memory_question", "memory_ultimate", "memory_default", "screening"} <= set(grids)
    for grid in grids:
        runs = plan_runs(grid, seeds=1, runs_dir=tmp_path / grid)
        assert runs, grid
        for run in runs:
            config = load_config(run.config, run.overrides)
            assert config.train.seed == 0, run.name
    memory_default = {run.name: load_config(run.config, run.overrides)
                      for run in plan_runs("memory_default", seeds=1, runs_dir=tmp_path / "md")}
    assert {(c.env.game, c.agent.memory, c.env.temporal, c.loss.reward) for c in memory_default.values()} == {
        (game, memory, temporal, "outcome") for game in ("standard", "ultimate") for memory in ("none", "gru")
        for temporal in (False, True)}
