"""The reader learns from play: after each game (or every N) the cell classifier is updated from the cells the games
settled, with rehearsal of its own training cells, and the update is kept only if it is not worse on a held-back
check set; otherwise the reader goes on with the weights it had (rolled back).

One update (`ReaderLearner.update`), bounded: `updates` optimiser steps of `batch_size` cells, of which
`rehearsal_share` are the reader's own training cells (so it does not forget them) and the rest the settled cells
not held back, drawn class-balanced (a game shows far more empty cells than marks) and with the training recipe's
augmentation; labels the cell itself contradicts are left out (`vision.online.plausible`). The check set: the
settled cells held back (`vision.online.examples.HELD_BACK_SHARE` of each game's cell positions) plus training-style
cells no classifier is trained on (`vision.online.rehearsal.check_cells`); kept iff the updated reader makes no more
errors on it than the reader it would replace. Every kept version is saved (`game-NNNN.pt`), so any one can be
gone back to.
"""
from __future__ import annotations

import copy
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ncbot.vision.classifier.inference import CellClassifier, load_classifier, save_weights, weights_meta
from ncbot.vision.classifier.model import CellCNN
from ncbot.vision.classifier.train import FitConfig, fit
from ncbot.vision.labels import LABELS
from ncbot.vision.online.examples import CellExamples
from ncbot.vision.online.plausible import plausible
from ncbot.vision.online.rehearsal import check_cells, rehearsal_cells

START_NAME, CURRENT_NAME, EXAMPLES_FOLDER = "start.pt", "reader.pt", "examples"


@dataclass(frozen=True)
class ReaderLearning:
    """How the reader learns from play (defaults chosen on the tuning handwriting, docs/vision.md)."""

    every: int = 1                 # update after every N games
    updates: int = 100             # optimiser steps per update: the compute an update may take
    batch_size: int = 64
    lr: float = 1e-3               # Adam, cosine-decayed to 5 % over the update's steps
    rehearsal_share: float = 0.5   # of each batch: the reader's own training cells
    filter_labels: bool = True     # leave out labels the cell's ink contradicts
    seed: int = 0

    def validate(self) -> None:
        if self.every < 1 or self.updates < 1 or self.batch_size < 2:
            raise ValueError(f"reader learning needs every >= 1, updates >= 1, batch_size >= 2; got {self.every}, "
                             f"{self.updates}, {self.batch_size}")
        if not 0.0 <= self.rehearsal_share < 1.0 or self.lr <= 0:
            raise ValueError(f"reader learning needs 0 <= rehearsal_share < 1 and lr > 0; got {self.rehearsal_share}, {self.lr}")


@dataclass
class ReaderUpdate:
    """What one game taught the reader (one object of the report's `per_game`, key `reader`)."""

    game: int
    examples: dict[str, int]              # settled cells of this game, per label
    updated: bool = False                 # an update ran after this game (every N games)
    kept: bool | None = None              # ... and passed the check (None: no update ran)
    left_out: int = 0                     # cells whose label their ink contradicts (all games so far)
    check_cells: int = 0
    check_errors_before: int | None = None
    check_errors_after: int | None = None
    cpu_seconds: float = 0.0              # of the update and its check, this process
    weights: str | None = None            # the version saved when kept

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def errors(classifier: CellClassifier, images: np.ndarray, labels: np.ndarray) -> int:
    """Cells read wrong."""
    return int((classifier.predict(images) != labels).sum()) if len(labels) else 0


@dataclass
class ReaderLearner:
    """A reader that learns from the games it plays; `add_game` after each game, `state` + `resume` across runs."""

    model: CellCNN
    meta: dict[str, Any]
    settings: ReaderLearning = field(default_factory=ReaderLearning)
    folder: Path | None = None
    examples: CellExamples = field(default_factory=CellExamples.empty)
    games: int = 0
    updates: int = 0
    kept: int = 0
    pending: int = 0

    def __post_init__(self) -> None:
        self.settings.validate()
        self.current = START_NAME  # the file of the current weights in `folder`
        self._rehearsal: tuple[np.ndarray, np.ndarray, str] | None = None
        self._check: tuple[np.ndarray, np.ndarray] | None = None

    # ------------------------------------------------------------------ building
    @classmethod
    def start(cls, weights: str | Path | None, settings: ReaderLearning, folder: str | Path | None = None) -> "ReaderLearner":
        """A learner from classifier weights (None: the shipped ones); with `folder` its versions are saved there."""
        classifier = load_classifier(weights)
        meta = weights_meta(weights)
        learner = cls(copy.deepcopy(classifier.model), meta, settings, Path(folder) if folder is not None else None)
        if learner.folder is not None:
            (learner.folder / EXAMPLES_FOLDER).mkdir(parents=True, exist_ok=True)
            save_weights(learner.model, learner.folder / START_NAME, {**meta, "learned_games": 0})
            save_weights(learner.model, learner.folder / CURRENT_NAME, {**meta, "learned_games": 0})
        return learner

    @classmethod
    def resume(cls, folder: str | Path, state: dict[str, Any], settings: ReaderLearning) -> "ReaderLearner":
        """The learner as `state()` described it when its last game was committed: the weights it named, the settled
        cells of those games (files of later games, written before a crash, are ignored and rewritten)."""
        folder = Path(folder)
        try:
            games, current = int(state["games"]), str(state["current"])
            counters = {key: int(state[key]) for key in ("updates", "kept", "pending")}
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"the reader's learning state for {folder} is incomplete; expected the state a learning "
                             f"run wrote") from None
        model = copy.deepcopy(load_classifier(folder / current).model)
        examples = CellExamples.empty()
        for game in range(games):
            path = folder / EXAMPLES_FOLDER / f"game-{game:04d}.npz"
            if path.is_file():
                examples = examples.concat(CellExamples.load(path))
        learner = cls(model, weights_meta(folder / START_NAME), settings, folder, examples, games=games, **counters)
        learner.current = current
        return learner

    def state(self) -> dict[str, Any]:
        """What a resumed run needs (json-able): counters and the file of the current weights."""
        return {"games": self.games, "updates": self.updates, "kept": self.kept, "pending": self.pending,
                "current": self.current}

    @property
    def classifier(self) -> CellClassifier:
        """The reader as it reads now (a new object after every kept update)."""
        return CellClassifier(self.model)

    @property
    def weights_path(self) -> Path | None:
        return None if self.folder is None else self.folder / CURRENT_NAME

    def rehearsal(self) -> tuple[np.ndarray, np.ndarray, str]:
        if self._rehearsal is None:
            self._rehearsal = rehearsal_cells(self.meta)
        return self._rehearsal

    def check(self) -> tuple[np.ndarray, np.ndarray]:
        """The check set: held-back settled cells (whose ink does not contradict their label) + training-style cells."""
        if self._check is None:
            self._check = check_cells()
        held = self.examples.select(self.examples.held_back)
        if self.settings.filter_labels and len(held):
            held = held.select(plausible(held.images, held.labels, held.games))
        return np.concatenate([held.images, self._check[0]]), np.concatenate([held.labels, self._check[1]])

    # ------------------------------------------------------------------ learning
    def add_game(self, examples: CellExamples) -> ReaderUpdate:
        """Take one game's settled cells; update after every `every` games that had some."""
        report = ReaderUpdate(game=self.games, examples=examples.counts())
        if self.folder is not None:
            examples.save(self.folder / EXAMPLES_FOLDER / f"game-{self.games:04d}.npz")
        self.examples = self.examples.concat(examples)
        self.games += 1
        self.pending += int(len(examples) > 0)  # a game without a look at the sheet teaches nothing new
        if self.pending >= self.settings.every:
            self.pending = 0
            self.update(report)
        return report

    def training_batch_cells(self) -> tuple[np.ndarray, np.ndarray, int]:
        """The cells of one update: rehearsal and settled cells (class-balanced) in the configured shares, and how
        many settled cells were left out as contradicted by their ink."""
        settings = self.settings
        rng = np.random.default_rng([settings.seed, self.updates])
        pool = self.examples.select(~self.examples.held_back)
        left_out = 0
        if settings.filter_labels and len(pool):
            keep = plausible(pool.images, pool.labels, pool.games)
            left_out = int((~keep).sum())
            pool = pool.select(keep)
        total = settings.updates * settings.batch_size
        rehearse_images, rehearse_labels, _ = self.rehearsal()
        n_play = 0 if len(pool) == 0 else int(round(total * (1.0 - settings.rehearsal_share)))
        pick = rng.integers(len(rehearse_labels), size=total - n_play)
        images, labels = [rehearse_images[pick]], [rehearse_labels[pick]]
        if n_play:
            present = [k for k in range(len(LABELS)) if (pool.labels == k).any()]
            classes = rng.choice(present, size=n_play)
            chosen = np.array([rng.choice(np.flatnonzero(pool.labels == k)) for k in classes])
            images.append(pool.images[chosen])
            labels.append(pool.labels[chosen])
        order = rng.permutation(total)
        return np.concatenate(images)[order], np.concatenate(labels)[order], left_out

    def update(self, report: ReaderUpdate) -> None:
        """One bounded update from everything settled so far; kept iff not worse on the check set."""
        started = time.process_time()
        images, labels, report.left_out = self.training_batch_cells()
        candidate = copy.deepcopy(self.model)
        config = FitConfig(epochs=1, batch_size=self.settings.batch_size, lr=self.settings.lr,
                             seed=self.settings.seed * 100_003 + self.updates)
        with torch.random.fork_rng():  # the caller's torch stream (the robot's policy) is left as it was
            fit(images, labels, config, model=candidate)
        check_images, check_labels = self.check()
        before, after = (errors(CellClassifier(m), check_images, check_labels) for m in (self.model, candidate))
        self.updates += 1
        report.updated, report.kept = True, after <= before
        report.check_cells, report.check_errors_before, report.check_errors_after = len(check_labels), before, after
        if report.kept:
            self.model = candidate.eval()
            self.kept += 1
            if self.folder is not None:
                self.current = f"game-{report.game:04d}.pt"
                for name in (self.current, CURRENT_NAME):
                    save_weights(self.model, self.folder / name, {**self.meta, "learned_games": self.games})
                report.weights = str(self.folder / self.current)
        else:
            self.model.eval()
        report.cpu_seconds = round(time.process_time() - started, 3)
