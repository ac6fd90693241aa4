"""The paper's cell classifier: a two-layer CNN whose output layer is a linear SVM over three labels.

40x40 -> conv 8 (5x5, pad 2) -> ReLU -> max-pool 2/2 -> conv 16 (5x5, pad 2) -> ReLU -> max-pool 3/3
-> linear (16*6*6 -> 3). Trained with the multi-class hinge loss (`nn.MultiMarginLoss`) and weight decay,
which is what makes the last layer an SVM rather than a softmax regression.
"""
from __future__ import annotations

import torch
from torch import nn

from ncbot.vision.labels import CELL_SIZE, LABELS


class BlockMaxPool(nn.MaxPool2d):
    """MaxPool2d(k, stride k) computed as a reshape + amax: the same numbers, several times faster on
    one CPU core for the 81-cell batches of a 9x9 board (that is where reading time went)."""

    def __init__(self, k: int) -> None:
        super().__init__(k, k)
        self.k = k

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n, c, h, w = x.shape
        k = self.k
        x = x[:, :, : h - h % k, : w - w % k]
        return x.reshape(n, c, h // k, k, w // k, k).amax(dim=(3, 5))


class CellCNN(nn.Module):
    """Scores (N, 3) for (nought, cross, nothing) from (N, 1, 40, 40) inputs."""

    def __init__(self) -> None:
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(1, 8, 5, padding=2), nn.ReLU(), BlockMaxPool(2),
            nn.Conv2d(8, 16, 5, padding=2), nn.ReLU(), BlockMaxPool(3),
        )
        side = CELL_SIZE // 2 // 3
        self.svm = nn.Linear(16 * side * side, len(LABELS))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.svm(self.features(x).flatten(1))


def svm_loss() -> nn.Module:
    """Multi-class hinge loss (Weston-Watkins, margin 1, as ConvNetJS' SVM layer): the SVM's objective."""
    return nn.MultiMarginLoss(margin=1.0)
