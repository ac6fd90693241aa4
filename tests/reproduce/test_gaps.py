"""The remaining gaps' queue (pipelines/reproduce/gaps.py): the planned runs load as configs with new seeds, and the
queue trains, evaluates, skips what is done and reports its state, on real tiny `ncbot train` / `ncbot eval` runs."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from ncbot.pipelines.config import load_config
from ncbot.pipelines.reproduce import gaps
from ncbot.pipelines.reproduce.gaps_plan import ActsEval, CheckpointEval, GapRun, plan
from ncbot.pipelines.reproduce import gaps_report
from ncbot.pipelines.reproduce.gaps_report import write_gaps_report

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
    tiny = GapRun("compact", "standard", "dqn_original-notemporal", 60, TINY + ("env.dialogues=compact",),
                  (CheckpointEval(), ActsEval()))  # the whole of question (c) here
    monkeypatch.setattr(gaps, "plan", lambda: [tiny])
    monkeypatch.setattr(gaps_report, "plan", lambda: [tiny])
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
    written = write_gaps_report(tmp_path, tmp_path / "results")  # (c) finished reads the logged run; (b) has no run
    report = written[0].read_text()
    sources, lengths = report.split("## (b)")[1].split("## (c)")
    assert tiny.name not in sources and f"| {tiny.name} | " in lengths
    assert "no test's runs are all finished" in report and "(c) 1 of 1" in report
    stamps = {path: path.stat().st_mtime_ns for path in folder.rglob("*.json")}
    assert gaps.run_queue(tmp_path) == 0  # everything done: nothing runs again
    assert stamps == {path: path.stat().st_mtime_ns for path in folder.rglob("*.json")}


def _write_eval(folder: Path, success: float, reward: float = 0.5, length: float = 14.0) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    seat = {"task_success": success, "avg_reward": reward, "avg_length": length, "truncated": 0.0, "games": 3000}
    (folder / "eval.json").write_text(json.dumps({"first": seat, "second": seat, "frames": 1}))


def test_the_report_runs_the_tests_fixed_in_the_plan(tmp_path: Path) -> None:
    """Every A/D/E run finished with known numbers: the verdicts are the plan's Welch tests against the shipped CSVs."""
    from scipy.stats import ttest_ind

    from ncbot.pipelines.reproduce.gaps_report import LATE_CHECKPOINTS, family, published, Runs

    values = {}
    for index, run in enumerate(plan()):
        if run.question in ("steps800k", "offered") or run.row == "ultimate150":
            base = {"steps800k": 0.95, "offered": 0.85}.get(run.question, 0.90)
            values[run.name] = base + 0.004 * (index % 5) - (0.02 if run.cell == "proposed-notemporal" else 0.0)
            _write_eval(run.folder(tmp_path), values[run.name])
            evals = run.folder(tmp_path) / "checkpoint_evals"
            evals.mkdir()
            for frames in (*LATE_CHECKPOINTS, 400_000):
                (evals / f"step-{frames:09d}-first.json").write_text(json.dumps({"task_success": values[run.name] - 0.01}))
    tests, notes = family(Runs(tmp_path))
    assert [test["test"][:2] for test in tests] == ["A1", "D1", "E1", "E2"]
    long = [values[f"steps800k/ultimate100/proposed-temporal/seed{seed}"] for seed in range(20, 26)]
    expected = ttest_ind(long, published("ultimate100", "proposed-temporal"), equal_var=False, alternative="greater")
    assert tests[0]["p"] == pytest.approx(expected.pvalue) and tests[0]["verdict"] == "shown"
    assert tests[1]["verdict"] == "shown" and tests[1]["means"][1] == pytest.approx(0.858)  # offered below 0.9681
    assert tests[2]["n"] == (10, 10) and tests[2]["alpha"] == 0.0304
    assert all(test["holm_p"] >= test["p"] for test in tests)
    for run in plan():  # one run of (a) missing: A1 is not read, and Holm's p waits for the whole family
        if run.question == "steps800k":
            (run.folder(tmp_path) / "eval.json").unlink()
            break
    tests, _ = family(Runs(tmp_path))
    assert [test["test"][:2] for test in tests] == ["D1", "E1", "E2"] and {test["holm_p"] for test in tests} == {None}
    assert notes["A: paired 800K - 400K, same seeds"] == pytest.approx([0.01] * 6)
    assert notes["D: the paper's 0.8258 inside one new run"][1] in ("yes", "no")
    assert notes["E3: mean within-run SD of the late checkpoints"] == 0.0  # every late checkpoint the same here


def test_an_unfinished_question_is_not_read(tmp_path: Path) -> None:
    from ncbot.pipelines.reproduce.gaps_report import Runs, family

    first = next(run for run in plan() if run.question == "offered")
    _write_eval(first.folder(tmp_path), 0.5)  # one of five runs
    assert family(Runs(tmp_path)) == ([], {})
