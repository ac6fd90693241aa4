"""Where harsh-photo reading errors come from, counted by cause, on the TUNING split only (docs/vision.md).

    python bench/studies/vision_harsh_diagnose.py GRID N [START] [STYLES] [CROPS.png]      e.g. 9 200 0 pen

Every photo's true grid-line crossings are known (the generator's homography and lens), so each wrong cell
is put down to: page or grid not found; the fitted lattice > 0.15 cell off at one of the cell's corners (split
by whether the page's corners were found more than half a cell off: then the page finder, else the grid); a
smaller geometric error (right when cut at the true crossings); or the classifier (wrong even at the true
crossings). Also prints errors by motion-blur length, and with CROPS.png draws every wrong cell as the reader
cut it beside the same cell cut at the true crossings. Never run it on HARSH_HELDOUT_SEED.
"""
import sys, collections, json
import cv2, numpy as np
from ncbot.vision.data import HARSH_TUNING_SEED
from ncbot.vision.data.frames import random_scene, random_board, render
from ncbot.vision.grid import _grid_lines, cut_cells, PAGE_SIDE, DEFAULT_RHO
from ncbot.vision.illumination import balance_frame
from ncbot.vision.page import locate_balanced_page
from ncbot.vision.lattice import lattice
from ncbot.vision.labels import LABELS
from ncbot.vision.classifier import load_classifier
from ncbot.vision.grid import cell_probabilities
import torch; torch.set_num_threads(1)

grid = int(sys.argv[1]); n = int(sys.argv[2]); start = int(sys.argv[3]) if len(sys.argv) > 3 else 0
styles = tuple(sys.argv[4].split("+")) if len(sys.argv) > 4 else ("pen",)
crops_png = sys.argv[5] if len(sys.argv) > 5 else None
tiles = []
base = HARSH_TUNING_SEED + 100_000 * grid
clf = load_classifier()
rho = DEFAULT_RHO[grid]

def cut(frame, crossings):
    return cut_cells(frame, crossings, grid, rho)[0]

counts = collections.Counter(); conf = collections.Counter(); oconf = collections.Counter()
total = 0; per_photo = []
errs_geo = []; bym = {}
for i in range(start, start + n):
    seed = base + i
    rng = np.random.default_rng(seed)
    scene = random_scene(grid, rng, 640, 480, styles, "harsh")
    board = random_board(grid, rng)
    image = render(scene, board, rng)
    truth = np.array([LABELS.index({"x": "cross", "o": "nought", "": "nothing"}[s]) for s in board])
    total += len(truth)
    true_x = scene.grid_crossings()
    frame = balance_frame(image)
    oracle = cell_probabilities(clf, cut(frame, true_x)).argmax(1)
    corners, mask = locate_balanced_page(frame)
    why = None
    if corners is None:
        why = "no_page"
    else:
        ps = PAGE_SIDE[grid]
        sq = np.array([[0, 0], [ps, 0], [ps, ps], [0, ps]], np.float32)
        to_page = cv2.getPerspectiveTransform(corners, sq)
        pg = cv2.cvtColor(cv2.warpPerspective(frame, to_page, (ps, ps)), cv2.COLOR_BGR2GRAY)
        found = _grid_lines(pg, grid)
        if found is None:
            why = "no_grid"
    if why:
        counts[why] += len(truth); per_photo.append((i, why, len(truth)))
        continue
    xs, ys, ink = found
    cr = cv2.perspectiveTransform(lattice(ink, xs, ys, 3).reshape(1, -1, 2), np.linalg.inv(to_page)).reshape(grid+1, grid+1, 2)
    step = np.linalg.norm(true_x[0, -1] - true_x[0, 0]) / grid
    err = np.linalg.norm(cr - true_x, axis=-1) / step  # in cells
    cells = cut(frame, cr)
    pred = cell_probabilities(clf, cells).argmax(1)
    wrong = np.flatnonzero(pred != truth)
    page_off = np.linalg.norm(corners - scene.page_corners(), axis=-1).max() / step > 0.5
    if crops_png and len(wrong):
        true_cells = cut(frame, true_x)
        tiles += [np.hstack([cells[k], np.full((40, 2), 128, np.uint8), true_cells[k]]) for k in wrong]
    nw = 0
    for k in wrong:
        r, c = divmod(k, grid)
        e = err[r:r+2, c:c+2].max()
        if e > 0.15:
            cause = "geometry>0.15cell, page corners >0.5 cell off" if page_off else "geometry>0.15cell, page right"
        elif oracle[k] == truth[k]:
            cause = "geometry-small(oracle right)"
        else:
            cause = "classifier(oracle wrong too)"
        counts[cause] += 1; conf[(LABELS[truth[k]], LABELS[pred[k]], cause[:4])] += 1; nw += 1
    for k in np.flatnonzero(oracle != truth):
        oconf[(LABELS[truth[k]], LABELS[oracle[k]])] += 1
    errs_geo.append(err.max())
    per_photo.append((i, f"maxerr {err.max():.2f} wrong {nw}", nw))
    H = scene.harsh; bym[H.motion.shape[0]] = bym.get(H.motion.shape[0], np.zeros(3)) + [nw, (oracle != truth).sum(), len(truth)]
print("photos", n, "cells", total, "wrong", sum(counts.values()), f"acc {1 - sum(counts.values())/total:.4f}")
for k, v in counts.most_common(): print(f"  {k}: {v}")
print("confusions (truth, pred, cause):")
for k, v in conf.most_common(): print("  ", k, v)
print("oracle confusions:", dict(oconf), "oracle acc", 1 - sum(oconf.values())/ (total - counts['no_page'] - counts['no_grid']))
print("geom max err quantiles", np.quantile(errs_geo, [0.5, 0.9, 0.99, 1.0]).round(3))
print("worst photos", sorted(per_photo, key=lambda t: -t[2])[:12])

for k in sorted(bym): print("motion", k, bym[k])

if crops_png and tiles:  # rows of 6: the reader's cut | the cut at the true crossings, 3x enlarged
    rows = [tiles[j:j + 6] + [np.zeros_like(tiles[0])] * (6 - len(tiles[j:j + 6])) for j in range(0, len(tiles), 6)]
    sheet = np.vstack([np.hstack([np.pad(t, 3, constant_values=0) for t in row]) for row in rows])
    cv2.imwrite(crops_png, cv2.resize(sheet, None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST))
    print("wrong cells drawn:", crops_png)
