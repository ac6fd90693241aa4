"""What the vision budget's runs show: per-N records, the markdown of data_budget.md's vision section and of
results/vision_experiments.md (the paper's three numbers and its confusion matrix beside ours), and their PNGs.

Kept apart from pipelines/reproduce/vision.py (which runs the trainings) so each file has one job.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

TARGET = 0.98  # our target: >= 98 % of held-out cells right at the paper's budget of 310 images

# ---- what the runs show -----------------------------------------------------------------------------------------

def _interval(values: list[float], items: int) -> list[float] | None:
    """The 95 % interval over seeds of an accuracy measured on ``items`` held-out items (logit scale: inside [0, 1])."""
    from ncbot.pipelines.reproduce.seed_stats import proportion_interval

    found = proportion_interval(values, max(1, items))
    return None if found.low is None else [found.low, found.high]


def records(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One record per N (the `--json` "vision" list): means over seeds, the 95 % interval (Student t of the
    per-seed logits, `ncbot.pipelines.reproduce.seed_stats.proportion_interval`), every seed's value."""
    by_n: dict[int, list[dict[str, Any]]] = {}
    for r in results:
        by_n.setdefault(r["spec"]["images"], []).append(r)
    out = []
    for n, runs in sorted(by_n.items()):
        runs = sorted(runs, key=lambda r: r["spec"]["seed"])
        cells, boards = [r["cell_accuracy"] for r in runs], [r["board_accuracy"] for r in runs]
        meta = runs[0]["meta"]
        out.append({"images": n, "clean": meta["clean"], "noisy": meta["noisy_generated"] + meta["noisy_photo"],
                    "noisy_generated": meta["noisy_generated"], "noisy_photo": meta["noisy_photo"],
                    "seeds": [r["spec"]["seed"] for r in runs], "updates": meta["updates"],
                    "cell_accuracy": float(np.mean(cells)), "cell_accuracy_ci95": _interval(cells, runs[0]["cells"]),
                    "cell_accuracy_per_seed": cells,
                    "board_accuracy": float(np.mean(boards)),
                    "board_accuracy_ci95": _interval(boards, runs[0]["photos"]),
                    "board_accuracy_per_seed": boards,
                    "cell_accuracy_by_style": {s: float(np.mean([r["cell_accuracy_by_style"][s] for r in runs]))
                                               for s in runs[0]["cell_accuracy_by_style"]},
                    "heldout_cells": runs[0]["cells"], "heldout_photos": runs[0]["photos"],
                    "meets_target": bool(np.mean(cells) >= TARGET)})
    return out


def target_text(recs: list[dict[str, Any]]) -> str:
    """Whether N = 310 reaches the target, and where the mean cell accuracy falls below it."""
    from ncbot.vision.budget import PAPER_IMAGES

    at_paper = next((r for r in recs if r["images"] == PAPER_IMAGES), None)
    below = [r["images"] for r in recs if not r["meets_target"]]
    lines = []
    if at_paper is None:
        lines.append(f"N = {PAPER_IMAGES} was not run at this budget: the target cannot be checked.")
    else:
        ci = at_paper["cell_accuracy_ci95"]
        ci_text = f" (95 % t-interval over seeds {100 * ci[0]:.2f}-{100 * ci[1]:.2f} %)" if ci else ""
        verdict = "**met**" if at_paper["meets_target"] else "**missed**"
        lines.append(f"Target (>= {100 * TARGET:.0f} % of held-out cells at the paper's {PAPER_IMAGES} images): {verdict}, "
                     f"mean {100 * at_paper['cell_accuracy']:.2f} % over {len(at_paper['seeds'])} seed(s){ci_text}.")
    if below:
        above = [r["images"] for r in recs if r["meets_target"]]
        first_ok = min((n for n in above if all(m >= n for m in above) and all(b < n for b in below)), default=None)
        where = (f"the mean is below {100 * TARGET:.0f} % at N = {', '.join(str(n) for n in below)}"
                 + (f"; from N = {first_ok} on it is at or above" if first_ok else "; no N reached it"))
        lines.append(f"Where it falls below: {where}.")
    else:
        lines.append(f"Every N measured reaches {100 * TARGET:.0f} %.")
    return " ".join(lines)


def _pct(value: float | None) -> str:
    return "–" if value is None else f"{100 * value:.2f} %"


def _ci(ci: list[float] | None) -> str:
    return "n<2" if ci is None else f"{100 * ci[0]:.2f}-{100 * ci[1]:.2f}"


def vision_section(recs: list[dict[str, Any]], shipped: dict[str, Any] | None, label: str, note: str = "") -> str:
    """The data-budget table (markdown), shared by data_budget.md and vision_experiments.md."""
    if not recs:
        return (note or "No vision points at this budget.") + "\n"
    from ncbot.vision.budget import BUDGET_UPDATES

    first = recs[0]
    updates_note = ("as many as the shipped run on its clean and noisy cells" if abs(first["updates"] - BUDGET_UPDATES) < 64
                    else f"a smoke budget: the shipped run made {BUDGET_UPDATES:,} on its clean and noisy cells")
    lines = [f"> {label}", "",
             "The shipped classifier's recipe (`vision/training.py`: the paper's CNN + linear SVM, hinge loss, Adam "
             "3e-3 cosine, batch 64, flips/turns/shifts) trained on N labelled cells of the training handwriting "
             f"(\"pen\"), with {first['updates']:,} updates ({updates_note}; below 64 cells a batch is the whole set): "
             "fewer cells, not less training. N splits as the paper's 109 clean : 201 noisy (clean = round(N x 109 / 310)); the "
             "noisy part is half generated noisy cells, half cells the reader cut from training photos "
             "(`vision/budget.py`). Scored on held-out handwriting only: "
             f"{first['heldout_cells']:,} cells (\"sketch\" + \"hershey\", half noisy) and {first['heldout_photos']} "
             "3x3 photos of sketch + hershey marks (board = all 9 cells right). Interval: 95 % Student t over seeds of the per-seed logits (inside [0, 1]).",
             "", "| N images | clean + noisy (generated + photo) | seeds | cells right (mean) | 95 % interval | "
             "per seed | 3x3 boards right (mean) | 95 % interval | per seed | >= 98 % cells |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        lines.append(f"| {r['images']:,} | {r['clean']} + {r['noisy']} ({r['noisy_generated']} + {r['noisy_photo']}) | "
                     f"{len(r['seeds'])} | {_pct(r['cell_accuracy'])} | {_ci(r['cell_accuracy_ci95'])} | "
                     f"{', '.join(f'{100 * v:.2f}' for v in r['cell_accuracy_per_seed'])} | "
                     f"{_pct(r['board_accuracy'])} | {_ci(r['board_accuracy_ci95'])} | "
                     f"{', '.join(f'{100 * v:.1f}' for v in r['board_accuracy_per_seed'])} | "
                     f"{'yes' if r['meets_target'] else 'no'} |")
    if shipped:
        lines.append(f"| shipped weights: {shipped['images']:,} | 24,000 generated (60 % noisy) + 16,002 photo + 8,000 harsh cells | 1 "
                     f"| {_pct(shipped['cell_accuracy'])} | | | {_pct(shipped['board_accuracy'])} | | | "
                     f"{'yes' if shipped['cell_accuracy'] >= TARGET else 'no'} |")
    lines += ["", target_text(recs), "", "Figure: `data_budget_vision.png` (the paper's 310 dashed, the 98 % target dotted)."]
    return "\n".join(lines) + "\n"


def _suptitle(fig: Any, label: str, command: str) -> None:
    import textwrap

    fig.suptitle("\n".join(textwrap.wrap(f"{label} Made by: {command}", 170)), fontsize=7)


def plot_curve(recs: list[dict[str, Any]], shipped: dict[str, Any] | None, path: Path, label: str,
               command: str) -> Path:
    """Cells and boards right against N (log axis), every seed a dot, the paper's 310 and the 98 % target marked."""
    from ncbot.pipelines.plots import pyplot, save_figure
    from ncbot.vision.budget import PAPER_IMAGES

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, key, title in ((axes[0], "cell_accuracy", "held-out cells right"),
                           (axes[1], "board_accuracy", "held-out 3x3 photos read entirely right")):
        xs = [r["images"] for r in recs]
        ax.plot(xs, [r[key] for r in recs], marker="o", color="C0", label="mean over seeds")
        for r in recs:
            ax.scatter([r["images"]] * len(r[f"{key}_per_seed"]), r[f"{key}_per_seed"], color="C0", alpha=0.35, s=14)
        if shipped:
            ax.axhline(shipped[key], color="C2", linestyle="-.", label=f"shipped ({shipped['images']:,} cells)")
        ax.axvline(PAPER_IMAGES, color="grey", linestyle="--", label="paper: 109 + 201 = 310")
        if key == "cell_accuracy":
            ax.axhline(TARGET, color="C3", linestyle=":", label="target 98 %")
        ax.set_xscale("log")
        ax.set_xlabel("labelled training cells N")
        ax.set_ylabel("share right")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    _suptitle(fig, label, command)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return save_figure(fig, path)


# ---- the paper's vision experiments beside ours -----------------------------------------------------------------

LABEL_ORDER = ("nought", "cross", "nothing")
PAPER_EXPERIMENTS = (  # the paper's vision experiments: name, the paper's accuracy
    ("leave-one-out, clean", "leave-one-out on the 109 clean cells", 0.999),
    ("train clean -> test noisy", "train on the 109 clean -> test on the 201 noisy", 0.74),
    ("train noisy -> test clean", "train on the 201 noisy -> test on the 109 clean", 0.984),
)
# the paper's one confusion matrix, % of each true label (rows nought, cross, nothing; columns the same order)
PAPER_CONFUSION = ((95.1, 4.9, 0.0), (0.0, 100.0, 0.0), (0.0, 0.0, 100.0))


def _rates(confusion: list[list[int]]) -> np.ndarray:
    matrix = np.asarray(confusion, float)
    return 100 * matrix / np.maximum(matrix.sum(axis=1, keepdims=True), 1)


def _pooled(results: list[dict[str, Any]], n: int) -> tuple[list[list[int]], int]:
    runs = [r for r in results if r["spec"]["images"] == n]
    return (np.sum([r["confusion"] for r in runs], axis=0).tolist() if runs else []), len(runs)


def render_experiments(vb: Any, paper: list[dict[str, Any]], results: list[dict[str, Any]],
                       shipped: dict[str, Any], command: str) -> str:
    """results/vision_experiments.md: the paper's three numbers and its confusion matrix beside ours (vb: the
    VisionBudget, for its label and photo count)."""
    from ncbot.vision.budget import PAPER_IMAGES

    ours = {r["name"]: r for r in paper}
    folds = ours["leave-one-out, clean"]["n"]
    loo_note = "exact, 109 trainings" if folds == 109 else f"first {folds} of 109 folds only"
    train_cmd = f"`ncbot vision train --budget {PAPER_IMAGES} --seed S --out W.pt` then `ncbot vision eval --what cells,reading --frames {vb.photos} --weights W.pt`"
    lines = ["# Vision: the paper's experiments beside ours", "", f"> {vb.label}", "",
             f"Made by `{command}` (vision part, `pipelines/reproduce/vision.py`). Our data are generated (no photos of "
             "real handwriting exist here): the paper's clean / noisy sets are `vision/data/cells.py`'s clean and noisy "
             "cells of the training style (seeds 109,000 / 201,000); held-out handwriting = the \"sketch\" and "
             "\"hershey\" stroke models, never trained on. Figures: `vision_experiments.png` (confusion matrices), "
             "`data_budget_vision.png` (data budget).", "",
             "## The paper's three numbers", "",
             "| experiment | paper | ours | n | how ours was made |", "|---|---|---|---|---|"]
    for key, text, value in PAPER_EXPERIMENTS:
        r = ours[key]
        how = (f"{loo_note}; " if key.startswith("leave") else "") + \
            "`ncbot.vision.experiments.paper_experiments` (40 epochs, batch 16); alone: `ncbot vision eval --what paper`"
        lines.append(f"| {text} | {100 * value:.1f} % | **{100 * r['accuracy']:.1f} %** | {r['n']} | {how} |")
    pooled, seeds = _pooled(results, PAPER_IMAGES)
    columns = [("paper (its one matrix)", np.array(PAPER_CONFUSION), "the paper"),
               (f"ours: N = {PAPER_IMAGES} cells, held-out styles, {seeds} seed(s) pooled",
                _rates(pooled) if pooled else None, train_cmd + f" for S in 0..{max(seeds - 1, 0)}"),
               (f"ours: shipped weights ({shipped['images']:,} cells), held-out styles", _rates(shipped["confusion"]),
                "`ncbot vision eval --what cells`"),
               ("ours: train noisy -> test clean", _rates(ours["train noisy -> test clean"]["confusion"]),
                "`ncbot vision eval --what paper`")]
    columns = [c for c in columns if c[1] is not None]
    lines += ["", "## Confusion matrix (rows: true label; % of the row called nought / cross / nothing)", "",
              "| true label | " + " | ".join(c[0] for c in columns) + " |", "|---" * (len(columns) + 1) + "|"]
    for i, label in enumerate(LABEL_ORDER):
        lines.append(f"| {label} | " + " | ".join(" / ".join(f"{v:.1f}" for v in c[1][i]) for c in columns) + " |")
    lines += ["", "Commands: " + "; ".join(f"{c[0]}: {c[2]}" for c in columns[1:]) + ". "
              f"Held-out cells: {shipped['cells']:,} ({vb.cells} sketch + {vb.cells} hershey, half noisy; TEST_SEED + 1, + 2).", "",
              "## Data budget: labelled cells against held-out accuracy", "",
              vision_section(records(results), shipped, vb.label).rstrip(), ""]
    return "\n".join(lines)


def plot_confusions(paper: list[dict[str, Any]], results: list[dict[str, Any]], shipped: dict[str, Any],
                    path: Path, label: str, command: str) -> Path:
    """The paper's matrix and ours side by side (row percentages)."""
    from ncbot.pipelines.plots import pyplot, save_figure
    from ncbot.vision.budget import PAPER_IMAGES

    pooled, seeds = _pooled(results, PAPER_IMAGES)
    panels = [("paper", np.array(PAPER_CONFUSION))]
    if pooled:
        panels.append((f"ours: N = {PAPER_IMAGES}, held-out styles\n({seeds} seed(s) pooled)", _rates(pooled)))
    panels.append((f"ours: shipped ({shipped['images']:,} cells)\nheld-out styles", _rates(shipped["confusion"])))
    noisy_clean = next(r for r in paper if r["name"] == "train noisy -> test clean")
    panels.append(("ours: train noisy -> test clean", _rates(noisy_clean["confusion"])))
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(3.3 * len(panels), 3.4))
    for ax, (title, rates) in zip(axes, panels):
        ax.imshow(rates, vmin=0, vmax=100, cmap="Blues")
        for (i, j), v in np.ndenumerate(rates):
            ax.text(j, i, f"{v:.1f}%", ha="center", va="center", fontsize=8, color="white" if v > 50 else "black")
        ax.set_xticks(range(3), LABEL_ORDER, fontsize=7)
        ax.set_yticks(range(3), LABEL_ORDER, fontsize=7)
        ax.set_xlabel("predicted", fontsize=8)
        ax.set_ylabel("true", fontsize=8)
        ax.set_title(title, fontsize=8)
    _suptitle(fig, label, command)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return save_figure(fig, path)


