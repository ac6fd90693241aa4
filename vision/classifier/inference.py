"""Loading weights and classifying batches of cells (the board reader calls this once per frame)."""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import torch

from fileio import atomic_path
from vision.classifier.model import CellCNN
from vision.classifier.preprocess import to_gray_cell, to_input
from vision.labels import LABELS

DEFAULT_WEIGHTS = Path(__file__).resolve().parent.parent / "weights" / "cell_cnn.pt"


class CellClassifier:
    """A trained CellCNN with numpy in/out: SVM scores, softmax probabilities, labels."""

    def __init__(self, model: CellCNN) -> None:
        self.model = model.eval()

    @torch.no_grad()
    def scores(self, cells: np.ndarray) -> np.ndarray:
        """uint8 (N, 40, 40) gray cells -> float32 (N, 3) SVM scores (nought, cross, nothing)."""
        if len(cells) == 0:
            return np.zeros((0, len(LABELS)), np.float32)
        return self.model(to_input(cells)).numpy()

    def probabilities(self, cells: np.ndarray) -> np.ndarray:
        """Softmax over the SVM scores: the per-cell label probabilities Algorithm 1 sums over frames."""
        s = self.scores(cells)
        e = np.exp(s - s.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)

    def predict(self, cells: np.ndarray) -> np.ndarray:
        """Label index per cell, int64 (N,)."""
        return self.scores(cells).argmax(axis=1)

    def classify_image(self, image: np.ndarray) -> tuple[str, list[float]]:
        """One crop of any size and colour -> (label name, 3 scores)."""
        s = self.scores(to_gray_cell(image)[None])[0]
        return LABELS[int(s.argmax())], [float(v) for v in s]


def save_weights(model: CellCNN, path: str | Path, meta: dict[str, str | int | float] | None = None) -> Path:
    """Write {state_dict, meta} atomically (`fileio`), so a crash never leaves half a file."""
    with atomic_path(path) as temp:
        torch.save({"state_dict": model.state_dict(), "meta": dict(meta or {})}, temp)
    return Path(path)


def load_classifier(path: str | Path | None = None) -> CellClassifier:
    """Load weights saved by `save_weights` (default: the shipped ones), with weights_only=True."""
    if path is None:
        return _default_classifier()
    return _load(Path(path))


def _load(path: Path) -> CellClassifier:
    if not path.is_file():
        raise FileNotFoundError(f"classifier weights {path} do not exist; train them with `ncbot vision train --out {path}`")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
        model = CellCNN()
        model.load_state_dict(blob["state_dict"])
    except Exception as error:  # a truncated or foreign file: say which file, not a pickle traceback
        raise ValueError(f"classifier weights {path} are not a CellCNN checkpoint ({type(error).__name__}: {error})") from None
    return CellClassifier(model)


@functools.lru_cache(maxsize=1)
def _default_classifier() -> CellClassifier:
    return _load(DEFAULT_WEIGHTS)
