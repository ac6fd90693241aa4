"""The test every report shares (pipelines/reproduce/two_sample.py): its reading ladder, its power and Holm."""
from __future__ import annotations

import numpy as np
import pytest

from ncbot.pipelines.reproduce.seed_stats import power_of
from ncbot.pipelines.reproduce.two_sample import (NO, NOT_SHOWN, SHOWN, TOO_FEW_RUNS, UNTESTED, TwoSampleTest, holm,
                                                  welch_greater)


def test_the_reading_ladder() -> None:
    assert TwoSampleTest((0.95, 0.96, 0.97), (0.90, 0.91, 0.92)).reading(0.05) == SHOWN
    noisy = TwoSampleTest((0.90, 0.99, 0.80), (0.85, 0.95, 0.80))
    assert noisy.reading(0.01) == UNTESTED and noisy.power(0.01) < 0.8
    assert noisy.reading() == NOT_SHOWN  # without an effect to power against there is no "untested"
    tight = tuple(0.95 + 0.001 * i for i in range(6))
    assert TwoSampleTest(tight, tuple(v + 0.0005 for v in tight)).reading(0.05) == NO  # powered and behind
    assert TwoSampleTest(tuple(v + 0.0005 for v in tight), tight).reading(0.05) == NOT_SHOWN  # ahead, not enough
    assert TwoSampleTest((0.9,), (0.8, 0.7)).reading(0.05) == TOO_FEW_RUNS


def test_the_power_is_the_test_as_run() -> None:
    """Unequal sides and spreads are powered as they are tested (each side's spread, Welch df), more runs on one
    side add power, and the power is the rate at which the Welch test detects the effect."""
    rng = np.random.default_rng(0)
    a, b = tuple(rng.normal(0.9, 0.03, 6)), tuple(rng.normal(0.9, 0.01, 10))
    test = TwoSampleTest(a, b)
    spread_a, spread_b = float(np.std(a, ddof=1)), float(np.std(b, ddof=1))
    assert test.power(0.03) == pytest.approx(power_of(0.03, spread_a, 6, 0.05, 10, spread_b))
    assert TwoSampleTest(a, b[:6]).power(0.03) < test.power(0.03) < 1.0
    draws = [welch_greater(list(rng.normal(0.93, spread_a, 6)), list(rng.normal(0.9, spread_b, 10)))[2] < 0.05
             for _ in range(4000)]
    assert abs(np.mean(draws) - test.power(0.03)) < 0.03


def test_a_pooled_spread_would_overstate_the_power_when_spreads_differ() -> None:
    """The Ultimate (150) claim (ii) spreads, 5 seeds a side: Welch df 5.3, not 8."""
    pooled = float(np.sqrt((0.0332 ** 2 + 0.0135 ** 2) / 2))
    assert power_of(0.0373, 0.0332, 5, std_other=0.0135) == pytest.approx(0.645, abs=0.005)
    assert power_of(0.0373, pooled, 5) == pytest.approx(0.684, abs=0.005)  # df = 2n - 2: equal spreads only
    assert power_of(0.0373, 0.02, 5) == power_of(0.0373, 0.02, 5, 0.05, 5, 0.02)


def test_holm_keeps_the_order_and_leaves_missing_out() -> None:
    assert holm([0.01, None, 0.04, 0.03]) == pytest.approx([0.03, None, 0.06, 0.06])
    assert holm([0.5, 0.9]) == [1.0, 1.0]
    assert holm([]) == []
