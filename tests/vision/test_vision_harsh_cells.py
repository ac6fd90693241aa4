"""Harsh training cells (vision.data.harsh_cells): seeded and balanced, a longer streak blurs the stroke more,
and the shipped weights, trained with them, read harsh cells of unseen seeds that the earlier weights missed."""
from __future__ import annotations

import numpy as np

from ncbot.vision.classifier import load_classifier
from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.conditions import HarshRanges
from ncbot.vision.data.harsh_cells import harsh_cell, make_harsh_cells
from ncbot.vision.labels import LABELS
from ncbot.vision.training import DefaultTraining


def test_same_seed_same_cells_and_balanced_labels() -> None:
    images, labels = make_harsh_cells(30, seed=TEST_SEED + 810_000)
    again, again_labels = make_harsh_cells(30, seed=TEST_SEED + 810_000)
    other, _ = make_harsh_cells(30, seed=TEST_SEED + 810_001)
    assert images.shape == (30, 40, 40) and images.dtype == np.uint8
    assert np.array_equal(images, again) and np.array_equal(labels, again_labels)
    assert not np.array_equal(images, other)
    assert np.bincount(labels, minlength=len(LABELS)).tolist() == [10, 10, 10]


def test_a_longer_motion_streak_leaves_a_fainter_stroke() -> None:
    # the same cell (same draws) with a 1 px and a 7 px streak: the streak spreads the ink, its darkest
    # pixels come closer to the paper, which is what the network must learn to read
    contrast = {}
    for length in (1.0, 7.0):
        ranges = HarshRanges(motion_px=(length, length), exposure=(1.0, 1.0), noise_sigma=(0.0, 0.0), jpeg_quality=(95, 95))
        cells = [harsh_cell(LABELS.index("cross"), np.random.default_rng(TEST_SEED + 820_000 + k), ranges=ranges)
                 for k in range(12)]
        contrast[length] = np.mean([np.median(c) - np.percentile(c, 1) for c in cells])
    assert contrast[7.0] < 0.8 * contrast[1.0]


def test_shipped_weights_read_streaked_cells_of_unseen_seeds() -> None:
    assert DefaultTraining().n_harsh_cells > 0  # the shipped recipe includes them (vision/training.py)
    images, labels = make_harsh_cells(300, seed=TEST_SEED + 830_000, ranges=HarshRanges(motion_px=(5.0, 7.0)))
    right = float((load_classifier().predict(images) == labels).mean())
    # 5-7 px streaks: the weights shipped before harsh cells read 96.7% of these (10 wrong), the same recipe
    # retrained without them 96.7% too; the weights with pen harsh cells 98.7% (4 wrong), and so do the shipped
    # ones, whose harsh cells are half "hasty"
    assert right >= 0.98, right
