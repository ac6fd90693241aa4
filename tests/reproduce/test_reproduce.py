"""`ncbot reproduce` on a tiny real budget: the grid runs through `ncbot ablate`'s runner, finished runs are
skipped, and the table, claims and data-budget files are written and labelled with the budget."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from ncbot.pipelines.grid.runner import Cluster
from ncbot.pipelines.reproduce.grid import BUDGETS, Budget, reproduce, row_config, write_grid
from ncbot.pipelines.reproduce.dialogues import filter_agreement, plan_dialogue_runs
from tests.learning_helpers import ncbot, write_paper_configs

TINY = Budget(name="tiny", seeds=1, rows=("standard",), max_games={"standard": 4}, eval_games=20,
              eval_every_frames={"standard": 64}, game_points=(2, 4), label="TINY BUDGET (test)",
              dialogue_subsets=2, dialogue_games=4, dialogue_points=(2,))


def test_reproduce_runs_the_grid_once_and_writes_labelled_reports(tmp_path: Path) -> None:
    configs, out, runs = write_paper_configs(tmp_path, 256), tmp_path / "results", tmp_path / "runs"
    result = reproduce("all", TINY, out=out, runs=runs, cluster=Cluster(workers=2), command="ncbot reproduce all --budget tiny",
                       configs=configs)
    assert (result["runs"]["done"], result["runs"]["failed"]) == (5, 0), result["runs"]
    for name in ("paper_table.md", "paper_claims.md", "data_budget.md"):
        text = (out / name).read_text()
        assert "TINY BUDGET (test)" in text and "ncbot reproduce all --budget tiny" in text, name
    assert (out / "data_budget_games.png").stat().st_size > 0 and (out / "data_budget_dialogues.png").stat().st_size > 0
    table = (out / "paper_table.md").read_text()
    assert "| 3x3 (32, 32) | DQN-Original | paper | 1 |" in table  # labelled by the runs' own hidden widths
    assert "| 3x3 | Uniform in the masks (no learning) | paper | 1 | 0 |" in table  # no network, no frames
    budget = result["budget_report"]
    assert {r["dialogues"] for r in budget["dialogues"]} == {1, 2, 4, 8, 12, 24}
    # the dialogue-budget agents: 2 subsets at k = 2, their test games read back per k (3x3 only)
    assert (result["dialogue_runs"]["done"], result["dialogue_runs"]["failed"]) == (2, 0), result["dialogue_runs"]
    trained = {r["dialogues"]: r for r in budget["dialogues"] if r["game"] == "standard" and r["task_success"] is not None}
    assert set(trained) == {2} and trained[2]["runs"] == 2 and trained[2]["avg_length"] > 5
    assert 0 <= trained[2]["task_success"] <= 1 and len(trained[2]["task_success_ci95"]) == 2
    config = yaml.safe_load((runs / "dialogues-tiny" / "k02" / "seed1" / "config.yaml").read_text())
    assert config["env"]["dialogue_subset"] == {"k": 2, "seed": 1} and config["train"]["seed"] == 1
    assert "| standard | 24 | 1 |" in (out / "data_budget.md").read_text()
    assert {r["games"] for r in budget["games"]} == {2, 4} and len({r["agent"] for r in budget["games"]}) == 4
    assert budget["vision"] == [] and "no vision points" in budget["vision_note"]
    for run in (runs / "tiny").glob("paper/standard/*/seed0"):
        saved = json.loads((run / "eval.json").read_text())
        if run.parent.name.startswith("uniform"):
            assert saved["frames"] == 0 and saved["first"]["games"] == 20
            continue
        # the budget's games cap or the config's frames, whichever first; the budget's test games
        assert (saved["episodes"] >= 4 or saved["frames"] >= 256) and saved["frames"] <= 256 + 64
        assert saved["first"]["games"] == 20
    again = reproduce("budget", TINY, out=out, runs=runs, cluster=Cluster(workers=1), configs=configs)
    assert (again["runs"]["done"], again["runs"]["skipped"]) == (0, 5)  # resumable: finished runs skipped
    assert (again["dialogue_runs"]["done"], again["dialogue_runs"]["skipped"]) == (0, 2)
    # --report-only: no run starts; all 5 of the budget's runs are done, so the table is not PARTIAL
    report = reproduce("table", TINY, out=tmp_path / "report", runs=runs, report_only=True)
    assert "runs" not in report and (report["table"]["finished_runs"], report["table"]["planned_runs"]) == (5, 5)
    assert "PARTIAL" not in (tmp_path / "report" / "paper_table.md").read_text()
    # one run's result gone (as if still training): PARTIAL, counted, and still no run starts
    (runs / "tiny" / "paper" / "standard" / "proposed-temporal" / "seed0" / "eval.json").unlink()
    partial = reproduce("table", TINY, out=tmp_path / "partial", runs=runs, report_only=True)
    assert (partial["table"]["finished_runs"], partial["table"]["planned_runs"]) == (4, 5)
    for name in ("paper_table.md", "paper_claims.md"):
        text = (tmp_path / "partial" / name).read_text()
        assert "TINY BUDGET (test)" in text and "PARTIAL: 4 of the budget's 5 runs finished" in text, name
    assert not (runs / "tiny" / "paper" / "standard" / "proposed-temporal" / "seed0" / "eval.json").exists()


def test_grid_applies_the_budget_to_the_paper_configs(tmp_path: Path) -> None:
    grid = yaml.safe_load(write_grid(BUDGETS["quick"], tmp_path).read_text())
    cell = grid["suites"]["paper"]["standard"]
    assert cell["config"].endswith("paper/standard_proposed_temporal.yaml")
    assert "train.max_games=2000" in cell["overrides"] and "eval.games=500" in cell["overrides"]
    assert set(grid["suites"]["paper"]) == {"standard", "ultimate100"}
    full = yaml.safe_load(write_grid(BUDGETS["full"], tmp_path / "full").read_text())
    assert set(full["suites"]["paper"]) == {"standard", "ultimate100", "ultimate150"}
    assert "train.max_games=20000" in full["suites"]["paper"]["ultimate150"]["overrides"]


def test_dialogue_runs_cover_every_k_with_the_paper_config(tmp_path: Path) -> None:
    runs = plan_dialogue_runs(BUDGETS["full"], tmp_path, row_config("standard"))
    assert len(runs) == 6 * 5 and runs[-1].run_dir == tmp_path / "k24" / "seed4"
    assert runs[0].config.name == "standard_proposed_temporal.yaml"
    assert {"env.dialogue_subset.k=24", "env.dialogue_subset.seed=4", "train.seed=4", "train.max_games=5000",
            "env.dialogues=paper", "agent.name=proposed"} <= set(runs[-1].overrides)


def test_filter_agreement_is_one_with_every_dialogue_and_less_with_one() -> None:
    assert filter_agreement("standard", 24, 0) == 1.0 and filter_agreement("standard", 12, 0, reference=12) == 1.0
    assert 0.0 < filter_agreement("standard", 1, 0) < 1.0
    assert filter_agreement("standard", 12, 0) < 1.0  # the authored dozen shows turns the first dozen never does
    with pytest.raises(ValueError, match="between 1 and 24"):
        filter_agreement("standard", 25, 0)


def test_report_only_needs_the_table_part_and_an_existing_runs_folder(tmp_path: Path) -> None:
    for args, expected in ((["all", "--budget", "quick", "--report-only"], "use it with the part 'table'"),
                           (["table", "--budget", "quick", "--report-only", "--runs", str(tmp_path / "none")],
                            "no runs folder")):
        result = ncbot("reproduce", *args, "--out", str(tmp_path / "out"))
        assert result.returncode == 2 and expected in result.stderr and "Traceback" not in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_cli_rejects_an_unknown_budget_in_one_line(tmp_path: Path) -> None:
    result = ncbot("reproduce", "table", "--budget", "medium", "--out", str(tmp_path), "--runs", str(tmp_path))
    assert result.returncode == 2 and result.stderr.strip() == "ncbot: error: --budget must be one of full, quick; got 'medium'"


def test_cli_rejects_an_address_without_ray_before_writing_anything(tmp_path: Path) -> None:
    result = ncbot("reproduce", "budget", "--budget", "quick", "--address", "1.2.3.4:6379", "--out", str(tmp_path / "o"),
                   "--runs", str(tmp_path / "r"))
    assert result.returncode == 2 and result.stderr.strip() == (
        "ncbot: error: --address 1.2.3.4:6379 needs --backend ray (it is the Ray cluster's HOST:PORT)")
    assert not (tmp_path / "r").exists()
