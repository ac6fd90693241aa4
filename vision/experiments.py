"""The paper's three classifier experiments on our data, and the board-reading evaluation.

Paper (Sec. 2 of the notes): 99.9% leave-one-out on 109 clean cells; 74% trained clean -> tested noisy;
98.4% trained noisy -> tested clean. Leave-one-out here is exact: 109 trainings, each on 108 cells and
tested on the one left out. Every result comes with a confusion matrix as markdown and PNG.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ncbot.fileio import atomic_path, atomic_write_bytes, atomic_write_text
from ncbot.vision.classifier.inference import CellClassifier, load_classifier
from ncbot.vision.classifier.train import FitConfig, fit
from ncbot.vision.data import (CLEAN_SEED, HARSH_HELDOUT_SEED, HARSH_TUNING_SEED, HARSH_TUNING_STYLE_OFFSET, N_CLEAN, N_NOISY,
                         NOISY_SEED, TEST_SEED)
from ncbot.vision.data.cells import make_cells
from ncbot.vision.data.frames import make_frame
from ncbot.vision.grid import read_page
from ncbot.vision.labels import LABELS
from ncbot.vision.sheet import Grid, grid_label
from ncbot.vision.strokes import TUNING_STYLES

PAPER_TRAIN = FitConfig(epochs=40, batch_size=16, lr=3e-3, weight_decay=1e-4, augment=True, seed=0)
HARSH_SPLITS = ("heldout", "tuning", "tuning-style")  # `harsh_reading`'s photo sets


@dataclass
class Result:
    """One experiment: accuracy and the confusion matrix (rows = true label, columns = predicted)."""

    name: str
    accuracy: float
    confusion: np.ndarray
    n: int
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"name": self.name, "accuracy": self.accuracy, "n": self.n,
                "confusion": self.confusion.tolist(), "labels": list(LABELS), **self.extra}


def confusion(truth: np.ndarray, predicted: np.ndarray, k: int = len(LABELS)) -> np.ndarray:
    """k x k counts: rows = true label, columns = predicted label."""
    matrix = np.zeros((k, k), np.int64)
    np.add.at(matrix, (np.asarray(truth), np.asarray(predicted)), 1)
    return matrix


def _result(name: str, truth: np.ndarray, predicted: np.ndarray, **extra) -> Result:
    truth, predicted = np.asarray(truth), np.asarray(predicted)
    return Result(name, float((truth == predicted).mean()), confusion(truth, predicted), len(truth), extra)


def leave_one_out(images: np.ndarray, labels: np.ndarray, config: FitConfig = PAPER_TRAIN,
                  progress: Callable[..., Any] | None = None) -> np.ndarray:
    """Prediction for each cell by a CNN trained on all the others (exact LOO: n trainings)."""
    predicted = np.empty(len(images), np.int64)
    keep = np.ones(len(images), bool)
    folds = range(len(images))
    for i in progress(folds, desc="leave-one-out", unit="fold") if progress else folds:
        keep[i] = False
        model = CellClassifier(fit(images[keep], labels[keep], config))
        predicted[i] = model.predict(images[i:i + 1])[0]
        keep[i] = True
    return predicted


def paper_experiments(config: FitConfig = PAPER_TRAIN, progress: Callable[..., Any] | None = None,
                      loo_folds: int | None = None) -> list[Result]:
    """LOO on clean, clean -> noisy, noisy -> clean (loo_folds < 109 runs only the first folds: tests)."""
    clean, clean_labels = make_cells(N_CLEAN, CLEAN_SEED)
    noisy, noisy_labels = make_cells(N_NOISY, NOISY_SEED, noisy=True)
    folds = N_CLEAN if loo_folds is None else loo_folds
    if folds < N_CLEAN:
        predicted = np.array([CellClassifier(fit(np.delete(clean, i, 0), np.delete(clean_labels, i), config))
                              .predict(clean[i:i + 1])[0] for i in range(folds)])
        loo = _result("leave-one-out, clean", clean_labels[:folds], predicted, folds=folds)
    else:
        loo = _result("leave-one-out, clean", clean_labels, leave_one_out(clean, clean_labels, config, progress))
    on_clean = CellClassifier(fit(clean, clean_labels, config))
    on_noisy = CellClassifier(fit(noisy, noisy_labels, config))
    return [loo,
            _result("train clean -> test noisy", noisy_labels, on_clean.predict(noisy)),
            _result("train noisy -> test clean", clean_labels, on_noisy.predict(clean))]


def heldout_cells(classifier: CellClassifier | None = None, n: int = 600, seed: int = TEST_SEED) -> list[Result]:
    """Shipped weights on unseen generated cells of the training style and of the two held-out styles."""
    classifier = classifier or load_classifier()
    results = []
    for offset, (name, styles) in enumerate((("pen (training style, unseen seeds)", ("pen",)),
                                             ("sketch (held-out style)", ("sketch",)),
                                             ("hershey fonts (held-out style)", ("hershey",)))):
        images, labels = make_cells(n, seed + offset, noisy_fraction=0.5, styles=styles)
        results.append(_result(f"cells: {name}", labels, classifier.predict(images)))
    return results


def reading(grid: Grid, n_frames: int, styles: tuple[str, ...], classifier: CellClassifier | None = None,
            seed: int = TEST_SEED + 50_000, progress: Callable[..., Any] | None = None,
            conditions: str = "clean") -> Result:
    """Read n generated photos: per-cell confusion, plus boards read entirely right and read failures
    (no sheet found / no grid found on it, counted apart)."""
    classifier = classifier or load_classifier()
    truth, predicted, whole, failures = [], [], 0, 0
    missing = {"no_page": 0, "no_grid": 0}
    name = "+".join(styles)
    frames = range(n_frames)
    for i in progress(frames, desc=f"read {grid_label(grid)} {name}", unit="photo", leave=False) if progress else frames:
        frame = make_frame(grid, seed + i, styles=styles, conditions=conditions)
        labels = [LABELS.index({"x": "cross", "o": "nought", "": "nothing"}[s]) for s in frame.board]
        try:
            probs = read_page(frame.image, grid, classifier).probabilities
            guess = probs.argmax(axis=1).tolist()
        except ValueError as error:
            failures += 1
            missing["no_page" if "no paper sheet" in str(error) else "no_grid"] += 1
            guess = [-1] * len(labels)
        whole += guess == labels
        truth.extend(labels)
        predicted.extend(guess)
    truth_a, pred_a = np.array(truth), np.array(predicted)
    read = pred_a >= 0
    where = "" if conditions == "clean" else f" {conditions}"
    result = _result(f"read {grid_label(grid)}{where} photos, {name} marks", truth_a[read], pred_a[read],
                     photos=n_frames, boards_right=whole / n_frames, read_failures=failures, **missing, seed=seed)
    result.accuracy = float((truth_a == pred_a).mean())  # failures count as wrong cells
    return result


def harsh_reading(n_frames: int, split: str = "heldout", classifier: CellClassifier | None = None,
                  progress: Callable[..., Any] | None = None) -> list[Result]:
    """Reading under the "harsh" photo conditions (vision.data.conditions), 3x3 and 9x9.

    split "tuning": the photos the reader was tuned on ("pen" marks only). split "tuning-style": tuning seeds
    beside those with the tuning handwriting ("marker"), on which training choices are judged. split
    "heldout": other seeds (other shadows, casts, lenses) and the held-out "sketch" + "hershey" handwriting
    (the figures), with "pen" marks on held-out seeds beside them.
    """
    if split not in HARSH_SPLITS:
        raise ValueError(f"split must be one of {', '.join(HARSH_SPLITS)}; got {split!r}")
    if split == "tuning":
        sets = [(grid, ("pen",), HARSH_TUNING_SEED + 100_000 * grid) for grid in (3, 9)]
    elif split == "tuning-style":
        sets = [(grid, TUNING_STYLES, HARSH_TUNING_SEED + 100_000 * grid + HARSH_TUNING_STYLE_OFFSET) for grid in (3, 9)]
    else:
        sets = [(grid, styles, HARSH_HELDOUT_SEED + 100_000 * grid + offset)
                for grid in (3, 9) for offset, styles in ((0, ("sketch", "hershey")), (50_000, ("pen",)))]
    classifier = classifier or load_classifier()
    return [reading(grid, n_frames, styles, classifier, seed, progress, conditions="harsh")
            for grid, styles, seed in sets]


def harsh_frames_png(path: Path, seeds: tuple[int, ...] = (0, 1, 2, 3, 4, 5), classifier: CellClassifier | None = None) -> None:
    """A few held-out harsh photos (3x3 then 9x9) with the true page (red), the page found (green), the
    grid found (blue) and how many cells were read right, so people can look at what the reader does."""
    import cv2

    classifier = classifier or load_classifier()
    tiles = []
    for k, offset in enumerate(seeds):
        grid = 3 if k < len(seeds) // 2 else 9
        frame = make_frame(grid, HARSH_HELDOUT_SEED + 100_000 * grid + offset, styles=("sketch", "hershey"),
                           conditions="harsh")
        image = frame.image.copy()
        cv2.polylines(image, [np.round(frame.page_corners).astype(np.int32)], True, (0, 0, 255), 1, cv2.LINE_AA)
        try:
            r = read_page(frame.image, grid, classifier)
        except ValueError as error:
            cv2.putText(image, str(error)[:60], (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 255), 1, cv2.LINE_AA)
        else:
            cv2.polylines(image, [np.round(r.page_corners).astype(np.int32)], True, (0, 255, 0), 2, cv2.LINE_AA)
            cv2.polylines(image, [np.round(r.grid_corners).astype(np.int32)], True, (255, 128, 0), 2, cv2.LINE_AA)
            wrong = [i for i, (a, b) in enumerate(zip(r.cells, frame.board)) if a != b]
            cv2.putText(image, f"{grid}x{grid}: {grid * grid - len(wrong)}/{grid * grid} cells right", (8, 20),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 255, 0) if not wrong else (0, 0, 255), 2, cv2.LINE_AA)
        tiles.append(cv2.resize(image, (360, 270), interpolation=cv2.INTER_AREA))
    columns = len(seeds) // 2
    mosaic = np.vstack([np.hstack(tiles[:columns]), np.hstack(tiles[columns:2 * columns])])
    ok, png = cv2.imencode(".png", mosaic)
    if not ok:
        raise ValueError(f"could not encode the harsh-frames figure for {path}")
    atomic_write_bytes(png.tobytes(), path)


def markdown(results: list[Result]) -> str:
    """A table of accuracies and one confusion matrix per result (row-normalised percentages)."""
    lines = ["| experiment | n | accuracy | extra |", "|---|---|---|---|"]
    for r in results:
        extra = ", ".join(f"{k} {v:.4f}" if isinstance(v, float) else f"{k} {v}" for k, v in r.extra.items())
        lines.append(f"| {r.name} | {r.n} | {100 * r.accuracy:.2f}% | {extra} |")
    for r in results:
        lines += ["", f"**{r.name}** (rows: true, columns: predicted; % of the row)", "",
                  "| true \\ predicted | " + " | ".join(LABELS) + " |", "|---" * (len(LABELS) + 1) + "|"]
        for label, row in zip(LABELS, r.confusion):
            total = max(row.sum(), 1)
            lines.append(f"| {label} | " + " | ".join(f"{100 * v / total:.1f}% ({v})" for v in row) + " |")
    return "\n".join(lines) + "\n"


def confusion_png(results: list[Result], path: Path) -> None:
    """All confusion matrices side by side, row-normalised, with counts."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(3.6 * len(results), 3.6), squeeze=False)
    for ax, r in zip(axes[0], results):
        rates = r.confusion / np.maximum(r.confusion.sum(axis=1, keepdims=True), 1)
        ax.imshow(rates, vmin=0, vmax=1, cmap="Blues")
        for (i, j), v in np.ndenumerate(r.confusion):
            ax.text(j, i, f"{100 * rates[i, j]:.1f}%\n({v})", ha="center", va="center", fontsize=8,
                    color="white" if rates[i, j] > 0.5 else "black")
        ax.set_xticks(range(len(LABELS)), LABELS, fontsize=8)
        ax.set_yticks(range(len(LABELS)), LABELS, fontsize=8)
        ax.set_xlabel("predicted")
        ax.set_ylabel("true")
        ax.set_title(f"{r.name}\n{100 * r.accuracy:.1f}% of {r.n}", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as temp:
        fig.savefig(temp, dpi=110, format="png")
    plt.close(fig)


def write_report(results: list[Result], out_dir: Path, stem: str) -> list[Path]:
    """<stem>.md, <stem>.png and <stem>.json in out_dir, each written atomically."""
    out_dir = Path(out_dir)
    md, png, js = out_dir / f"{stem}.md", out_dir / f"{stem}.png", out_dir / f"{stem}.json"
    atomic_write_text(markdown(results), md)
    confusion_png(results, png)
    atomic_write_text(json.dumps([r.to_json() for r in results], indent=1), js)
    return [md, png, js]
