"""`ncbot table`: t-intervals over seeds, "paper inside ours?", the claims' Welch tests and verdicts, and bad
eval.json files as one-line errors, on small run trees of eval.json files with known values."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from scipy import stats

from ncbot.pipelines.reproduce.claims import TOO_FEW, evaluate_claims
from ncbot.pipelines.reproduce.two_sample import welch_greater
from ncbot.pipelines.reproduce.table import t_interval, write_report
from tests.learning_helpers import ncbot

ORIGINAL, VARIANT = "dqn_original-notemporal", "dqn_variant-notemporal"
NOTEMPORAL, TEMPORAL = "proposed-notemporal", "proposed-temporal"


def write_run(root: Path, cell: str, seed: int, success: float, length: float = 10.0, *, suite: str = "paper",
              game: str = "standard", frames: int = 400000) -> None:
    folder = root / suite / game / cell / f"seed{seed}"
    folder.mkdir(parents=True)
    (folder / "eval.json").write_text(json.dumps({
        "frames": frames, "train_wall_time_s": 100.0 + seed, "run_id": f"{suite}-{game}-{cell}-{seed}",
        "first": {"games": 3000, "avg_reward": 0.5, "task_success": success, "avg_length": length, "truncated": 0.0},
        "second": {"games": 3000, "task_success": success - 0.1},
        "history": [{"frames": 1000, "task_success": 0.5, "avg_reward": 0.1}],
    }))


def write_cell(root: Path, cell: str, successes: list[float], lengths: list[float] | None = None, **where) -> None:
    for seed, success in enumerate(successes):
        write_run(root, cell, seed, success, (lengths or [10.0] * len(successes))[seed], **where)


def test_t_interval_matches_the_hand_computed_student_interval() -> None:
    values = [0.90, 0.92, 0.94, 0.96, 0.98]
    # mean 0.94, s^2 = 0.004 / 4 = 0.001, t(0.975, 4) = 2.776445, half = t * s / sqrt(5) = 0.0392649
    interval = t_interval(values)
    assert interval.n == 5 and interval.mean == pytest.approx(0.94)
    assert (interval.low, interval.high) == pytest.approx((0.9007351, 0.9792649), abs=1e-7)
    assert (interval.low, interval.high) == pytest.approx(stats.t.interval(0.95, 4, loc=0.94, scale=stats.sem(values)))


def test_one_seed_has_no_interval_and_identical_seeds_a_zero_width_one() -> None:
    single = t_interval([0.7627])
    assert (single.low, single.high, single.holds(0.7627), single.text(4)) == (None, None, "n<2", "0.7627 [n<2]")
    constant = t_interval([0.1, 0.1, 0.1])  # fsum-free rounding would give a 1e-17 "spread" here
    assert (constant.mean, constant.low, constant.high) == (0.1, 0.1, 0.1)
    assert (constant.holds(0.1), constant.holds(0.1001)) == ("yes", "no")
    with pytest.raises(ValueError):
        t_interval([])


def _logit_interval(values: list[float], games: int, predict: bool) -> tuple[float, float]:
    """The interval by hand: Student t over the empirical logits, mapped back."""
    logits = [math.log((v * games + 0.5) / (games - v * games + 0.5)) for v in values]
    n, mean = len(logits), sum(logits) / len(logits)
    s = math.sqrt(sum((x - mean) ** 2 for x in logits) / (n - 1))
    half = stats.t.ppf(0.975, n - 1) * s * (math.sqrt(1 + 1 / n) if predict else 1 / math.sqrt(n))
    return 1 / (1 + math.exp(-(mean - half))), 1 / (1 + math.exp(-(mean + half)))


def test_table_rows_intervals_and_paper_inside(tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    write_cell(runs, TEMPORAL, [0.9960, 0.9980, 1.0000])  # paper 0.9980: inside the prediction interval
    write_cell(runs, VARIANT, [0.99, 0.99])  # paper 0.9720; a constant pair: zero spread, outside
    write_cell(runs, ORIGINAL, [0.80])  # one seed: not tested
    write_cell(runs, "proposed-temporal-k2", [0.99, 0.98])  # no paper number
    report = write_report(runs, tmp_path / "out" / "table.md")
    by_cell = {row.cell: row for row in report.rows}
    assert [row.cell for row in report.rows] == [ORIGINAL, VARIANT, TEMPORAL, "proposed-temporal-k2"]
    assert {cell: row.paper_inside for cell, row in by_cell.items()} == {
        TEMPORAL: "yes", VARIANT: "no", ORIGINAL: "n<2", "proposed-temporal-k2": None}
    success = by_cell[TEMPORAL].stats["task_success"]
    assert success.mean == pytest.approx(0.998)
    assert (success.low, success.high) == pytest.approx(_logit_interval([0.996, 0.998, 1.0], 3000, predict=False))
    assert (success.predict_low, success.predict_high) == \
        pytest.approx(_logit_interval([0.996, 0.998, 1.0], 3000, predict=True))
    assert 0 < success.predict_low < success.low < success.high < success.predict_high < 1  # never past 1
    length = by_cell[TEMPORAL].stats["avg_length"]  # not a rate: plain Student t on the raw scale
    assert (length.low, length.high) == (10.0, 10.0)
    assert by_cell[TEMPORAL].stats["task_success_second"].mean == pytest.approx(0.898)
    assert by_cell[TEMPORAL].stats["train_wall_time_s"].mean == pytest.approx(101.0)

    table = (tmp_path / "out" / "table.md").read_text()
    assert f"Made by `ncbot table {runs}" in table and "prediction interval" in table
    temporal_line = next(line for line in table.splitlines() if "| Proposed + temporal | paper |" in line)
    cells = [cell.strip() for cell in temporal_line.split("|")[1:-1]]
    low, high = _logit_interval([0.996, 0.998, 1.0], 3000, predict=False)
    assert cells[3:11] == ["3", "400000/400000/400000", "0.5000 [0.5000, 0.5000]", f"0.9980 [{low:.4f}, {high:.4f}]",
                           success.prediction_text(4), "0.9980", "yes", "0.0000 [0.0000, 0.0000]"]
    assert cells[11] == "–"  # all-negative: these eval.json files do not have it
    assert cells[-3:] == ["0.6300", "no", "14.06"]  # the paper's 0.63 outside our (zero-width) 0.5
    assert "| DQN-Original | paper | 1 | 400000 | 0.5000 [n<2] | 0.8000 [n<2] | n<2 | 0.8258 | n<2 |" in table
    claims = (tmp_path / "out" / "paper_claims.md").read_text()
    assert "Made by `ncbot table" in claims and "one-sided Welch's t-test" in claims
    assert (tmp_path / "out" / "curves_paper_standard.png").stat().st_size > 0
    seeds = (tmp_path / "out" / "table_seeds.csv").read_text().splitlines()
    assert seeds[0].startswith("suite,game,agent,seed,run_id,frames") and len(seeds) == 1 + 3 + 2 + 1 + 2
    assert "paper,standard,proposed-temporal,2,paper-standard-proposed-temporal-2,400000" in seeds[-3]


def test_an_agent_without_a_network_is_one_row_per_game_not_per_width(tmp_path: Path) -> None:
    for game in ("ultimate100", "ultimate150"):  # the uniform choice inside the masks plays the same at both widths
        write_cell(tmp_path, "uniform-notemporal", [0.88, 0.89], game=game, frames=0)
        write_cell(tmp_path, TEMPORAL, [0.92, 0.93], game=game)
    report = write_report(tmp_path, tmp_path / "t.md")
    assert [(row.game, row.cell) for row in report.rows] == [
        ("ultimate100", "uniform-notemporal"), ("ultimate100", TEMPORAL), ("ultimate150", TEMPORAL)]


def test_a_copied_seed_folder_is_refused(tmp_path: Path) -> None:
    import shutil

    write_cell(tmp_path, TEMPORAL, [0.99, 0.98])
    shutil.copytree(tmp_path / "paper" / "standard" / TEMPORAL / "seed1", tmp_path / "paper" / "standard" / TEMPORAL / "seed2")
    with pytest.raises(ValueError, match="seed1 and .*seed2 hold the same run"):
        write_report(tmp_path, tmp_path / "t.md")


def test_rates_stay_inside_zero_and_one_with_few_seeds() -> None:
    from ncbot.pipelines.reproduce.seed_stats import proportion_interval, t_interval

    values = [0.7700, 0.9067, 0.8758]  # a raw t-interval of these reaches past 1
    assert t_interval(values).high > 1
    rate = proportion_interval(values, 600)
    assert 0 < rate.predict_low < rate.low < rate.mean < rate.high < rate.predict_high < 1
    perfect = proportion_interval([1.0] * 5, 3000)
    assert (perfect.low, perfect.high) == (1.0, 1.0)  # no spread between seeds, as a t-interval


def test_welch_matches_scipy_and_handles_constant_sides() -> None:
    a, b = [0.99, 0.97, 0.98, 0.995, 0.985], [0.95, 0.96, 0.90, 0.97, 0.93]
    t, df, p = welch_greater(a, b)
    expected = stats.ttest_ind(a, b, equal_var=False, alternative="greater")
    assert (t, p) == pytest.approx((expected.statistic, expected.pvalue))
    assert df == pytest.approx(expected.df)
    assert welch_greater(b, a)[2] == pytest.approx(1 - p)  # the other direction
    # one side constant: ordinary Welch with the other side's df
    t, df, p = welch_greater([1.0] * 5, b)
    assert df == pytest.approx(4) and p == pytest.approx(stats.ttest_1samp(b, 1.0, alternative="less").pvalue)
    # both sides constant: exact difference, p 0 or 1, no NaN
    assert welch_greater([1.0] * 5, [0.9] * 5) == (None, None, 0.0)
    assert welch_greater([0.9] * 5, [1.0] * 5) == (None, None, 1.0)
    assert welch_greater([0.9] * 5, [0.9] * 5) == (None, None, 1.0)
    assert welch_greater([0.9], [0.8, 0.7]) == (None, None, None)


def _paper_tree(root: Path, seeds: int, temporal_gain: float) -> None:
    """Proposed > Variant > Original in task success; temporal vs not by ``temporal_gain``; proposed dialogues
    shorter than DQN-Variant's, longer than DQN-Original's (claim iii fails on the second comparison)."""
    jitter = [0.000, 0.004, -0.004, 0.002, -0.002, 0.001][:seeds]
    write_cell(root, ORIGINAL, [0.80 + j for j in jitter], [9.0 + 10 * j for j in jitter])
    write_cell(root, VARIANT, [0.90 + j for j in jitter], [14.0 + 10 * j for j in jitter])
    write_cell(root, NOTEMPORAL, [0.97 - temporal_gain + j for j in reversed(jitter)])
    write_cell(root, TEMPORAL, [0.97 + j for j in jitter], [12.0 + 10 * j for j in reversed(jitter)])


def test_claims_verdicts_and_p_value_direction(tmp_path: Path) -> None:
    _paper_tree(tmp_path, seeds=5, temporal_gain=0.02)
    claims = {claim.claim: claim for claim in write_report(tmp_path, tmp_path / "t.md").claims}
    assert list(claims) == ["i.a", "i.b", "ii", "iii.a", "iii.b"]
    assert [claims[name].verdict for name in claims] == \
        ["reproduced", "reproduced", "reproduced", "not reproduced", "not reproduced"]
    assert claims["i.a"].p < 1e-6 and claims["i.a"].p == max(test.p for test in claims["i.a"].tests)
    shorter_than_variant, shorter_than_original = claims["iii.a"].tests
    assert shorter_than_variant.p < 0.001 and shorter_than_original.p > 0.999  # the wrong way round: p near 1
    assert claims["iii.a"].p == shorter_than_original.p

    reversed_tree = tmp_path / "reversed"
    _paper_tree(reversed_tree, seeds=5, temporal_gain=-0.02)  # temporal features hurt
    (claim_ii,) = [claim for claim in write_report(reversed_tree, reversed_tree / "t.md").claims if claim.claim == "ii"]
    assert claim_ii.verdict == "not reproduced" and claim_ii.p > 0.999


def test_the_claims_are_the_papers_comparisons_and_no_other() -> None:
    """Each Proposed agent against each baseline, the temporal features, the dialogue lengths; DQN-Variant above
    DQN-Original is not a claim of the paper; the paper's own table fails some of them, as printed."""
    from ncbot.pipelines.reproduce.claims import CLAIMS, paper_holds

    compared = {(metric, larger, smaller) for _, tests in CLAIMS.values() for metric, larger, smaller in tests}
    assert ("task_success", VARIANT, ORIGINAL) not in compared
    for proposed in (TEMPORAL, NOTEMPORAL):
        for baseline in (VARIANT, ORIGINAL):
            assert {("task_success", proposed, baseline), ("avg_length", baseline, proposed)} <= compared
    assert ("task_success", TEMPORAL, NOTEMPORAL) in compared and len(compared) == 9
    assert paper_holds("iii.b", "ultimate100") == "no: DQN-Original 63.54 vs Proposed, no temporal 63.62"
    assert paper_holds("iii.a", "standard").startswith("no: DQN-Variant 13.99 vs Proposed + temporal 14.06")
    assert paper_holds("iii.a", "ultimate100") == paper_holds("i.b", "ultimate150") == "yes"


def test_claims_with_fewer_than_five_seeds_are_not_decided(tmp_path: Path) -> None:
    _paper_tree(tmp_path, seeds=4, temporal_gain=0.02)
    claims = write_report(tmp_path, tmp_path / "t.md").claims
    assert [claim.verdict for claim in claims] == [TOO_FEW] * 5
    assert claims[0].p < 0.05  # shown for information, still not a verdict
    claims = evaluate_claims({("paper", "standard", cell): {"task_success": [0.9] * n, "avg_length": [9.0] * n}
                              for cell, n in ((ORIGINAL, 5), (VARIANT, 5), (TEMPORAL, 1))})
    assert [claim.claim for claim in claims] == ["i.a", "iii.a"]  # the others lack the no-temporal agent: left out
    claim = claims[0]
    assert (claim.p, claim.verdict, claim.tests[1].p) == (None, TOO_FEW, None)  # one seed: no p for its tests


def test_zero_variance_claims_are_decided_without_nan(tmp_path: Path) -> None:
    write_cell(tmp_path, ORIGINAL, [0.8] * 5)
    write_cell(tmp_path, VARIANT, [0.9] * 5)
    write_cell(tmp_path, TEMPORAL, [1.0] * 5)
    write_cell(tmp_path, NOTEMPORAL, [1.0] * 5)
    report = write_report(tmp_path, tmp_path / "t.md")
    verdicts = {claim.claim: (claim.verdict, claim.p) for claim in report.claims}
    assert verdicts == {"i.a": ("reproduced", 0.0), "i.b": ("reproduced", 0.0), "ii": ("not reproduced", 1.0),
                        "iii.a": ("not reproduced", 1.0), "iii.b": ("not reproduced", 1.0)}
    assert "nan" not in json.dumps(report.to_dict()).lower()
    assert "both sides constant" in report.claims_text


def test_cli_writes_both_tables_and_prints_one_json_object(tmp_path: Path) -> None:
    _paper_tree(tmp_path / "runs", seeds=5, temporal_gain=0.02)
    out, claims = tmp_path / "results" / "paper_table.md", tmp_path / "elsewhere" / "claims.md"
    done = ncbot("table", str(tmp_path / "runs"), "--out", str(out), "--claims", str(claims), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["command"] == f"ncbot table {tmp_path / 'runs'} --out {out} --claims {claims} --json"
    assert [row["agent"] for row in report["rows"]] == [ORIGINAL, VARIANT, NOTEMPORAL, TEMPORAL]
    row = report["rows"][3]
    assert (row["seeds"], row["paper"]["task_success"], row["paper_inside_ours"]) == (5, 0.998, "no")
    assert row["task_success"]["low"] < row["task_success"]["mean"] < row["task_success"]["high"]
    assert [(c["claim"], c["verdict"]) for c in report["claims"]] == \
        [("i.a", "reproduced"), ("i.b", "reproduced"), ("ii", "reproduced"), ("iii.a", "not reproduced"),
         ("iii.b", "not reproduced")]
    assert report["claims"][0]["tests"][0]["larger"] == TEMPORAL
    assert out.exists() and claims.exists() and f"Made by `{report['command']}`" in claims.read_text()

    text = ncbot("table", str(tmp_path / "runs"), "--out", str(out))
    assert text.returncode == 0 and "| (iii.a) | 3x3 (100) | paper |" in text.stdout
    assert (out.parent / "paper_claims.md").exists()


@pytest.mark.parametrize("content, expected", [
    ("{not json", "is not JSON"),
    ("[1, 2]", "holds a JSON list, not an object"),
    (json.dumps({"frames": 1, "train_wall_time_s": 1.0, "first": {"avg_reward": 0.1, "task_success": 0.9},
                 "second": {"task_success": 0.8}}), "has no 'first.avg_length'"),
    (json.dumps({"frames": 1, "train_wall_time_s": 1.0, "first": {"avg_reward": 0.1, "task_success": "high",
                 "avg_length": 9}, "second": {"task_success": 0.8}}), "'first.task_success' is 'high', not a finite"),
])
def test_bad_eval_json_is_one_line_and_exit_code_2(tmp_path: Path, content: str, expected: str) -> None:
    write_cell(tmp_path / "runs", TEMPORAL, [0.99, 0.98])
    bad = tmp_path / "runs" / "paper" / "standard" / TEMPORAL / "seed1" / "eval.json"
    bad.write_text(content)
    done = ncbot("table", str(tmp_path / "runs"))
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.strip().splitlines()) == 1
    assert str(bad) in done.stderr and expected in done.stderr and "expected the JSON object" in done.stderr


def test_table_and_claims_cannot_share_a_file(tmp_path: Path) -> None:
    write_cell(tmp_path, TEMPORAL, [0.99])
    with pytest.raises(ValueError, match="both be written"):
        write_report(tmp_path, tmp_path / "paper_claims.md")


def test_claim_ii_with_too_little_power_is_untested_and_p_values_are_holm_adjusted(tmp_path: Path) -> None:
    from ncbot.pipelines.reproduce.seed_stats import power_of

    spread = [0.0, 0.03, -0.03, 0.015, -0.015]  # seeds that differ by more than the paper's 3x3 gain of 0.0112
    write_cell(tmp_path, NOTEMPORAL, [0.96 + j for j in spread])
    write_cell(tmp_path, TEMPORAL, [0.96 + j for j in reversed(spread)])
    write_cell(tmp_path, VARIANT, [0.90 + j for j in spread])
    write_cell(tmp_path, ORIGINAL, [0.80 + j for j in spread])
    claims = {claim.claim: claim for claim in write_report(tmp_path, tmp_path / "t.md").claims}
    ii = claims["ii"]
    s = float(stats.tstd([0.96 + j for j in spread]))
    assert ii.power == pytest.approx(power_of(0.9980 - 0.9868, s, 5)) and ii.power < 0.8
    assert ii.verdict.startswith("not reproduced; power") and ii.verdict.endswith("untested")
    ps = sorted(claim.p for claim in claims.values())  # Holm by hand over the file's five claims
    expected, running = [], 0.0
    for rank, p in enumerate(ps):
        running = max(running, min(1.0, (len(ps) - rank) * p))
        expected.append(running)
    assert sorted(claim.holm_p for claim in claims.values()) == pytest.approx(expected)
    assert "Holm" in (tmp_path / "paper_claims.md").read_text()
