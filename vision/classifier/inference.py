"""Loading weights and classifying batches of cells (the board reader calls this once per frame)."""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import torch

from ncbot.fileio import atomic_path
from ncbot.vision.classifier.model import CellCNN
from ncbot.vision.classifier.preprocess import to_gray_cell, to_input
from ncbot.vision.labels import LABELS

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
    expected = "expected the {state_dict, meta} file `ncbot vision train` writes"
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # truncated, not torch, or pickled objects: say which file, not a pickle traceback
        reason = next((line.strip() for line in str(error).splitlines() if line.strip()), "")[:200]
        if "Weights only load failed" in reason:  # torch's advice (turn weights_only off) is the unsafe one
            reason = "not a tensors-only torch file; ncbot never unpickles Python objects"
        raise ValueError(f"classifier weights {path} could not be loaded ({type(error).__name__}: {reason}); {expected}") from None
    if not isinstance(blob, dict) or not isinstance(blob.get("state_dict"), dict):
        raise ValueError(f"classifier weights {path} hold no 'state_dict'; {expected}")
    model = CellCNN()
    missing, unexpected = model.state_dict().keys() - blob["state_dict"].keys(), blob["state_dict"].keys() - model.state_dict().keys()
    if missing or unexpected:
        raise ValueError(f"classifier weights {path} are not a CellCNN's (missing {sorted(missing)[:3]}, unexpected "
                         f"{sorted(unexpected)[:3]}); {expected}")
    try:
        model.load_state_dict(blob["state_dict"])
    except RuntimeError as error:  # right names, wrong shapes: another network's weights
        shapes = " ".join(str(error).split())
        raise ValueError(f"classifier weights {path} do not fit the CellCNN ({shapes}); {expected}") from None
    return CellClassifier(model)


def weights_meta(path: str | Path | None = None) -> dict[str, str | int | float]:
    """The metadata `save_weights` stored with the weights (default: the shipped ones), e.g. "n_training_cells":
    how many labelled cells they were trained on; one-line ValueError for a file without it."""
    path = Path(path) if path is not None else DEFAULT_WEIGHTS
    if not path.is_file():
        raise FileNotFoundError(f"classifier weights {path} do not exist")
    blob = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(blob, dict) or not isinstance(blob.get("meta"), dict):
        raise ValueError(f"classifier weights {path} hold no 'meta' (expected the file `ncbot vision train` writes)")
    return dict(blob["meta"])


@functools.lru_cache(maxsize=1)
def _default_classifier() -> CellClassifier:
    return _load(DEFAULT_WEIGHTS)
