"""How well declared rows x cols grids are read from generated photos, with 3x3 beside them as the reference.

Run by hand: `python bench/declared_grid_reading.py [--frames 200] [--sequences 60] [--grids 3x3,4x4,6x7] [--skip 0]`.
Prints, per grid and photo quality (clean, harsh), how many boards `read_page` returns exactly (with a 95%
Wilson interval), the cells read right and the photos where no sheet or grid was found; then, per grid, the
move recogniser on drawing sequences (right move, reported from a frame showing the hand, wrong, missed).

The photos and sequences follow the rule of `ncbot vision eval`'s held-out figures: seeds no one tuned or
trained on (`ncbot.vision.data.DECLARED_SEED`, + 100,000 x rows + 10,000 x cols per grid) and the held-out
handwriting ("sketch", "hershey", `ncbot.vision.strokes.HELDOUT_STYLES`), which the classifier never saw.
`--skip N` starts each part N seeds later: a change to the reader found by looking at the first photos' failures
is judged on photos nobody has looked at (e.g. `--skip 1000`).
"""
from __future__ import annotations

import argparse
import math
import os
import time

import cv2
import torch

from ncbot.vision.classifier import load_classifier
from ncbot.vision.classifier.inference import CellClassifier
from ncbot.vision.data import DECLARED_SEED
from ncbot.vision.data.frames import make_frame
from ncbot.vision.grid import read_page
from ncbot.vision.recogniser_eval import evaluate_sequences
from ncbot.vision.sheet import Grid, grid_label, grid_shape, parse_grid
from ncbot.vision.strokes import HELDOUT_STYLES

PART_OFFSET = {"clean": 0, "harsh": 3_000, "sequences": 6_000}  # each part has room for 3,000 seeds


def first_seed(grid: Grid, part: str) -> int:
    """The first seed of one grid's photos or sequences: blocks apart for every rows x cols and part."""
    rows, cols = grid_shape(grid)
    return DECLARED_SEED + 100_000 * rows + 10_000 * cols + PART_OFFSET[part]


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95% interval of a proportion k/n that stays inside [0, 1] near 0 and 1."""
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def read_photos(grid: Grid, quality: str, n: int, classifier: CellClassifier, skip: int = 0) -> dict:
    """Read n photos of one grid and quality (from the part's seed + skip): exact boards, cells right, failures,
    and the seeds read wrong."""
    seed = first_seed(grid, quality) + skip
    exact, cells_right, cells, failures, wrong = 0, 0, 0, 0, []
    for i in range(n):
        frame = make_frame(grid, seed + i, styles=HELDOUT_STYLES, conditions=quality)
        try:
            read = read_page(frame.image, grid, classifier).cells
        except ValueError:
            failures += 1
            read = [None] * len(frame.board)
        right = sum(a == b for a, b in zip(read, frame.board))
        exact += right == len(frame.board)
        cells_right += right
        cells += len(frame.board)
        if right < len(frame.board):
            wrong.append((seed + i, len(frame.board) - right if read[0] is not None else "no read"))
    return {"seed": seed, "n": n, "exact": exact, "cells_right": cells_right, "cells": cells,
            "failures": failures, "wrong": wrong}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="photos per grid and quality (<= 3000)")
    parser.add_argument("--sequences", type=int, default=60, help="drawing sequences per grid (<= 3000; 0: none)")
    parser.add_argument("--grids", default="3x3,4x4,6x7", help="comma list of 3, 9 or ROWSxCOLS")
    parser.add_argument("--qualities", default="clean,harsh", help="comma list of clean, harsh")
    parser.add_argument("--skip", type=int, default=0,
                        help="start each part this many seeds later (photos not looked at)")
    args = parser.parse_args()
    if not 1 <= args.frames <= 3000 or not 0 <= args.sequences <= 3000:
        parser.error("--frames must be 1..3000 and --sequences 0..3000 (each part's seed block holds 3,000)")
    if not 0 <= args.skip or args.skip + max(args.frames, args.sequences) > 3000:
        parser.error("--skip must be >= 0 and --skip + --frames (and + --sequences) at most 3000 "
                     "(each part's seed block)")
    grids = [parse_grid(g) for g in args.grids.split(",")]
    qualities = [q.strip() for q in args.qualities.split(",")]
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    classifier = load_classifier()
    start = time.perf_counter()
    print(f"handwriting {'+'.join(HELDOUT_STYLES)} (held out); seeds from DECLARED_SEED = {DECLARED_SEED}")
    print("| grid | photos | seeds | boards exact (95% CI) | cells right | no sheet/grid |")
    print("|---|---|---|---|---|---|")
    wrong_lists = []
    for grid in grids:
        for quality in qualities:
            r = read_photos(grid, quality, args.frames, classifier, args.skip)
            low, high = wilson(r["exact"], r["n"])
            print(f"| {grid_label(grid)} | {quality} | {r['seed']}.. | {r['exact']}/{r['n']} = {r['exact'] / r['n']:.3f} "
                  f"[{low:.3f}, {high:.3f}] | {r['cells_right'] / r['cells']:.4f} | {r['failures']} |", flush=True)
            wrong_lists.append(f"{grid_label(grid)} {quality}: " + (", ".join(f"{s} ({k})" for s, k in r["wrong"]) or "none"))
    print("\nboards read wrong, seed (cells wrong):")
    print("\n".join(f"- {line}" for line in wrong_lists))
    if args.sequences:
        print("\n| grid | sequences | seeds | right move | right within 3 clean frames | reported from a hand frame "
              "| wrong | missed |")
        print("|---|---|---|---|---|---|---|---|")
        failures = []
        for grid in grids:
            s = evaluate_sequences(grid, args.sequences, first_seed(grid, "sequences") + args.skip, HELDOUT_STYLES,
                                   classifier)
            print(f"| {grid_label(grid)} | {s.sequences} | {s.seed}.. | {s.right}/{s.sequences} | "
                  f"{s.on_target}/{s.sequences} | {s.reported_from_hand_frame} | {s.wrong} | {s.missed} |", flush=True)
            failures += [f"- {grid_label(grid)} seed {f['seed']}: {f['problem']}" for f in s.failures]
        print("\nsequences off target:\n" + ("\n".join(failures) or "none"))
    print(f"\n{time.perf_counter() - start:.0f} s wall; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
