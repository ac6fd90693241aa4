"""The paper's cell classifier: a two-layer CNN whose output layer is a linear SVM over three labels.

40x40 -> conv 8 (5x5, pad 2) -> ReLU -> max-pool 2/2 -> conv 16 (5x5, pad 2) -> ReLU -> max-pool 3/3
-> linear (16*6*6 -> 3). Trained with the multi-class hinge loss (`nn.MultiMarginLoss`) and weight decay,
which is what makes the last layer an SVM rather than a softmax regression.
"""
from __future__ import annotations

import torch
from torch import nn

from vision.labels import CELL_SIZE, LABELS


class CellCNN(nn.Module):
    """Scores (N, 3) for (nought, cross, nothing) from (N, 1, 40, 40) inputs."""

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(1, 8, 5, padding=2), nn.ReLU(), nn.MaxPool2d(2, 2),
            nn.Conv2d(8, 16, 5, padding=2), nn.ReLU(), nn.MaxPool2d(3, 3),
        )
        side = CELL_SIZE // 2 // 3
        self.svm = nn.Linear(16 * side * side, len(LABELS))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.svm(self.features(x).flatten(1))


def svm_loss() -> nn.Module:
    """Multi-class hinge loss (Weston-Watkins, margin 1, as ConvNetJS' SVM layer): the SVM's objective."""
    return nn.MultiMarginLoss(margin=1.0)
