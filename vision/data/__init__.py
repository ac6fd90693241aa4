"""Seeded synthetic data for the vision stack: cells (clean / noisy) and whole camera frames.

Seeds are fixed per purpose so that test data never overlaps training data: the paper-style sets use
CLEAN_SEED / NOISY_SEED, default weights train from TRAIN_SEED upwards, tests draw from TEST_SEED upwards.
"""
from __future__ import annotations

CLEAN_SEED = 109_000      # the "clean" set (paper: 109 images)
NOISY_SEED = 201_000      # the "noisy" set (paper: 201 images)
TRAIN_SEED = 1_000_000    # the large varied set the shipped weights are trained on
BUDGET_SEED = TRAIN_SEED + 500_000  # data-budget draws (vision.budget): training style, + 10,000 per draw seed
TEST_SEED = 9_000_000     # held-out cells and frames used by tests and the reading figures
# the reader that learns from play (vision.online): training-style cells an update is checked on (never trained on),
# and the cells a person's handwriting is scored on when it is not one of the budget's held-out styles (+ a hash
# of the style's name); only evaluated
REHEARSAL_CHECK_SEED = TRAIN_SEED + 800_000
STYLE_CHECK_SEED = TEST_SEED + 5_000_000
N_CLEAN, N_NOISY = 109, 201
# "harsh" photo conditions (vision.data.conditions): the reader was tuned on TUNING photos with "pen" marks
# only; its figures come from HELDOUT photos (other seeds, so other shadows, casts, lenses) with the held-out
# "sketch" and "hershey" handwriting, never looked at while tuning
HARSH_TUNING_SEED = TEST_SEED + 2_000_000
HARSH_HELDOUT_SEED = TEST_SEED + 3_000_000
# the TUNING-STYLE split: harsh photos from HARSH_TUNING_SEED + 100,000 x grid + this offset with the tuning
# handwriting ("marker", vision.strokes.TUNING_STYLES): training choices are judged on it, so handwriting the
# classifier never saw can be measured without looking at the held-out styles or seeds
HARSH_TUNING_STYLE_OFFSET = 50_000
# photos and drawing sequences of declared rows x cols grids (and 3x3 beside them), only ever measured
# (bench/declared_grid_reading.py): DECLARED_SEED + 100,000 x rows + 10,000 x cols, + 0 clean photos,
# + 3,000 harsh photos, + 6,000 sequences, with the held-out handwriting; never tuned or trained on
DECLARED_SEED = TEST_SEED + 4_000_000
