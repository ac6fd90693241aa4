"""Few-seed aggregates (interquartile mean, probability of improvement, stratified bootstrap, performance profiles)
on small score sets whose answers are worked by hand, and their place in `ncbot table`'s claims report."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import trim_mean

from ncbot.pipelines.reproduce.aggregate import (improvement_interval, iqm, iqm_interval, performance_profile,
                                                 probability_of_improvement, reading)
from ncbot.pipelines.reproduce.table import write_report
from tests.reproduce.test_table import NOTEMPORAL, ORIGINAL, TEMPORAL, VARIANT, write_cell


def test_iqm_cuts_a_quarter_from_each_end_as_rliable_does() -> None:
    assert iqm([8, 1, 7, 2, 6, 3, 5, 4]) == pytest.approx(4.5)  # the middle four: 3, 4, 5, 6
    assert iqm([0.1, 0.9, 0.5, 0.6, 100.0]) == pytest.approx((0.5 + 0.6 + 0.9) / 3)  # 5 runs: one cut each end
    rng = np.random.default_rng(3)
    for n in (3, 5, 7, 10):
        scores = rng.random(n)
        assert iqm(scores) == pytest.approx(trim_mean(scores, 0.25))
    with pytest.raises(ValueError, match="at least one score"):
        iqm([])


def test_probability_of_improvement_counts_pairs_and_ties_half_and_averages_strata() -> None:
    assert probability_of_improvement([[3, 1]], [[2, 2]]) == pytest.approx(0.5)  # 2 of 4 pairs ahead
    assert probability_of_improvement([[2]], [[2]]) == pytest.approx(0.5)  # a tie is half
    assert probability_of_improvement([[3, 3]], [[2, 3]]) == pytest.approx(0.75)  # 2 ahead + 2 ties of 4
    # strata weigh equally, whatever their run counts: (1 + 0) / 2
    assert probability_of_improvement([[5, 5, 5], [0]], [[1], [1, 1, 1]]) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="same, non-empty list of strata"):
        probability_of_improvement([[1]], [[1], [2]])
    with pytest.raises(ValueError, match="at least one run"):
        probability_of_improvement([[1], []], [[1], [2]])


def test_the_bootstrap_resamples_within_strata_and_repeats_itself() -> None:
    # every stratified resample holds three 0s and three 1s, so the IQM never moves; pooled resampling would
    point, low, high = iqm_interval([[0, 0, 0], [1, 1, 1]])
    assert (point, low, high) == (0.5, 0.5, 0.5)
    # one side ahead in every pair of every resample: the interval is the point
    assert improvement_interval([[0.9, 0.95], [0.8, 0.85]], [[0.5, 0.6], [0.1, 0.2]]) == (1.0, 1.0, 1.0)
    larger, smaller = [[0.91, 0.93, 0.88, 0.95, 0.90]], [[0.89, 0.90, 0.87, 0.92, 0.88]]
    found = improvement_interval(larger, smaller)
    assert found == improvement_interval(larger, smaller)  # fixed generator seed
    assert found[1] < found[0] < found[2] and 0 <= found[1] and found[2] <= 1
    assert found != improvement_interval(larger, smaller, seed=1)
    assert (reading(0.55, 0.9), reading(0.1, 0.45), reading(0.4, 0.9)) == \
        ("as claimed", "against the claim", "not separated")


def test_performance_profile_is_the_share_of_runs_above_each_threshold() -> None:
    profile = performance_profile([0.7, 0.8, 0.9, 0.95], [0.0, 0.75, 0.9, 1.0])
    assert profile.tolist() == [1.0, 0.75, 0.25, 0.0]  # strictly above: 0.9 is not above 0.9


def test_claims_report_pools_the_rows_both_agents_have(tmp_path: Path) -> None:
    jitter = [0.000, 0.004, -0.004, 0.002, -0.002]
    for game in ("standard", "ultimate100"):
        write_cell(tmp_path, ORIGINAL, [0.80 + j for j in jitter], game=game)
        write_cell(tmp_path, VARIANT, [0.90 + j for j in jitter], game=game)
        write_cell(tmp_path, TEMPORAL, [0.97 + j for j in jitter], game=game)
    write_cell(tmp_path, NOTEMPORAL, [0.96, 0.98], game="standard")
    write_cell(tmp_path, NOTEMPORAL, [0.99], game="ultimate100")  # one seed: this row stays out of the pool
    report = write_report(tmp_path, tmp_path / "t.md")
    pooled = {(c["larger"], c["smaller"], c["metric"]): c for c in report.pooled["comparisons"]}
    above_variant = pooled[(TEMPORAL, VARIANT, "task_success")]
    assert (above_variant["games"], above_variant["runs"], above_variant["p"]) == \
        (("standard", "ultimate100"), (10, 10), 1.0)
    assert above_variant["reading"] == "as claimed"
    temporal = pooled[(TEMPORAL, NOTEMPORAL, "task_success")]
    assert (temporal["games"], temporal["runs"]) == (("standard",), (5, 2))
    assert temporal["p"] == 0.5 and temporal["low"] < 0.5 < temporal["high"] and temporal["reading"] == "not separated"
    scores = {score["cell"]: score for score in report.pooled["scores"]}
    assert scores[NOTEMPORAL]["runs"] == 2 and scores[ORIGINAL]["runs"] == 10
    assert scores[ORIGINAL]["iqm"] == pytest.approx(0.80, abs=0.002)
    assert "## Pooled over game rows" in report.claims_text
    (claim_i,) = [claim for claim in report.claims if claim.claim == "i.a" and claim.game == "standard"]
    assert claim_i.improvements == ((1.0, 1.0, 1.0), (1.0, 1.0, 1.0))
    assert "1.00 [1.00, 1.00]<br>1.00 [1.00, 1.00]" in report.claims_text
    assert json.dumps(report.to_dict())  # serialisable, pooled included
    assert (tmp_path / "t_profiles.png").stat().st_size > 10_000
