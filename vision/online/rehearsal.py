"""The reader's own training cells, rehearsed in every update so that learning a person's hand does not make it
forget the handwriting it was trained on, and a set of training-style cells every update is checked on.

Which cells: a classifier trained on a data budget (`ncbot vision train --budget N`, its weights' meta names the
budget and its seed) gets exactly its N training cells back (`ncbot.vision.budget.training_set`); any other weights
(the shipped ones, or unknown) get cells drawn from the shipped recipe's generator and seed in its "pen" style, the
kind of cell they were trained on.
"""
from __future__ import annotations

import numpy as np

from ncbot.vision.data import REHEARSAL_CHECK_SEED, TRAIN_SEED
from ncbot.vision.data.cells import make_cells

GENERATED_REHEARSAL = 2_000  # cells drawn when the weights do not name their training cells
CHECK_CELLS = 300            # training-style cells each update is checked on


def rehearsal_cells(meta: dict) -> tuple[np.ndarray, np.ndarray, str]:
    """(images, labels, where they come from) of the cells the weights described by `meta` were trained on."""
    if "budget_images" in meta and "budget_seed" in meta:
        from ncbot.vision.budget import training_set

        images, labels, _ = training_set(int(meta["budget_images"]), int(meta["budget_seed"]))
        return images, labels, f"its {len(labels)} budget training cells (seed {int(meta['budget_seed'])})"
    images, labels = make_cells(GENERATED_REHEARSAL, TRAIN_SEED, noisy_fraction=0.6, styles=("pen",))
    return images, labels, f"{GENERATED_REHEARSAL} generated training-style cells"


def check_cells(n: int = CHECK_CELLS) -> tuple[np.ndarray, np.ndarray]:
    """Training-style ("pen") cells, half noisy, that no classifier is trained on: an update that forgets shows here."""
    return make_cells(n, REHEARSAL_CHECK_SEED, noisy_fraction=0.5, styles=("pen",))
