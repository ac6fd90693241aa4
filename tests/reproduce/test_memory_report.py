"""`ncbot reproduce memory`: temporal information three ways, read from grids' run folders
(pipelines/reproduce/memory.py)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
import yaml
from scipy.stats import ttest_ind

from ncbot.pipelines.reproduce.memory import comparisons, read_arms, write_memory_report
from tests.learning_helpers import ncbot

# robot-first task success per seed of each arm: (suite, memory, temporal, batch) -> values
ARMS = {
    ("ff", "none", False, 2): [0.990, 0.992, 0.985, 0.995, 0.991],
    ("ff", "none", True, 2): [0.993, 0.989, 0.996, 0.990, 0.994],
    ("ff16", "none", False, 16): [0.980, 0.982, 0.979, 0.985, 0.983],
    ("ff16", "none", True, 16): [0.981, 0.984, 0.978, 0.983, 0.982],
    ("gru", "gru", False, 16): [0.999, 0.998, 0.997, 0.999, 0.996],
    ("gru", "gru", True, 16): [0.998, 0.999, 0.995, 0.997, 0.999],
}


def _history(success: float) -> list[dict]:
    return [{"episodes": games, "frames": 10 * games, "task_success": value, "games": 500}
            for games, value in ((400, 0.94), (800, 0.96), (1200, success))]


def grid_runs(root: Path, arms: dict = ARMS, game: str = "standard", reward: str | None = None, tag: str = "") -> Path:
    """Run folders in the layout `ncbot ablate` writes, each with the config.yaml, eval.json and checkpoint a
    finished run has (a Q-network of a size that tells the arms apart); ``tag`` makes other run ids."""
    for (suite, memory, temporal, batch), values in arms.items():
        cell = f"proposed-{'temporal' if temporal else 'notemporal'}"
        for seed, success in enumerate(values):
            folder = root / suite / game / cell / f"seed{seed}"
            folder.mkdir(parents=True)
            config = {"env": {"game": game, "temporal": temporal}, "agent": {"memory": memory},
                      "buffer": {"batch_size": batch}}
            if reward is not None:  # a config without loss.reward trains on the paper's rewards (its default)
                config["loss"] = {"reward": reward}
            (folder / "config.yaml").write_text(yaml.safe_dump(config))
            (folder / "eval.json").write_text(json.dumps({
                "frames": 30000, "train_wall_time_s": 150.0 + seed, "run_id": f"{tag}{game}{suite}{cell}{seed}",
                "history": _history(success),
                "first": {"games": 3000, "task_success": success, "win": success - 0.03, "avg_reward": 0.8,
                          "avg_length": 11.9},
                "second": {"games": 3000, "task_success": success - 0.04, "avg_reward": 0.7, "avg_length": 12.1}}))
            width = 8 if memory == "none" else 12
            torch.save({"qnet": {"weight": torch.zeros(width, 10), "bias": torch.zeros(width)}}, folder / "checkpoint.pt")
    return root


def test_arms_are_told_apart_by_what_their_runs_were_trained_with(tmp_path: Path) -> None:
    arms = read_arms(grid_runs(tmp_path))
    assert [(a.memory, a.temporal, a.batch_size) for a in arms] == [
        ("none", False, 2), ("none", True, 2), ("none", False, 16), ("none", True, 16), ("gru", False, 16),
        ("gru", True, 16)]
    assert arms[0].values("first.task_success") == ARMS[("ff", "none", False, 2)]
    assert arms[0].values("params") == [88] * 5 and arms[4].values("params") == [132] * 5
    assert arms[0].values("games_to_0.95") == [800.0] * 5
    assert arms[0].values("games_to_0.99")[:2] == [1200.0, 1200.0] and len(arms[0].values("games_to_0.99")) == 4
    assert arms[0].values("ms_per_frame")[0] == pytest.approx(5.0)


def test_each_question_compares_arms_that_differ_in_one_way_and_matches_scipy(tmp_path: Path) -> None:
    found = {c.question: c for c in comparisons(read_arms(grid_runs(tmp_path)))}
    assert set(found) == {"temporal features help (feed-forward, batch 2)", "temporal features help (GRU, batch 16)",
                          "temporal features help (feed-forward, batch 16)",
                          "GRU helps (no temporal features, batch 16)", "GRU helps (with temporal features, batch 16)",
                          "GRU instead of the features (batch 16 vs 2)", "GRU instead of the features (batch 16 vs 16)"}
    gru = found["GRU helps (no temporal features, batch 16)"]
    assert (gru.better.memory, gru.worse.memory, gru.worse.batch_size) == ("gru", "none", 16)
    expected = ttest_ind(ARMS[("gru", "gru", False, 16)], ARMS[("ff16", "none", False, 16)], equal_var=False,
                         alternative="greater").pvalue
    assert gru.test.p == pytest.approx(expected)
    assert gru.verdict == "yes" and gru.test.difference.low > 0
    two_sided = ttest_ind(ARMS[("gru", "gru", False, 16)], ARMS[("ff16", "none", False, 16)], equal_var=False)
    assert (gru.test.difference.low, gru.test.difference.high) == pytest.approx(tuple(two_sided.confidence_interval(0.95)))
    assert gru.difference_second.mean == pytest.approx(gru.test.difference.mean)  # robot second is 0.04 lower in every run
    assert gru.test.improvement == (1.0, 1.0, 1.0)  # every GRU seed beats every feed-forward seed
    features = found["temporal features help (feed-forward, batch 2)"]  # 15 of 25 pairs ahead, 1 tied
    assert features.test.improvement[0] == pytest.approx(0.62) and features.test.improvement[1] < 0.62 < features.test.improvement[2]
    holms = sorted(c.holm_p for c in found.values())
    assert all(c.holm_p >= c.test.p for c in found.values()) and holms == sorted(holms) and holms[-1] <= 1.0


def test_the_report_and_the_seeds_csv(tmp_path: Path) -> None:
    written = write_memory_report(grid_runs(tmp_path / "runs"), tmp_path / "out", "ncbot reproduce memory runs")
    assert written["runs"] == 30 and written["arms"] == 6
    text = (tmp_path / "out" / "table.md").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| 3x3 | GRU, no temporal features, batch 16"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == "0, 1, 2, 3, 4" and cells[3].startswith("0.9978 [") and cells[-1] == "132"
    assert "(4 of 5 seeds)" in next(line for line in text.splitlines() if "feed-forward, no temporal features, batch 2" in line)
    csv = (tmp_path / "out" / "table_seeds.csv").read_text().splitlines()
    assert len(csv) == 31 and csv[0].startswith("game,reward,memory,temporal,batch_size,seed")
    assert Path(written["files"][2]).stat().st_size > 0


def test_one_report_reads_the_grids_of_both_games(tmp_path: Path) -> None:
    feed_forward = {key: values for key, values in ARMS.items() if key[0] == "ff"}
    standard = grid_runs(tmp_path / "standard", feed_forward)
    ultimate = grid_runs(tmp_path / "ultimate", feed_forward, game="ultimate")
    arms = read_arms([standard, ultimate])
    assert [(a.game, a.temporal) for a in arms] == [("standard", False), ("standard", True), ("ultimate", False),
                                                    ("ultimate", True)]
    found = comparisons(arms)
    assert [(c.better.game, c.question) for c in found] == [
        ("standard", "temporal features help (feed-forward, batch 2)"),
        ("ultimate", "temporal features help (feed-forward, batch 2)")]
    # the same seeds and spread: the power is to detect each game's own paper difference, larger on Ultimate
    assert found[1].power > found[0].power
    written = write_memory_report([str(standard), str(ultimate)], tmp_path / "out", "ncbot reproduce memory a b")
    assert written["runs"] == 20 and written["arms"] == 4
    text = (tmp_path / "out" / "table.md").read_text()
    assert any(line.startswith("| Ultimate | feed-forward, temporal features, batch 2") for line in text.splitlines())


def test_arms_of_two_recipes_are_told_apart_and_never_compared(tmp_path: Path) -> None:
    """The default recipes (outcome rewards, batch 1024) beside the paper's protocol: same game, memory and features,
    yet other arms; each question stays inside one recipe, and the curves get a panel per recipe."""
    paper = grid_runs(tmp_path / "paper", {key: ARMS[key] for key in [("ff", "none", False, 2), ("gru", "gru", False, 16)]},
                      reward="paper")
    default_arms = {("ff", "none", False, 1024): [0.999, 0.998, 1.0, 0.999, 0.997],
                    ("ff", "none", True, 1024): [0.998, 0.999, 0.999, 1.0, 0.998],
                    ("gru", "gru", False, 1024): [0.995, 0.997, 0.999, 0.998, 0.996]}
    default = grid_runs(tmp_path / "default", default_arms, reward="outcome")
    arms = read_arms([default, paper])
    assert [(a.reward, a.memory, a.temporal, a.batch_size) for a in arms] == [
        ("paper", "none", False, 2), ("paper", "gru", False, 16), ("outcome", "none", False, 1024),
        ("outcome", "none", True, 1024), ("outcome", "gru", False, 1024)]
    assert arms[2].label == "feed-forward, no temporal features, batch 1024, default recipe"
    assert arms[0].label == "feed-forward, no temporal features, batch 2"
    found = comparisons(arms)
    assert sorted(c.question for c in found) == [
        "GRU helps (no temporal features, batch 1024, default recipe)",
        "GRU instead of the features (batch 1024 vs 1024, default recipe)",
        "temporal features help (feed-forward, batch 1024, default recipe)"]
    # the paper's GRU has no feed-forward arm with the features in its own recipe: no question, though the default
    # recipe has one
    assert all(c.better.reward == c.worse.reward for c in found)
    # both arms at task success 1 on every seed: no test can separate them, and the verdict says so, not "no"
    at_ceiling = {("ff", "none", False, 1024): [1.0] * 5, ("ff", "none", True, 1024): [1.0] * 5}
    ceiling = comparisons(read_arms(grid_runs(tmp_path / "ceiling", at_ceiling, reward="outcome")))
    assert [c.verdict for c in ceiling] == ["at the ceiling (every seed 1.0000): cannot tell"]
    written = write_memory_report([str(paper), str(default)], tmp_path / "out", "ncbot reproduce memory a b")
    assert written["arms"] == 5
    csv = (tmp_path / "out" / "table_seeds.csv").read_text().splitlines()
    assert sum(line.split(",")[1] == "outcome" for line in csv[1:]) == 15


def test_a_seed_of_one_arm_in_two_folders_is_one_line(tmp_path: Path) -> None:
    feed_forward = {key: values for key, values in ARMS.items() if key[0] == "ff"}
    first, second = grid_runs(tmp_path / "a", feed_forward), grid_runs(tmp_path / "b", feed_forward, tag="other")
    with pytest.raises(ValueError, match="are the same seed of one arm"):
        read_arms([first, second])
    copy = grid_runs(tmp_path / "c", feed_forward)  # the same runs (same run ids) in a second folder: kept once
    assert [len(arm.runs) for arm in read_arms([first, copy])] == [5, 5]


def test_a_wrong_call_is_one_line_and_exit_2(tmp_path: Path) -> None:
    result = ncbot("reproduce", "memory", "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "memory reads runs folders" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    result = ncbot("reproduce", "memory", str(empty), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "no finished runs" in result.stderr, result.stderr


def test_a_powered_difference_that_is_not_significant_reads_not_shown_not_no(tmp_path: Path) -> None:
    """"no" is kept for an arm that did not come out ahead; one ahead but not significantly is "not shown"."""
    arms = {("ff", "none", False, 2): [0.890, 0.892, 0.889, 0.894, 0.891],
            ("ff", "none", True, 2): [0.920, 0.880, 0.925, 0.890, 0.905]}
    found = comparisons(read_arms(grid_runs(tmp_path, arms, game="ultimate")))
    assert len(found) == 1 and found[0].power >= 0.8 and 0.05 <= found[0].test.p
    assert found[0].verdict == "not shown (p >= 0.05)"
    flipped = {("ff", "none", False, 2): arms[("ff", "none", True, 2)],
               ("ff", "none", True, 2): arms[("ff", "none", False, 2)]}
    assert comparisons(read_arms(grid_runs(tmp_path / "flipped", flipped, game="ultimate")))[0].verdict == "no"


def _table_rows(path: Path) -> list[str]:
    return [line for line in path.read_text().splitlines() if line.startswith("|")]


def test_the_seeds_and_curves_csvs_stand_in_for_the_run_folders(tmp_path: Path) -> None:
    """A report's two CSVs read back give the same arms, numbers, tests and curves as the run folders they came
    from, so runs measured on another machine can be joined by new ones."""
    runs = grid_runs(tmp_path / "runs")
    write_memory_report(runs, tmp_path / "from_runs", "ncbot reproduce memory runs")
    seeds = tmp_path / "from_runs" / "table_seeds.csv"
    assert (tmp_path / "from_runs" / "table_curves.csv").read_text().count("\n") == 1 + 30 * 3
    again = read_arms(seeds)
    for before, after in zip(read_arms(runs), again, strict=True):
        assert after.label == before.label
        for metric in ("first.task_success", "second.task_success", "first.win", "games_to_0.95", "games_to_0.99",
                       "ms_per_frame", "params"):
            assert after.values(metric) == pytest.approx(before.values(metric)), metric
        for new, old in zip(after.runs, before.runs, strict=True):
            assert [(point["episodes"], point["frames"], point["task_success"]) for point in new["history"]] == \
                [(point["episodes"], point["frames"], point["task_success"]) for point in old["history"]]
    write_memory_report(str(seeds), tmp_path / "from_csv", "ncbot reproduce memory runs")
    assert _table_rows(tmp_path / "from_csv" / "table.md") == _table_rows(tmp_path / "from_runs" / "table.md")
    assert (tmp_path / "from_csv" / "table_seeds.csv").read_text() == seeds.read_text()
    assert (tmp_path / "from_csv" / "table_curves.csv").read_text() == \
        (tmp_path / "from_runs" / "table_curves.csv").read_text()


def test_a_seeds_csv_joins_new_runs_and_keeps_figures_it_cannot_redraw(tmp_path: Path) -> None:
    feed_forward = {key: values for key, values in ARMS.items() if key[0] == "ff"}
    gru = {key: values for key, values in ARMS.items() if key[0] == "gru"}
    write_memory_report(grid_runs(tmp_path / "old", feed_forward), tmp_path / "report", "ncbot reproduce memory old")
    (tmp_path / "report" / "table_curves.csv").unlink()  # a seeds CSV alone: no curves to draw
    seeds = tmp_path / "report" / "table_seeds.csv"
    arms = read_arms([seeds, grid_runs(tmp_path / "new", gru)])
    assert [(a.memory, a.temporal, len(a.runs)) for a in arms] == [("none", False, 5), ("none", True, 5),
                                                                    ("gru", False, 5), ("gru", True, 5)]
    assert arms[0].values("games_to_0.99")[:2] == [1200.0, 1200.0] and len(arms[0].values("games_to_0.99")) == 4
    assert "GRU helps (no temporal features, batch 16)" not in {c.question for c in comparisons(arms)}  # batch 2 only
    assert "GRU instead of the features (batch 16 vs 2)" in {c.question for c in comparisons(arms)}
    result = ncbot("reproduce", "memory", str(seeds), str(tmp_path / "new"), "--out", str(tmp_path / "report"))
    assert result.returncode == 0, result.stderr
    text = (tmp_path / "report" / "table.md").read_text()
    assert "Not drawn in `curves.png`" in text and "feed-forward, no temporal features, batch 2 (every seed)" in text
    assert "GRU, no temporal features" not in text.split("Not drawn")[1].split("\n")[0]
    assert len((tmp_path / "report" / "table_seeds.csv").read_text().splitlines()) == 21
    with pytest.raises(ValueError, match="are the same seed of one arm"):
        read_arms([seeds, grid_runs(tmp_path / "rerun", feed_forward, tag="rerun")])


def test_a_bad_seeds_csv_is_one_line_and_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "table_seeds.csv"
    bad.write_text("game,seed\nstandard,0\n")
    result = ncbot("reproduce", "memory", str(bad), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "lacks the columns" in result.stderr and "reward" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    write_memory_report(grid_runs(tmp_path / "runs"), tmp_path / "report", "ncbot reproduce memory runs")
    good = (tmp_path / "report" / "table_seeds.csv").read_text().splitlines()
    bad.write_text("\n".join([good[0], good[1].replace(",0.9", ",high", 1)]) + "\n")
    result = ncbot("reproduce", "memory", str(bad), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "line 2" in result.stderr and "expected a number" in result.stderr, result.stderr
    (tmp_path / "report" / "table_curves.csv").write_text("game,seed\nstandard,0\n")  # a curves file beside it
    result = ncbot("reproduce", "memory", str(tmp_path / "report" / "table_seeds.csv"), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and "table_curves.csv lacks the columns" in result.stderr, result.stderr
    assert "expected a table_curves.csv" in result.stderr and len(result.stderr.strip().splitlines()) == 1
