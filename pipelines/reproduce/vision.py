"""`ncbot reproduce vision`: the cell classifier's data budget and the paper's vision experiments beside ours.

Why here: the title's claim ("a few hundred images") is a curve, not one model: the shipped recipe trained on N
labelled cells (vision/budget.py), N from 10 to 1,000, several seeds, each scored on the held-out handwriting.
Every training is a folder `RUNS/vision/n<N>_seed<S>/` with `weights.pt` and `result.json`; a finished one is
skipped, a killed one retrained (a training is 1-3 CPU minutes), so `full` is resumable like the table's runs.
Outputs (drawn by pipelines/reproduce/vision_report.py): `OUT/data_budget_vision.png` (the curve, the paper's 310 marked), `OUT/vision_experiments.md` + `.png`
(the paper's three numbers and confusion matrix beside ours), and the vision section of `OUT/data_budget.md`
(`ncbot.pipelines.reproduce.budget` renders it with `vision_section`).
"""
from __future__ import annotations

import json
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.fileio import atomic_path, atomic_write_text

from ncbot.pipelines.reproduce.vision_report import plot_confusions, plot_curve, records, render_experiments, vision_section


@dataclass(frozen=True)
class VisionBudget:
    """The data-budget curve's points and how much held-out data scores each model."""

    name: str
    points: tuple[int, ...]   # labelled cells N
    seeds: int                # draws (data, initial weights, batch order) per N
    cells: int                # held-out cells per style (sketch, hershey)
    photos: int               # held-out 3x3 photos (sketch + hershey marks)
    loo_folds: int | None     # leave-one-out folds of the paper's first experiment (None: all 109)
    label: str                # the line every vision output of this budget carries
    updates: int | None = None  # optimiser steps per training (None: vision.budget.BUDGET_UPDATES)


VISION_BUDGETS = {
    "full": VisionBudget("full", (10, 25, 50, 109, 200, 310, 1000), 3, 600, 200, None,
                         "Vision budget full: N in {10, 25, 50, 109, 200, 310, 1000} labelled cells x 3 seeds; 1,200 "
                         "held-out cells and 200 held-out 3x3 photos per model; exact leave-one-out (109 folds)."),
    "quick": VisionBudget("quick", (10, 50, 310), 1, 600, 60, 20,
                          "QUICK VISION BUDGET (smoke run): N in {10, 50, 310} x 1 seed, 60 held-out photos, "
                          "leave-one-out on the first 20 of 109 folds. Run `--budget full` for the curve."),
}


def vision_budget_of(budget: Any) -> VisionBudget | None:
    """The vision budget of a reproduction budget (by name; None for budgets without one, e.g. tests' toys)."""
    return VISION_BUDGETS.get(getattr(budget, "name", budget))


# ---- the runs ---------------------------------------------------------------------------------------------------

def _heldout_path(root: Path, vb: VisionBudget) -> Path:
    return root / f"heldout_{vb.cells}cells_{vb.photos}photos.npz"


def _heldout(root: Path, vb: VisionBudget, progress: Any = None):
    """The held-out data of this budget, cut once and kept beside the runs (every worker scores on the same)."""
    from ncbot.vision.budget import HeldOut, heldout

    path = _heldout_path(root, vb)
    if path.is_file():
        with np.load(path) as z:
            cells = {style[6:]: (z[style], z["labels_" + style[6:]]) for style in z.files if style.startswith("cells_")}
            return HeldOut(cells, z["photo_cells"], z["photo_labels"], int(z["photos"]))
    data = heldout(vb.cells, vb.photos, progress)
    arrays = {f"cells_{s}": c for s, (c, _) in data.cells.items()} | {f"labels_{s}": l for s, (_, l) in data.cells.items()}
    root.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temp, open(temp, "wb") as stream:
        np.savez(stream, photo_cells=data.photo_cells, photo_labels=data.photo_labels, photos=data.photos, **arrays)
    return data


def _spec(vb: VisionBudget, n: int, seed: int) -> dict[str, Any]:
    from ncbot.vision.budget import BUDGET_UPDATES

    return {"images": n, "seed": seed, "updates_target": vb.updates or BUDGET_UPDATES, "heldout_cells": vb.cells,
            "heldout_photos": vb.photos}


def run_folder(root: Path, n: int, seed: int) -> Path:
    return root / f"n{n:05d}_seed{seed}"


def _done(root: Path, spec: dict[str, Any]) -> dict[str, Any] | None:
    path = run_folder(root, spec["images"], spec["seed"]) / "result.json"
    try:
        result = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return result if isinstance(result, dict) and result.get("spec") == spec else None


def train_and_score(root: str, spec: dict[str, Any], heldout_file: str) -> dict[str, Any]:
    """One point of the curve (run in a worker process): train (or reuse finished weights), score, save."""
    import cv2
    import torch

    from ncbot.vision.budget import HeldOut, evaluate, train_budget
    from ncbot.vision.classifier import load_classifier, save_weights

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    folder = run_folder(Path(root), spec["images"], spec["seed"])
    folder.mkdir(parents=True, exist_ok=True)
    weights = folder / "weights.pt"
    start_cpu, start_wall = time.process_time(), time.time()
    meta = None
    if weights.is_file():  # killed after training: keep the weights if they are this spec's
        try:
            meta = torch.load(weights, map_location="cpu", weights_only=True)["meta"]
        except Exception:  # a half-written or foreign file: train again
            meta = None
        if meta and (meta.get("budget_images"), meta.get("budget_seed"), meta.get("updates_target")) != \
                (spec["images"], spec["seed"], spec["updates_target"]):
            meta = None
    if meta is None:
        model, meta = train_budget(spec["images"], spec["seed"], spec["updates_target"])
        save_weights(model, weights, meta)
    with np.load(heldout_file) as z:
        cells = {k[6:]: (z[k], z["labels_" + k[6:]]) for k in z.files if k.startswith("cells_")}
        data = HeldOut(cells, z["photo_cells"], z["photo_labels"], int(z["photos"]))
    scores = evaluate(load_classifier(weights), data)
    result = {"spec": spec, **scores, "meta": meta, "weights": str(weights),
              "cpu_s": round(time.process_time() - start_cpu, 1), "wall_s": round(time.time() - start_wall, 1)}
    atomic_write_text(json.dumps(result, indent=1), folder / "result.json")
    return result


def run_vision_budget(vb: VisionBudget, root: Path, workers: int = 1, progress: Any = None,
                      train: bool = True) -> list[dict[str, Any]]:
    """Every (N, seed) point of the budget: finished ones read back, the rest trained (``workers`` processes);
    train=False returns the finished ones only (a report of a run still under way)."""
    import multiprocessing

    root = Path(root)
    data_file = _heldout_path(root, vb)
    _heldout(root, vb, progress)
    # the paper's 310 first (the target check), then seed by seed: a run stopped early still has whole curves
    from ncbot.vision.budget import PAPER_IMAGES

    order = sorted(((n != PAPER_IMAGES, seed, n) for seed in range(vb.seeds) for n in vb.points))
    specs = [_spec(vb, n, seed) for _, seed, n in order]
    results = {(s["images"], s["seed"]): _done(root, s) for s in specs}
    todo = [s for s in specs if results[(s["images"], s["seed"])] is None]
    if not train:
        return [results[key] for key in sorted(results) if results[key] is not None]
    if todo and workers > 1:
        with ProcessPoolExecutor(min(workers, len(todo)), mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = [pool.submit(train_and_score, str(root), s, str(data_file)) for s in todo]
            done = as_completed(futures)
            for future in progress(done, total=len(todo), desc="vision budget", unit="model") if progress else done:
                r = future.result()
                results[(r["spec"]["images"], r["spec"]["seed"])] = r
    else:
        for s in progress(todo, desc="vision budget", unit="model") if progress else todo:
            results[(s["images"], s["seed"])] = train_and_score(str(root), s, str(data_file))
    return [results[key] for key in sorted(results)]


# ---- reference figures (kept beside the runs) ---------------------------------------------------------------

def shipped_reference(vb: VisionBudget, root: Path) -> dict[str, Any]:
    """The shipped weights (40,002 training cells) on the very same held-out data: the curve's ceiling."""
    from ncbot.vision.budget import SHIPPED_CELLS, evaluate
    from ncbot.vision.classifier import load_classifier

    return {"images": SHIPPED_CELLS, **evaluate(load_classifier(), _heldout(Path(root), vb))}


def paper_experiments(vb: VisionBudget, root: Path, progress: Any = None) -> list[dict[str, Any]]:
    """`ncbot.vision.experiments.paper_experiments` at this budget's leave-one-out folds, kept beside the runs."""
    from ncbot.vision import experiments as ex

    path = Path(root) / f"paper_experiments_{vb.loo_folds or 'all'}folds.json"
    if path.is_file():
        return json.loads(path.read_text())
    found = [r.to_json() for r in ex.paper_experiments(progress=progress, loo_folds=vb.loo_folds)]
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(json.dumps(found, indent=1), path)
    return found


# ---- entry points (pipelines/reproduce/grid.py, pipelines/reproduce/budget.py) ----------------------------------------

def vision_root(runs_dir: Path) -> Path:
    return Path(runs_dir) / "vision"


def no_vision_note(budget: Any) -> str:
    return (f"not measured: budget {getattr(budget, 'name', budget)!r} has no vision points "
            f"(vision budgets: {', '.join(VISION_BUDGETS)})")


def write_vision_report(budget: Any, *, runs_dir: Path, out: Path, command: str, workers: int = 1,
                        progress: Any = None, partial: str | None = None) -> dict[str, Any]:
    """The vision part: the budget's trainings, the paper's experiments, OUT/vision_experiments.{md,png} and
    OUT/data_budget_vision.png. Returns {"vision": records, "shipped": ..., "paper_experiments": ..., "files"}.
    ``partial`` (a sentence saying why): report the finished points only, without training, labelled PARTIAL."""
    from dataclasses import replace

    vb = vision_budget_of(budget)
    if vb is None:
        raise ValueError(no_vision_note(budget))
    root, out = vision_root(runs_dir), Path(out)
    results = run_vision_budget(vb, root, workers, progress, train=partial is None)
    if partial is not None:
        vb = replace(vb, label=f"PARTIAL ({len(results)} of {len(vb.points) * vb.seeds} points finished): {partial} "
                               f"{vb.label}")
    paper = paper_experiments(vb, root, progress)
    shipped = shipped_reference(vb, root)
    out.mkdir(parents=True, exist_ok=True)
    md = atomic_write_text(render_experiments(vb, paper, results, shipped, command), out / "vision_experiments.md")
    files = [md, plot_confusions(paper, results, shipped, out / "vision_experiments.png", vb.label, command),
             plot_curve(records(results), shipped, out / "data_budget_vision.png", vb.label, command)]
    return {"label": vb.label, "vision": records(results), "shipped": shipped, "paper_experiments": paper,
            "files": [str(p) for p in files]}


def vision_budget_part(budget: Any, *, runs_dir: Path, out: Path, command: str = "ncbot reproduce budget",
                       workers: int = 1) -> dict[str, Any]:
    """What `ncbot reproduce budget` shows of vision: the records, the markdown section and the curve's PNG
    (trainings already finished by the vision part are read back, missing ones trained here)."""
    vb = vision_budget_of(budget)
    if vb is None:
        return {"vision": [], "vision_note": no_vision_note(budget), "vision_markdown": no_vision_note(budget) + ".\n",
                "vision_figures": []}
    root = vision_root(runs_dir)
    results = run_vision_budget(vb, root, workers)
    recs, shipped = records(results), shipped_reference(vb, root)
    Path(out).mkdir(parents=True, exist_ok=True)
    figure = plot_curve(recs, shipped, Path(out) / "data_budget_vision.png", vb.label, command)
    return {"vision": recs, "vision_note": vb.label, "vision_markdown": vision_section(recs, shipped, vb.label),
            "vision_figures": [str(figure)]}


def run_vision_part(part: str, budget: Any, *, runs_dir: Path, out: Path, command: str, workers: int) -> dict[str, Any]:
    """`reproduce`'s hook: part vision (or all, when the budget has vision points) writes the vision files; part
    budget only trains the missing points in parallel (data_budget.md then reads them back)."""
    from ncbot.pipelines.progress import progress_bar

    vb = vision_budget_of(budget)
    if part == "vision" or (part == "all" and vb is not None):
        return {"vision_report": write_vision_report(budget, runs_dir=runs_dir, out=out, command=command,
                                                     workers=workers, progress=progress_bar)}
    if vb is not None:
        run_vision_budget(vb, vision_root(runs_dir), workers, progress_bar)
    return {}
