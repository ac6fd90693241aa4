"""The interquartile mean, probability of improvement and stratified bootstrap intervals of
`ncbot.pipelines.reproduce.aggregate` against the reference implementation, `rliable` (Agarwal et al. 2021).

rliable is not a dependency (its pins conflict with ours); its values on the shipped runs are recorded here.
Recorded 2026-12-04 with rliable 1.2.0 (arch 7.2.0, pandas 2.x) installed into a throwaway folder
(`pip install --target DIR rliable "pandas<3"`, then PYTHONPATH=DIR): scores = robot-first task success of seeds 0-4
of results/paper_table_seeds.csv, one column per game row (3x3, Ultimate (100), Ultimate (150)), as
`metrics.aggregate_iqm`, `metrics.probability_of_improvement` and `library.get_interval_estimates` (50,000
stratified bootstrap resamples for the IQM, 20,000 for the probability of improvement, percentile intervals).
Point values must agree exactly; the intervals, drawn from other random streams, within their Monte-Carlo error.
"""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from ncbot.pipelines.reproduce.aggregate import (improvement_interval, iqm, iqm_interval,
                                                 probability_of_improvement)

SEEDS = Path(__file__).resolve().parents[2] / "results" / "paper_table_seeds.csv"
RLIABLE = {
    "iqm": {"proposed-temporal": 0.934037037037037, "dqn_variant-notemporal": 0.8878148148148148},
    "iqm_ci": {"proposed-temporal": (0.9178518518518519, 0.9432962962962963),
               "dqn_variant-notemporal": (0.8792962962962964, 0.8923703703703705)},
    "poi": {("proposed-temporal", "dqn_variant-notemporal"): 0.8533333333333332,
            ("proposed-notemporal", "dqn_original-notemporal"): 1.0,
            ("proposed-temporal", "proposed-notemporal"): 0.49333333333333335},
    "poi_ci": {("proposed-temporal", "dqn_variant-notemporal"): (0.68, 0.9866666666666667),
               ("proposed-temporal", "proposed-notemporal"): (0.29333333333333333, 0.7066666666666667)},
}


def _strata(agent: str) -> list[list[float]]:
    with SEEDS.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return [[float(row["first.task_success"]) for row in rows
             if row["game"] == game and row["agent"] == agent and int(row["seed"]) < 5]
            for game in ("standard", "ultimate100", "ultimate150")]


def test_point_values_equal_rliables() -> None:
    for agent, expected in RLIABLE["iqm"].items():
        assert iqm([score for stratum in _strata(agent) for score in stratum]) == pytest.approx(expected, abs=1e-12)
    for (larger, smaller), expected in RLIABLE["poi"].items():
        assert probability_of_improvement(_strata(larger), _strata(smaller)) == pytest.approx(expected, abs=1e-12)


def test_stratified_bootstrap_intervals_agree_with_rliables() -> None:
    for agent, (low, high) in RLIABLE["iqm_ci"].items():
        _, found_low, found_high = iqm_interval(_strata(agent), reps=50_000)
        assert (found_low, found_high) == pytest.approx((low, high), abs=0.002)
    for (larger, smaller), (low, high) in RLIABLE["poi_ci"].items():
        _, found_low, found_high = improvement_interval(_strata(larger), _strata(smaller), reps=20_000)
        assert (found_low, found_high) == pytest.approx((low, high), abs=1 / 75 + 0.005)  # steps of 1/75 per row
