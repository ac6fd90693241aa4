"""Training the cell CNN with the SVM hinge loss.

Noughts and crosses keep their label under flips, quarter turns and small shifts, so training draws
those augmentations per batch: a few hundred cells then behave like many more (the paper's data set was
only 109 / 201 photos).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from dataclasses import dataclass

import numpy as np
import torch

from ncbot.vision.classifier.model import CellCNN, svm_loss
from ncbot.vision.classifier.preprocess import to_input


@dataclass
class FitConfig:
    """Hyper-parameters of one fit of the cell classifier (defaults: the shipped weights)."""

    epochs: int = 30           # passes over the training cells
    batch_size: int = 64       # cells per update
    lr: float = 3e-3           # Adam learning rate (cosine-decayed to 5% over training)
    weight_decay: float = 1e-4 # L2 on all weights: the SVM's margin regulariser
    augment: bool = True       # flips, quarter turns and +-2 px shifts per batch
    seed: int = 0              # initial weights, batch order and augmentations


def _augment(x: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    k = int(torch.randint(4, (1,), generator=generator))
    x = torch.rot90(x, k, dims=(2, 3))
    if bool(torch.randint(2, (1,), generator=generator)):
        x = torch.flip(x, dims=(3,))
    dy, dx = (int(v) for v in torch.randint(-2, 3, (2,), generator=generator))
    return torch.roll(x, shifts=(dy, dx), dims=(2, 3))


def fit(images: np.ndarray, labels: np.ndarray, config: FitConfig = FitConfig(),
        progress: Callable[..., Any] | None = None, description: str = "train cells",
        model: CellCNN | None = None) -> CellCNN:
    """Train a fresh CellCNN (or go on training `model`, in place) on uint8 (N, 40, 40) cells and int labels (N,);
    same seed -> same weights."""
    if len(images) != len(labels) or len(images) == 0:
        raise ValueError(f"need as many labels as images (and at least one); got {len(images)} images, {len(labels)} labels")
    torch.manual_seed(config.seed)
    generator = torch.Generator().manual_seed(config.seed)
    model = CellCNN() if model is None else model
    inputs = to_input(images)
    targets = torch.as_tensor(labels, dtype=torch.long)
    optimiser = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    steps_per_epoch = max(1, -(-len(inputs) // config.batch_size))
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, config.epochs * steps_per_epoch, eta_min=config.lr * 0.05)
    loss_fn = svm_loss()
    model.train()
    epochs = range(config.epochs)
    for _ in progress(epochs, desc=description, unit="epoch", leave=False) if progress else epochs:
        order = torch.randperm(len(inputs), generator=generator)
        for start in range(0, len(inputs), config.batch_size):
            batch = order[start:start + config.batch_size]
            x = inputs[batch]
            if config.augment:
                x = _augment(x, generator)
            loss = loss_fn(model(x), targets[batch])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
    model.eval()
    return model
