"""Training candidates for the cell classifier, judged on the TUNING-STYLE split (docs/vision.md).

    python bench/studies/vision_style_candidates.py crops DIR [N9] [N3]     cut every scored set's reader crops once
    python bench/studies/vision_style_candidates.py base DIR                cache the shipped recipe's generated + photo cells
    python bench/studies/vision_style_candidates.py train DIR NAME [--harsh N] [--harsh-styles pen,hasty]
                                            [--cell-styles pen] [--epochs E] [--streak-photo-cells 0.5]
    python bench/studies/vision_style_candidates.py score DIR W.pt [W.pt ...]
    python bench/studies/vision_style_candidates.py styles OUT.png          the five handwriting styles, clean and harsh cells

Scored sets, every candidate classifying the same crops (`ncbot.vision.grid.extract_cells`, then
`cell_probabilities` as `read_page` does; unread photos count as all cells wrong):
- tuning view: harsh photos from HARSH_TUNING_SEED + 100,000 x grid + 50,000 with "marker" marks (the tuning
  handwriting, never trained on), 9x9 and 3x3; harsh "marker" cells from HARSH_TUNING_SEED + 500,000;
- the tuning split of the reader (pen marks, HARSH_TUNING_SEED + 100,000 x grid, photos 0..N-1);
- the clean sets quoted throughout docs/vision.md (`vision eval --what cells,reading --frames 60`), which
  must not get worse.
Never cuts HARSH_HELDOUT_SEED photos: the held-out harsh split is evaluated with `ncbot vision eval --what
harsh` only, once, after a candidate is chosen.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np
import torch

from ncbot.vision.classifier import FitConfig, fit, load_classifier, save_weights
from ncbot.vision.data import HARSH_TUNING_SEED, HARSH_TUNING_STYLE_OFFSET, TEST_SEED
from ncbot.vision.data.cells import make_cells
from ncbot.vision.data.frames import make_frame
from ncbot.vision.data.harsh_cells import make_harsh_cells
from ncbot.vision.grid import cell_probabilities, extract_cells
from ncbot.vision.labels import LABELS
from ncbot.vision.training import DefaultTraining, frame_cells

TUNING_STYLE_OFFSET = HARSH_TUNING_STYLE_OFFSET  # beside the pen tuning photos of the same grid
TUNING_CELL_SEED = HARSH_TUNING_SEED + 500_000
_INDEX = {"x": LABELS.index("cross"), "o": LABELS.index("nought"), "": LABELS.index("nothing")}


def photo_crops(grid: int, n: int, seed: int, styles: tuple[str, ...], conditions: str) -> dict[str, np.ndarray]:
    """Reader crops + truth of n photos; an unread photo gets blank crops marked unread (scored as wrong)."""
    cells, truth, read = [], [], []
    for i in range(n):
        frame = make_frame(grid, seed + i, styles=styles, conditions=conditions)
        truth.extend(_INDEX[s] for s in frame.board)
        try:
            cells.append(extract_cells(frame.image, grid).cell_images)
            read.extend([True] * grid * grid)
        except ValueError:
            cells.append(np.full((grid * grid, 40, 40), 255, np.uint8))
            read.extend([False] * grid * grid)
    return {"cells": np.concatenate(cells), "truth": np.array(truth), "read": np.array(read), "grid": np.array(grid)}


def true_crossing_crops(grid: int, n: int, seed: int, styles: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Cells cut at the photos' TRUE grid-line crossings (as bench/studies/vision_harsh_diagnose.py: the classifier's
    part alone, the reader's geometry errors left out)."""
    from ncbot.vision.data.frames import random_board, random_scene, render
    from ncbot.vision.grid import DEFAULT_RHO, cut_cells
    from ncbot.vision.illumination import balance_frame

    cells, truth = [], []
    for i in range(n):
        rng = np.random.default_rng(seed + i)
        scene = random_scene(grid, rng, 640, 480, styles, "harsh")
        board = random_board(grid, rng)
        image = render(scene, board, rng)
        cells.append(cut_cells(balance_frame(image), scene.grid_crossings(), grid, DEFAULT_RHO[grid])[0])
        truth.extend(_INDEX[s] for s in board)
    return {"cells": np.concatenate(cells), "truth": np.array(truth), "read": np.ones(len(truth), bool), "grid": np.array(grid)}


def crop_sets(n9: int, n3: int) -> dict[str, dict[str, np.ndarray]]:
    sets = {}
    for grid, n in ((9, n9), (3, n3)):
        base = HARSH_TUNING_SEED + 100_000 * grid
        sets[f"tune_marker_{grid}"] = photo_crops(grid, n, base + TUNING_STYLE_OFFSET, ("marker",), "harsh")
        sets[f"tune_pen_{grid}"] = photo_crops(grid, n, base, ("pen",), "harsh")
        print(f"{grid}x{grid} harsh tuning photos cut", flush=True)
    sets["tune_marker_9_true"] = true_crossing_crops(9, n9, HARSH_TUNING_SEED + 900_000 + TUNING_STYLE_OFFSET, ("marker",))
    sets["tune_pen_9_true"] = true_crossing_crops(9, n9, HARSH_TUNING_SEED + 900_000, ("pen",))
    images, labels = make_harsh_cells(900, TUNING_CELL_SEED, styles=("marker",))
    sets["tune_marker_cells"] = {"cells": images, "truth": labels, "read": np.ones(len(labels), bool), "grid": np.array(0)}
    for grid in (3, 9):  # the clean reading sets of `vision eval --what reading --frames 60`
        for name, styles in (("pen", ("pen",)), ("heldout", ("sketch", "hershey"))):
            sets[f"clean_{name}_{grid}"] = photo_crops(grid, 60, TEST_SEED + 50_000, styles, "clean")
        print(f"{grid}x{grid} clean photos cut", flush=True)
    for offset, style in enumerate(("pen", "sketch", "hershey")):  # `vision eval --what cells`
        images, labels = make_cells(600, TEST_SEED + offset, noisy_fraction=0.5, styles=(style,))
        sets[f"cells_{style}"] = {"cells": images, "truth": labels, "read": np.ones(len(labels), bool), "grid": np.array(0)}
    return sets


def score(classifier, crops: dict[str, np.ndarray]) -> dict[str, float]:
    grid = int(crops["grid"])
    if grid == 0:
        pred = classifier.predict(crops["cells"])
        wrong = pred != crops["truth"]
        return {"cells": 1 - wrong.mean(), "wrong": int(wrong.sum()),
                "nought_as_cross": int(((crops["truth"] == 0) & (pred == 1)).sum())}
    per = grid * grid
    preds = np.concatenate([cell_probabilities(classifier, crops["cells"][k:k + per]).argmax(1)
                            for k in range(0, len(crops["cells"]), per)])
    wrong = (preds != crops["truth"]) | ~crops["read"]
    boards = wrong.reshape(-1, per).any(1)
    return {"cells": 1 - wrong.mean(), "wrong": int(wrong.sum()), "boards": 1 - boards.mean(),
            "nought_as_cross": int(((crops["truth"] == 0) & (preds == 1) & crops["read"]).sum())}


def streaked(cells: np.ndarray, share: float, seed: int) -> np.ndarray:
    """A share of reader-cut 9x9 cells streaked as a harsh photo's motion blur would (1-7 frame px, a 9x9 cell
    being ~26 frame px per 40 cell px), with sensor noise: the harsh streak on real reader crops."""
    from ncbot.vision.data.conditions import HARSH, motion_kernel

    rng = np.random.default_rng(seed)
    out = cells.copy()
    for i in np.flatnonzero(rng.random(len(cells)) < share):
        kernel = motion_kernel(float(rng.uniform(*HARSH.motion_px)) * 40 / 26, float(rng.uniform(0, np.pi)))
        blurred = cv2.filter2D(cells[i].astype(np.float32), -1, kernel, borderType=cv2.BORDER_REFLECT)
        blurred += rng.normal(0, rng.uniform(*HARSH.noise_sigma), blurred.shape)
        out[i] = np.clip(np.round(blurred), 0, 255).astype(np.uint8)
    return out


def styles_png(path: Path) -> None:
    """Rows: each style's clean cells, then the same style's harsh cells (8 noughts, 8 crosses each)."""
    rows = []
    for style in ("pen", "hasty", "marker", "sketch", "hershey"):
        for make in (lambda: make_cells(48, TEST_SEED + 990_000, styles=(style,)),
                     lambda: make_harsh_cells(48, TEST_SEED + 990_000, styles=(style,))):
            images, labels = make()
            pick = np.concatenate([np.flatnonzero(labels == k)[:8] for k in (0, 1)])
            rows.append(np.hstack([np.pad(images[i], 1, constant_values=128) for i in pick]))
    image = cv2.resize(np.vstack(rows), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
    label_w = 150
    canvas = np.full((image.shape[0], image.shape[1] + label_w), 255, np.uint8)
    canvas[:, label_w:] = image
    for k, style in enumerate(("pen", "hasty", "marker", "sketch", "hershey")):
        role = {"pen": "training", "hasty": "training", "marker": "TUNING", "sketch": "held out", "hershey": "held out"}[style]
        for j, kind in enumerate(("clean", "harsh")):
            y = (2 * k + j) * 84 + 48
            cv2.putText(canvas, f"{style} {kind}", (4, y - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, 0, 1, cv2.LINE_AA)
            cv2.putText(canvas, role, (4, y + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.45, 90, 1, cv2.LINE_AA)
    cv2.imwrite(str(path), canvas, [cv2.IMWRITE_PNG_COMPRESSION, 9])


def main() -> None:
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    parser = argparse.ArgumentParser()
    parser.add_argument("what", choices=("crops", "base", "train", "score", "styles"))
    parser.add_argument("dir", type=Path)
    parser.add_argument("rest", nargs="*")
    parser.add_argument("--harsh", type=int, default=8_000)
    parser.add_argument("--harsh-styles", default="pen")
    parser.add_argument("--cell-styles", default="pen")
    parser.add_argument("--epochs", type=int, default=14)
    parser.add_argument("--streak-photo-cells", type=float, default=0.0,
                        help="share of the reader-cut 9x9 photo cells replaced by a motion-streaked copy")
    args = parser.parse_args()
    if args.what == "styles":
        styles_png(args.dir)
        return
    args.dir.mkdir(parents=True, exist_ok=True)
    start = time.process_time()
    if args.what == "crops":
        n9, n3 = (int(v) for v in (args.rest + ["100", "100"])[:2])
        sets = crop_sets(n9, n3)
        np.savez_compressed(args.dir / "crops.npz", **{f"{k}/{f}": v for k, d in sets.items() for f, v in d.items()})
    elif args.what == "base":
        c = DefaultTraining()
        f3, l3 = frame_cells(3, c.n_frames_3, c.seed + 100_000)
        f9, l9 = frame_cells(9, c.n_frames_9, c.seed + 200_000)
        np.savez_compressed(args.dir / "base.npz", f3=f3, l3=l3, f9=f9, l9=l9)
    elif args.what == "train":
        c = DefaultTraining()
        base = np.load(args.dir / "base.npz")
        cell_styles = tuple(args.cell_styles.split(","))
        if cell_styles == ("pen",) and "cells" in base:
            cells, labels = base["cells"], base["labels"]
        else:
            cells, labels = make_cells(c.n_cells, c.seed, noisy_fraction=0.6, styles=cell_styles)
        harsh, harsh_labels = make_harsh_cells(args.harsh, c.seed + 300_000, styles=tuple(args.harsh_styles.split(",")))
        f9 = base["f9"]
        if args.streak_photo_cells > 0:
            f9 = streaked(f9, args.streak_photo_cells, c.seed + 400_000)
        images = np.concatenate([cells, base["f3"], f9, harsh])
        targets = np.concatenate([labels, base["l3"], base["l9"], harsh_labels])
        print(f"{len(images)} training cells, data {time.process_time() - start:.0f} CPU s", flush=True)
        model = fit(images, targets, FitConfig(epochs=args.epochs, batch_size=64, lr=3e-3, seed=0))
        save_weights(model, args.dir / f"{args.rest[0]}.pt", {"harsh": args.harsh, "harsh_styles": args.harsh_styles,
                                                              "streak_photo_cells": args.streak_photo_cells,
                                                              "cell_styles": args.cell_styles, "epochs": args.epochs})
    else:
        data = np.load(args.dir / "crops.npz")
        names = sorted({k.split("/")[0] for k in data.files})
        sets = {n: {f: data[f"{n}/{f}"] for f in ("cells", "truth", "read", "grid")} for n in names}
        for path in args.rest:
            classifier = load_classifier(path)
            print(path)
            for n in names:
                s = score(classifier, sets[n])
                extra = f" boards {100 * s['boards']:.1f}%" if "boards" in s else ""
                print(f"  {n:20s} cells {100 * s['cells']:.2f}% wrong {s['wrong']:4d} o->x {s['nought_as_cross']:3d}{extra}")
    print(f"{args.what}: {time.process_time() - start:.0f} CPU s", flush=True)


if __name__ == "__main__":
    main()
