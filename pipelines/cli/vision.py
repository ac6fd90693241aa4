"""`ncbot vision ...`: read boards and cells from images, train and evaluate the cell classifier, generate data.

`read --json` prints one object, {"images": [{"image": PATH, "cells": [...]} or {"image": PATH, "error": "..."}]};
`classify --json` the same with {"image": PATH, "label": ..., "scores": [3 floats]}. An image that cannot be read is
one line on stderr, `ncbot: error: PATH: why`; the exit code is 2 when any image could not be read.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.cli.conventions import (json_option, listing, no_progress_option, out_file, out_folder,
                                             print_json, wrote)
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


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
#: a grid line count this far from a grid's size, across and down, is another grid (vision.grid.lines_found: 3x3
#: sheets give 1-7 lines a way, 9x9 sheets 6-10, hands over the sheet included)
GRID_MISFIT = 1.6


def _load_image(path: Path):
    import cv2

    if path.is_dir():
        raise IsADirectoryError(f"image {path} is a folder; expected an image file (a folder is read image by image)")
    if not path.is_file():
        raise FileNotFoundError(f"image {path} does not exist")
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError(f"image {path} could not be decoded (expected a PNG/JPEG/BMP file)")
    return image


def image_files(paths: list[Path]) -> list[Path]:
    """The images to read: files as given, and every PNG/JPEG/BMP file of a folder (sorted)."""
    found = []
    for path in paths:
        if path.is_dir():
            inside = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
            if not inside:
                raise FileNotFoundError(f"folder {path} holds no image; expected PNG, JPEG or BMP files")
            found += inside
        else:
            found.append(path)
    return found


def check_grid_fits(image, shape) -> None:
    """One line when the sheet's grid lines clearly belong to another grid than `--grid` (a 3x3 sheet read as 9x9
    would give 81 cells of nonsense), naming the lines found and the grid they fit."""
    from ncbot.vision.grid import lines_found
    from ncbot.vision.sheet import grid_label, grid_shape

    found = lines_found(image, shape)
    if found is None:
        return  # no sheet: the reader says so

    def misfit(cells: int, lines: int) -> bool:
        return cells > GRID_MISFIT * (lines + 1) or cells < (lines - 1) / GRID_MISFIT

    if not all(misfit(cells, lines) for cells, lines in zip(grid_shape(shape), found)):
        return
    fits = [str(n) for n in (3, 9) if not all(misfit(n, lines) for lines in found)]
    hint = f"; it fits --grid {fits[0]}" if fits else ""
    asked = str(shape) if isinstance(shape, int) else grid_label(shape)
    raise ValueError(f"the sheet's grid has {found[0]} lines across and {found[1]} down: not a {grid_label(shape)} "
                     f"grid (--grid {asked}){hint}")


def _classifier(weights: Optional[Path]):
    from ncbot.vision.classifier import load_classifier

    return load_classifier(weights)


def _board_text(cells: list[str], cols: int) -> str:
    rows = [" ".join(_SYMBOL[c] for c in cells[r:r + cols]) for r in range(0, len(cells), cols)]
    return " / ".join(rows)


@vision_app.command()
def read(images: list[Path] = typer.Argument(..., help="Photos of a game sheet, or folders of them."),
         grid: str = typer.Option("3", help="3 (noughts & crosses), 9 (ultimate) or ROWSxCOLS, e.g. 6x7 (a "
                                  "declared game's plain grid; 3..9 each)."),
         json_out: bool = json_option(),
         weights: Optional[Path] = typer.Option(None, help="Classifier weights (default: the shipped ones)."),
         rho: Optional[int] = typer.Option(None, min=8, max=256, help="Pixels per cell of the grid warp (default 64 / 40; 8..256).")) -> None:
    """Read the board on each photo: row-major cells "x" / "o" / "" over the full grid."""
    from ncbot.vision.grid import read_board
    from ncbot.vision.sheet import grid_shape, parse_grid

    shape = parse_grid(grid)
    cols = grid_shape(shape)[1]
    paths = image_files(images)
    _setup_threads()
    classifier = _classifier(weights)

    def read_one(path: Path) -> dict:
        image = _load_image(path)
        check_grid_fits(image, shape)
        cells = read_board(image, shape, classifier, rho)
        if not json_out:
            typer.echo(f"{path}: {_board_text(cells, cols)}")
        return {"image": str(path), "cells": cells}

    _each_image(paths, read_one, json_out)


def _each_image(paths: list[Path], read_one, json_out: bool) -> None:
    """Read every image; one line on stderr for each that cannot be read; exit 2 when any could not (for one image,
    its line is the only one)."""
    from ncbot.pipelines.errors import one_line

    results = []
    for path in paths:
        try:
            results.append(read_one(path))
        except (ValueError, OSError) as error:
            reason = one_line(error)
            results.append({"image": str(path), "error": reason})
            typer.echo(f"ncbot: error: {reason if str(path) in reason else f'{path}: {reason}'}", err=True)
    if json_out:
        print_json({"images": results})
    if any("error" in result for result in results):
        raise typer.Exit(2)


@vision_app.command()
def classify(images: list[Path] = typer.Argument(..., help="Crops of one cell each (any size; resized to 40x40), or "
                                                 "folders of them."),
             json_out: bool = json_option(),
             weights: Optional[Path] = typer.Option(None, help="Classifier weights (default: the shipped ones).")) -> None:
    """Classify each cell image as nought / cross / nothing with the CNN + SVM."""
    paths = image_files(images)
    _setup_threads()
    classifier = _classifier(weights)

    def classify_one(path: Path) -> dict:
        label, scores = classifier.classify_image(_load_image(path))
        if not json_out:
            typer.echo(f"{path}: {label} (scores {' '.join(f'{s:.2f}' for s in scores)})")
        return {"image": str(path), "label": label, "scores": [round(s, 4) for s in scores]}

    _each_image(paths, classify_one, json_out)


@vision_app.command()
def train(out: Path = out_file(Path("runs/vision/cell_cnn.pt"), "the weights (.pt; default runs/vision/cell_cnn.pt: "
                                "the shipped vision/weights/cell_cnn.pt changes only when named here)."),
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
          as_json: bool = json_option(),
          no_progress: bool = no_progress_option(),
          ) -> None:
    """Train the default cell classifier (the shipped vision/weights/cell_cnn.pt) on generated data, or with
    --budget N the same recipe on N labelled cells (109 : 201 clean : noisy, as the paper)."""
    from ncbot.vision.classifier import FitConfig, save_weights
    from ncbot.vision.data import TRAIN_SEED
    from ncbot.vision.training import DefaultTraining, train_default

    check_writable_file(out, "--out", (".pt",))
    if budget is not None:
        from ncbot.vision.budget import train_budget

        if data_seed is not None:
            raise ValueError("--data-seed does not apply with --budget: --seed picks the draw (vision.data.BUDGET_SEED + 10,000 x seed)")
        _setup_threads()
        model, meta = train_budget(budget, seed, updates, progress=progress_bar)
        _trained(save_weights(model, out, meta), meta, as_json,
                 f"{meta['clean']} clean + {meta['noisy_generated']} generated noisy + {meta['noisy_photo']} photo "
                 f"cells, {meta['updates']} updates, seed {seed}")
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
    _trained(save_weights(model, out, meta), meta, as_json, f"{meta['n_training_cells']} training cells")


def _trained(path: Path, meta: dict, as_json: bool, text: str) -> None:
    """What `vision train` made and where: the weights' metadata, then the `wrote` line."""
    if as_json:
        print_json({**meta, "written": [str(path)]})
    else:
        typer.echo(text)
    wrote(f"{path} (use it with --weights {path})")


@vision_app.command("eval")
def evaluate(out: Path = out_folder(Path("runs/vision"), "the markdown, PNG and JSON reports."),
             what: str = typer.Option("paper,cells,reading,recogniser",
                                      help="Comma list of: paper, cells, reading, recogniser, harsh."),
             frames: int = typer.Option(100, min=1, help="Photos per grid size and style for 'reading' and 'harsh'."),
             sequences: int = typer.Option(120, min=1, help="'recogniser': 3x3 drawing sequences per mark style set."),
             sequences9: int = typer.Option(40, min=1, help="'recogniser': 9x9 drawing sequences per mark style set."),
             seed_set: str = typer.Option("heldout", help="'recogniser', 'harsh': heldout (never tuned on) or tuning "
                                          "data; 'harsh' also tuning-style (tuning seeds, the tuning handwriting "
                                          "\"marker\", on which training choices are judged)."),
             weights: Optional[Path] = typer.Option(None, help="Weights for 'cells'/'reading' (default: shipped)."),
             loo_folds: Optional[int] = typer.Option(None, min=1, help="Run only the first LOO folds (default all 109)."),
             as_json: bool = json_option(), no_progress: bool = no_progress_option()) -> None:
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
    written, found, texts = [], {}, []

    def report(part: str, results: list, stem: str) -> None:
        written.extend(ex.write_report(results, out, stem))
        found[part] = [result.to_json() for result in results]
        texts.append(ex.markdown(results))

    if "paper" in parts:
        report("paper", ex.paper_experiments(progress=progress_bar, loo_folds=loo_folds), "paper_experiments")
    classifier = _classifier(weights) if {"cells", "reading", "recogniser", "harsh"} & set(parts) else None
    if "cells" in parts:
        report("cells", ex.heldout_cells(classifier), "heldout_cells")
    if "reading" in parts:
        report("reading", [ex.reading(grid, frames, styles, classifier, progress=progress_bar)
                           for grid in (3, 9) for styles in (("pen",), ("sketch", "hershey"))], "reading")
    if "harsh" in parts:
        stem = {"heldout": "reading_harsh", "tuning": "reading_harsh_tuning", "tuning-style": "reading_harsh_tuning_style"}[seed_set]
        report("harsh", ex.harsh_reading(frames, seed_set, classifier, progress=progress_bar), stem)
        if seed_set == "heldout":
            ex.harsh_frames_png(out / "reading_harsh_frames.png", classifier=classifier)
            written.append(out / "reading_harsh_frames.png")
    if "recogniser" in parts:
        from ncbot.vision import recogniser_eval as rx

        base = rx.HELDOUT_SEED if seed_set == "heldout" else rx.TUNING_SEED
        sets = [rx.evaluate_sequences(grid, n, base + offset, styles, classifier, progress=progress_bar)
                for grid, n in ((3, sequences), (9, sequences9))
                for offset, styles in ((0, ("pen",)), (100_000, ("sketch", "hershey")))]
        written += rx.write_report(sets, out, "recogniser" if seed_set == "heldout" else "recogniser_tuning")
        found["recogniser"] = [found_set.summary() for found_set in sets]
        texts.append(rx.markdown(sets))
    if as_json:
        print_json({**found, "written": [str(path) for path in written]})
    else:
        typer.echo("\n".join(texts))
    wrote(listing(written))


@vision_app.command()
def generate(kind: str = typer.Argument(..., help="cells, frames or sequence."),
             out: Path = out_folder(..., "the images (PNG) and their labels.jsonl."),
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
                                                                   "`ncbot robot --conditions`, the simulated room."),
             as_json: bool = json_option()) -> None:
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
    images = [str(out / record["image"]) for record in records]
    if as_json:
        print_json({"images": images, "labels": str(out / "labels.jsonl"), "written": [*images, str(out / "labels.jsonl")]})
    wrote(f"{len(records)} image{'s' if len(records) != 1 else ''} and labels.jsonl to {out}")


def _game_grid(game: str):
    """The grid of the sheet of ``game`` (the user names it here: a game class is imported); one line when the sheet
    cannot draw its board."""
    from ncbot.envs.games import load_game
    from ncbot.vision.sheet import game_grid

    return game_grid(load_game(game))


def register(app: typer.Typer) -> None:
    """Add `ncbot vision ...` to the root app."""
    app.add_typer(vision_app, name="vision")
