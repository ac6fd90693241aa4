"""`ncbot vision ...`: read boards and cells from images, train and evaluate the cell classifier, generate data.

JSON contract (used by the robot simulator): `read --json` prints one object per image,
{"image": PATH, "cells": [...]} or {"image": PATH, "error": "..."}; exit 0 if any image was read, else 2.
`classify --json` prints {"image": PATH, "label": ..., "scores": [3 floats]} (or "error").
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.outputs import check_writable_dir, check_writable_file
from ncbot.pipelines.progress import progress_bar  # light: tqdm loads only when a bar is drawn

vision_app = typer.Typer(help="Visual perception: read game sheets, classify cells, train/evaluate the CNN, generate data.",
                         no_args_is_help=True)

_SYMBOL = {"x": "X", "o": "O", "": "."}


def _setup_threads() -> None:
    import cv2
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)


def _load_image(path: Path):
    import cv2

    if not path.is_file():
        raise FileNotFoundError(f"image {path} does not exist")
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError(f"image {path} could not be decoded (expected a PNG/JPEG/BMP file)")
    return image


def _classifier(weights: Optional[Path]):
    from ncbot.vision.classifier import load_classifier

    return load_classifier(weights)


def _board_text(cells: list[str], cols: int) -> str:
    rows = [" ".join(_SYMBOL[c] for c in cells[r:r + cols]) for r in range(0, len(cells), cols)]
    return " / ".join(rows)


@vision_app.command()
def read(images: list[Path] = typer.Argument(..., help="Photos of a game sheet."),
         grid: str = typer.Option("3", help="3 (noughts & crosses), 9 (ultimate) or ROWSxCOLS, e.g. 6x7 (a "
                                  "declared game's plain grid; 3..9 each)."),
         json_out: bool = typer.Option(False, "--json", help="One JSON object per line per image."),
         weights: Optional[Path] = typer.Option(None, help="Classifier weights (default: the shipped ones)."),
         rho: Optional[int] = typer.Option(None, min=8, max=256, help="Pixels per cell of the grid warp (default 64 / 40; 8..256).")) -> None:
    """Read the board on each photo: row-major cells "x" / "o" / "" over the full grid."""
    from ncbot.vision.grid import read_board
    from ncbot.vision.sheet import grid_shape, parse_grid

    shape = parse_grid(grid)
    cols = grid_shape(shape)[1]
    _setup_threads()
    classifier = _classifier(weights)
    any_read = False
    for path in images:
        try:
            cells = read_board(_load_image(path), shape, classifier, rho)
        except (ValueError, FileNotFoundError) as error:
            typer.echo(json.dumps({"image": str(path), "error": str(error)}) if json_out else f"{path}: error: {error}")
            continue
        any_read = True
        typer.echo(json.dumps({"image": str(path), "cells": cells}) if json_out else f"{path}: {_board_text(cells, cols)}")
    if not any_read:
        typer.echo(f"ncbot: error: none of the {len(images)} image(s) could be read (reasons above)", err=True)
        raise typer.Exit(2)


@vision_app.command()
def classify(images: list[Path] = typer.Argument(..., help="Crops of one cell each (any size; resized to 40x40)."),
             json_out: bool = typer.Option(False, "--json", help="One JSON object per line per image."),
             weights: Optional[Path] = typer.Option(None, help="Classifier weights (default: the shipped ones).")) -> None:
    """Classify each cell image as nought / cross / nothing with the CNN + SVM."""
    _setup_threads()
    classifier = _classifier(weights)
    any_read = False
    for path in images:
        try:
            label, scores = classifier.classify_image(_load_image(path))
        except (ValueError, FileNotFoundError) as error:
            typer.echo(json.dumps({"image": str(path), "error": str(error)}) if json_out else f"{path}: error: {error}")
            continue
        any_read = True
        if json_out:
            typer.echo(json.dumps({"image": str(path), "label": label, "scores": [round(s, 4) for s in scores]}))
        else:
            typer.echo(f"{path}: {label} (scores {' '.join(f'{s:.2f}' for s in scores)})")
    if not any_read:
        typer.echo(f"ncbot: error: none of the {len(images)} image(s) could be read (reasons above)", err=True)
        raise typer.Exit(2)


@vision_app.command()
def train(out: Optional[Path] = typer.Option(None, "--out", "-o", help="Where to write the weights (default: the shipped file)."),
          cells: int = typer.Option(24_000, min=30, help="Generated cells (60% noisy)."),
          frames3: int = typer.Option(700, min=0, help="Generated 3x3 photos whose cells the reader cuts."),
          frames9: int = typer.Option(120, min=0, help="Generated 9x9 photos whose cells the reader cuts."),
          harsh_cells: int = typer.Option(8_000, min=0, help="Generated cells as a harsh photo leaves them (motion "
                                          "streak, dim light, JPEG; vision/data/harsh_cells.py)."),
          harsh_styles: str = typer.Option("pen,hasty", help="Handwriting of the harsh cells, comma list of the "
                                           "training styles pen, hasty (the tuning and held-out styles are refused)."),
          epochs: int = typer.Option(14, min=1, help="Passes over the training cells."),
          seed: int = typer.Option(0, help="Initial weights, batch order and augmentations."),
          data_seed: Optional[int] = typer.Option(None, help="Data seed (default vision.data.TRAIN_SEED)."),
          budget: Optional[int] = typer.Option(None, min=3, max=100_000, help="Data budget: train the same recipe on "
                                               "only N labelled training-style cells (paper: 310); needs --out; "
                                               "--seed picks the draw too (vision/budget.py)."),
          updates: Optional[int] = typer.Option(None, min=1, help="--budget only: optimiser steps (default: as many "
                                                "as the shipped run on its clean and noisy cells, 8,764)."),
          ) -> None:
    """Train the default cell classifier (the shipped vision/weights/cell_cnn.pt) on generated data, or with
    --budget N the same recipe on N labelled cells (109 : 201 clean : noisy, as the paper)."""
    from ncbot.vision.classifier import DEFAULT_WEIGHTS, FitConfig, save_weights
    from ncbot.vision.data import TRAIN_SEED
    from ncbot.vision.training import DefaultTraining, train_default

    if out is not None:
        check_writable_file(out, "--out", (".pt",))
    if budget is not None:
        from ncbot.vision.budget import train_budget

        if out is None:
            raise ValueError("--budget needs --out WEIGHTS.pt (it never overwrites the shipped weights)")
        if data_seed is not None:
            raise ValueError("--data-seed does not apply with --budget: --seed picks the draw (vision.data.BUDGET_SEED + 10,000 x seed)")
        _setup_threads()
        model, meta = train_budget(budget, seed, updates, progress=progress_bar)
        path = save_weights(model, out, meta)
        typer.echo(f"wrote {path} ({meta['clean']} clean + {meta['noisy_generated']} generated noisy + "
                   f"{meta['noisy_photo']} photo cells, {meta['updates']} updates, seed {seed})")
        return
    if updates is not None:
        raise ValueError("--updates applies only with --budget (the shipped recipe counts --epochs)")
    from ncbot.vision.strokes import TRAINING_STYLES

    styles = tuple(s.strip() for s in harsh_styles.split(",") if s.strip())
    if not styles or set(styles) - set(TRAINING_STYLES):
        raise ValueError(f"--harsh-styles takes a comma list of the training styles {', '.join(TRAINING_STYLES)}; "
                         f"got {harsh_styles!r}")
    _setup_threads()
    config = DefaultTraining(n_cells=cells, n_frames_3=frames3, n_frames_9=frames9, n_harsh_cells=harsh_cells,
                             harsh_styles=styles,
                             seed=TRAIN_SEED if data_seed is None else data_seed,
                             train=FitConfig(epochs=epochs, batch_size=64, lr=3e-3, seed=seed))
    model, meta = train_default(config, progress=progress_bar)
    path = save_weights(model, out or DEFAULT_WEIGHTS, meta)
    typer.echo(f"wrote {path} ({meta['n_training_cells']} training cells)")


@vision_app.command("eval")
def evaluate(out: Path = typer.Option(Path("runs/vision"), "--out", "-o", help="Directory for the markdown, PNG and JSON reports."),
             what: str = typer.Option("paper,cells,reading,recogniser",
                                      help="Comma list of: paper, cells, reading, recogniser, harsh."),
             frames: int = typer.Option(100, min=1, help="Photos per grid size and style for 'reading' and 'harsh'."),
             sequences: int = typer.Option(120, min=1, help="'recogniser': 3x3 drawing sequences per mark style set."),
             sequences9: int = typer.Option(40, min=1, help="'recogniser': 9x9 drawing sequences per mark style set."),
             seed_set: str = typer.Option("heldout", help="'recogniser', 'harsh': heldout (never tuned on) or tuning "
                                          "data; 'harsh' also tuning-style (tuning seeds, the tuning handwriting "
                                          "\"marker\", on which training choices are judged)."),
             weights: Optional[Path] = typer.Option(None, help="Weights for 'cells'/'reading' (default: shipped)."),
             loo_folds: Optional[int] = typer.Option(None, min=1, help="Run only the first LOO folds (default all 109).")) -> None:
    """Reproduce the paper's three experiments (LOO clean, clean->noisy, noisy->clean) and measure reading
    (clean and "harsh" photo conditions) and the move recogniser (Algorithm 1 on drawing sequences with a
    hand over the sheet)."""
    from ncbot.vision import experiments as ex

    parts = [p.strip() for p in what.split(",") if p.strip()]
    unknown = set(parts) - {"paper", "cells", "reading", "recogniser", "harsh"}
    if unknown or not parts:
        raise ValueError(f"--what takes a comma list of paper, cells, reading, recogniser, harsh; got {what!r}")
    if seed_set not in ex.HARSH_SPLITS:
        raise ValueError(f"--seed-set must be one of {', '.join(ex.HARSH_SPLITS)}; got {seed_set!r}")
    if seed_set == "tuning-style" and set(parts) - {"harsh"}:
        raise ValueError("--seed-set tuning-style applies to --what harsh only (harsh photos with the tuning handwriting)")
    check_writable_dir(out, "--out")
    _setup_threads()
    written = []
    if "paper" in parts:
        results = ex.paper_experiments(progress=progress_bar, loo_folds=loo_folds)
        written += ex.write_report(results, out, "paper_experiments")
        typer.echo(ex.markdown(results))
    classifier = _classifier(weights) if {"cells", "reading", "recogniser", "harsh"} & set(parts) else None
    if "cells" in parts:
        results = ex.heldout_cells(classifier)
        written += ex.write_report(results, out, "heldout_cells")
        typer.echo(ex.markdown(results))
    if "reading" in parts:
        results = [ex.reading(grid, frames, styles, classifier, progress=progress_bar)
                   for grid in (3, 9) for styles in (("pen",), ("sketch", "hershey"))]
        written += ex.write_report(results, out, "reading")
        typer.echo(ex.markdown(results))
    if "harsh" in parts:
        results = ex.harsh_reading(frames, seed_set, classifier, progress=progress_bar)
        stem = {"heldout": "reading_harsh", "tuning": "reading_harsh_tuning", "tuning-style": "reading_harsh_tuning_style"}[seed_set]
        written += ex.write_report(results, out, stem)
        if seed_set == "heldout":
            ex.harsh_frames_png(out / "reading_harsh_frames.png", classifier=classifier)
            written.append(out / "reading_harsh_frames.png")
        typer.echo(ex.markdown(results))
    if "recogniser" in parts:
        from ncbot.vision import recogniser_eval as rx

        base = rx.HELDOUT_SEED if seed_set == "heldout" else rx.TUNING_SEED
        sets = [rx.evaluate_sequences(grid, n, base + offset, styles, classifier, progress=progress_bar)
                for grid, n in ((3, sequences), (9, sequences9))
                for offset, styles in ((0, ("pen",)), (100_000, ("sketch", "hershey")))]
        written += rx.write_report(sets, out, "recogniser" if seed_set == "heldout" else "recogniser_tuning")
        typer.echo(rx.markdown(sets))
    typer.echo("wrote " + ", ".join(str(p) for p in written))


@vision_app.command()
def generate(kind: str = typer.Argument(..., help="cells, frames or sequence."),
             out: Path = typer.Option(..., "--out", "-o", help="Output directory (PNG files + labels.jsonl)."),
             n: int = typer.Option(20, min=1, max=100_000, help="Number of cells / frames (sequence: one sequence)."),
             seed: int = typer.Option(0, help="Data seed."),
             noisy: bool = typer.Option(False, help="cells: noisy instead of clean."),
             grid: str = typer.Option("3", help="frames/sequence: 3 (noughts & crosses), 9 (ultimate) or ROWSxCOLS, "
                                      "e.g. 6x7 (a declared game's plain grid; 3..9 each)."),
             game: Optional[str] = typer.Option(None, "--game", help="frames/sequence: the sheet of this game instead of "
                                                "--grid (a name, a game YAML file or a game class path/to/file.py:Misere)."),
             hand: bool = typer.Option(False, help="frames: a hand reaches over the sheet."),
             style: str = typer.Option("pen", help="Stroke style(s), comma list of pen, sketch, hershey."),
             quality: str = typer.Option("clean", "--quality", help="frames/sequence: photo quality, clean or harsh "
                                                                   "(shadow, colour cast, dim, lens, blur, JPEG); not "
                                                                   "`ncbot robot --conditions`, the simulated room.")) -> None:
    """Write generated data to disk to look at or to feed other tools."""
    import cv2

    from ncbot.vision.data.conditions import CONDITIONS
    from ncbot.vision.sheet import grid_label, parse_grid
    from ncbot.vision.strokes import STYLES

    styles = tuple(s.strip() for s in style.split(",") if s.strip())
    if not styles or set(styles) - set(STYLES):
        raise ValueError(f"--style takes a comma list of {', '.join(STYLES)}; got {style!r}")
    if kind not in ("cells", "frames", "sequence"):
        raise ValueError(f"kind must be cells, frames or sequence; got {kind!r}")
    shape = parse_grid(grid) if game is None else _game_grid(game)
    label = grid_label(shape)
    if quality not in CONDITIONS:
        raise ValueError(f"--quality must be one of {', '.join(CONDITIONS)}; got {quality!r}")
    check_writable_dir(out, "--out")
    out.mkdir(parents=True, exist_ok=True)
    records = []
    if kind == "cells":
        from ncbot.vision.data.cells import make_cells
        from ncbot.vision.labels import LABELS

        images, labels = make_cells(n, seed, noisy=noisy, styles=styles)
        for i, (image, label) in enumerate(zip(images, labels)):
            name = f"cell_{i:05d}.png"
            cv2.imwrite(str(out / name), image)
            records.append({"image": name, "label": LABELS[int(label)]})
    elif kind == "frames":
        from ncbot.vision.data.frames import make_frame

        for i in range(n):
            frame = make_frame(shape, seed + i, hand=hand, styles=styles, conditions=quality)
            name = f"frame_{label}_{seed + i}.png"
            cv2.imwrite(str(out / name), frame.image)
            records.append({"image": name, "grid": label, "cells": frame.board, "hand": hand,
                            "page_corners": frame.page_corners.astype(float).round(1).tolist()})
    else:
        from ncbot.vision.data.sequences import make_move_sequence

        seq = make_move_sequence(shape, seed, styles=styles, conditions=quality)
        for i, (image, has_hand) in enumerate(zip(seq.frames, seq.hand)):
            name = f"seq_{seed}_{i:03d}.png"
            cv2.imwrite(str(out / name), image)
            records.append({"image": name, "grid": label, "hand": has_hand, "known_board": seq.known_board,
                            "move": seq.move, "symbol": seq.symbol})
    atomic_write_text("".join(json.dumps(r) + "\n" for r in records), out / "labels.jsonl")
    typer.echo(f"wrote {len(records)} images and labels.jsonl to {out}")


def _game_grid(game: str):
    """The grid of the sheet of ``game`` (the user names it here: a game class is imported); one line when the sheet
    cannot draw its board."""
    from ncbot.envs.games import load_game
    from ncbot.vision.sheet import game_grid

    return game_grid(load_game(game))


def register(app: typer.Typer) -> None:
    """Add `ncbot vision ...` to the root app."""
    app.add_typer(vision_app, name="vision")
