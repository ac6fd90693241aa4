"""The remaining gaps' queue (pipelines/reproduce/gaps.py): the planned runs load as configs with new seeds, and the
queue trains, evaluates, skips what is done and reports its state, on real tiny `ncbot train` / `ncbot eval` runs."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from ncbot.pipelines.config import load_config
from ncbot.pipelines.reproduce import gaps
from ncbot.pipelines.reproduce.gaps_plan import ActsEval, CheckpointEval, GapRun, plan

PUBLISHED_SEEDS = set(range(12))  # results/ holds seeds 0-11 (the 3x3 temporal question's 12 the most)


def test_every_planned_run_is_a_valid_config_with_a_new_seed() -> None:
    runs = plan()
    assert len({run.name for run in runs}) == len(runs) == 31
    for run in runs:
        config = load_config(run.config, [*run.overrides, f"train.seed={run.seed}"])
        assert run.seed not in PUBLISHED_SEEDS
        assert (config.agent.name == "proposed") == run.cell.startswith("proposed")
        assert config.env.temporal == run.cell.endswith("-temporal")
    offered = [run for run in runs if run.question == "offered"]
    assert len(offered) == 5 and all(load_config(run.config, list(run.overrides)).env.taken_squares == "offered"
                                      for run in offered)
    long = [run for run in runs if run.question == "steps800k"]
    assert len(long) == 6 and all(load_config(run.config, list(run.overrides)).collector.total_frames == 800_000
                                  for run in long)
    commands = [command for command, _ in gaps.evaluation_jobs(long[0], Path("runs") / long[0].name)]
    at_400k = [command for command in commands if "step-000400000.pt" in command[4]]
    assert [command[command.index("--first") + 1] for command in at_400k[:2]] == ["robot", "human"]


TINY = ("collector.total_frames=256", "collector.init_random_frames=64", "collector.annealing_frames=128",
        "train.eval_every_frames=128", "eval.games=20", "eval.periodic_games=10", "checkpoint.every_frames=128",
        "checkpoint.keep=8", "logger.mcap=false", "train.max_games=20000")


def test_the_queue_trains_evaluates_skips_and_reports(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    tiny = GapRun("offered", "standard", "dqn_original-notemporal", 60, TINY + ("env.taken_squares=offered",),
                  (CheckpointEval(), ActsEval()))
    monkeypatch.setattr(gaps, "plan", lambda: [tiny])
    monkeypatch.setattr(gaps, "CHECKPOINT_GAMES", 30)
    monkeypatch.setattr(gaps, "ACTS_GAMES", 10)
    assert gaps.queue_status(tmp_path) == [f"{tiny.name}: not started; evaluations 0/1"]
    assert gaps.run_queue(tmp_path) == 0
    folder = tiny.folder(tmp_path)
    saved = json.loads((folder / "eval.json").read_text())
    assert saved["frames"] == 256 and saved["seed"] == 60
    written = sorted(path.name for path in (folder / "checkpoint_evals").iterdir())
    assert written == ["step-000000128-first.json", "step-000000256-first.json"]
    at_end = json.loads((folder / "checkpoint_evals" / "step-000000256-first.json").read_text())
    assert at_end["games"] == 30 and "--seed 2000066" in at_end["command"]  # the final evaluation's seed
    assert json.loads((folder / "acts" / "metrics.json").read_text())["games"] == 10
    assert list((folder / "acts").glob("episodes-*.mcap"))
    assert gaps.queue_status(tmp_path) == [f"{tiny.name}: trained; evaluations 3/3"]
    stamps = {path: path.stat().st_mtime_ns for path in folder.rglob("*.json")}
    assert gaps.run_queue(tmp_path) == 0  # everything done: nothing runs again
    assert stamps == {path: path.stat().st_mtime_ns for path in folder.rglob("*.json")}
