"""The reader that learns from play (`ncbot.vision.online`): settled cells as labels, the ink check against wrong
labels, real CNN updates with rehearsal that are kept only when not worse on the check set, and resuming."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from ncbot.vision.budget import heldout
from ncbot.vision.classifier import save_weights
from ncbot.vision.classifier.inference import CellClassifier, load_classifier
from ncbot.vision.classifier.train import FitConfig, fit
from ncbot.vision.data.cells import make_cells
from ncbot.vision.labels import CROSS, NOTHING, NOUGHT
from ncbot.vision.online import CellExamples, ReaderLearner, ReaderLearning, View, settled_examples
from ncbot.vision.online.examples import is_held_back
from ncbot.vision.online.heldout import style_cells
from ncbot.vision.online.plausible import plausible

torch.set_num_threads(1)


def test_every_cell_of_a_view_is_labelled_by_the_moves_made_before_it() -> None:
    blank = np.zeros((9, 40, 40), np.uint8)
    moves = [(4, CROSS), (0, NOUGHT), (8, CROSS)]
    examples = settled_examples([View(blank, 1), View(blank, 3)], moves, game=7)
    first, last = examples.labels[:9], examples.labels[9:]
    assert first[4] == CROSS and (np.delete(first, 4) == NOTHING).all()
    assert (last[[4, 0, 8]] == [CROSS, NOUGHT, CROSS]).all() and (np.delete(last, [0, 4, 8]) == NOTHING).all()
    assert (examples.games == 7).all() and (examples.positions == np.tile(np.arange(9), 2)).all()
    # the check set is chosen per (game, position): one mark is never both trained on and checked with
    assert (examples.held_back == [is_held_back(7, p) for p in examples.positions]).all()
    assert examples.held_back[:9].tolist() == examples.held_back[9:].tolist()


def test_a_move_outside_the_sheet_is_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match="outside the 9-cell sheet"):
        settled_examples([View(np.zeros((9, 40, 40), np.uint8), 1)], [(9, CROSS)], game=0)


def test_the_ink_check_rejects_marks_moved_to_another_cell() -> None:
    images, labels = make_cells(60, 123, styles=("pen",))
    games = np.zeros(60, np.int64)
    assert plausible(images, labels, games).mean() > 0.9  # true labels pass
    marks, empties = np.flatnonzero(labels != NOTHING), np.flatnonzero(labels == NOTHING)
    lied = labels.copy()
    lied[marks[:10]] = NOTHING      # a mark said to be nothing
    lied[empties[:10]] = NOUGHT     # an empty cell said to hold the person's mark
    keep = plausible(images, lied, games)
    assert not keep[empties[:10]].any()  # no ink where a mark is claimed
    assert keep[marks[:10]].sum() <= 2  # a mark drawn with a thin pen can hold less ink than half the median mark


def test_held_out_style_cells_are_the_budgets_held_out_cells() -> None:
    data = heldout(n_cells=50, n_photos=0)
    for style in ("sketch", "hershey"):
        images, labels = style_cells(style, 50)
        assert np.array_equal(images, data.cells[style][0]) and np.array_equal(labels, data.cells[style][1])
    with pytest.raises(ValueError, match="handwriting style 'biro' is unknown"):
        style_cells("biro")


@pytest.fixture(scope="module")
def weak_weights(tmp_path_factory) -> Path:
    """A reader trained briefly on 90 "pen" cells: it reads the "marker" hand poorly, so learning can show."""
    images, labels = make_cells(90, 4242, styles=("pen",))
    model = fit(images, labels, FitConfig(epochs=40, batch_size=32, lr=3e-3, seed=0))
    return save_weights(model, tmp_path_factory.mktemp("weak") / "weak.pt", {"n_training_cells": 90})


def person_examples(game: int, n: int = 240, lie: bool = False) -> CellExamples:
    images, labels = make_cells(n, 600 + game, noisy_fraction=0.5, styles=("marker",))
    if lie:  # every label wrong: crosses and noughts swapped, empty cells said to hold a mark
        labels = np.array([{NOUGHT: CROSS, CROSS: NOUGHT, NOTHING: NOUGHT}[int(k)] for k in labels])
    positions = np.arange(n) % 9
    return CellExamples(images, labels, np.full(n, game), positions, np.zeros(n, bool))


def test_an_update_from_the_persons_cells_reads_their_hand_better_and_is_kept(weak_weights: Path, tmp_path: Path) -> None:
    learner = ReaderLearner.start(weak_weights, ReaderLearning(updates=60, seed=1), tmp_path / "reader")
    test_images, test_labels = style_cells("marker", 300)
    before = float((learner.classifier.predict(test_images) == test_labels).mean())
    report = learner.add_game(person_examples(0))
    after = float((learner.classifier.predict(test_images) == test_labels).mean())
    assert report.updated and report.kept and report.check_errors_after <= report.check_errors_before
    assert after > before + 0.03, (before, after)
    assert Path(report.weights).is_file() and learner.current == "game-0000.pt"
    kept = load_classifier(report.weights)
    assert np.array_equal(kept.predict(test_images), learner.classifier.predict(test_images))


def test_an_update_that_makes_the_reader_worse_is_rolled_back(weak_weights: Path) -> None:
    learner = ReaderLearner.start(weak_weights, ReaderLearning(updates=60, filter_labels=False, rehearsal_share=0.1))
    before = {k: v.clone() for k, v in learner.model.state_dict().items()}
    report = learner.add_game(person_examples(0, lie=True))
    assert report.updated and not report.kept and report.check_errors_after > report.check_errors_before
    assert all(torch.equal(before[k], v) for k, v in learner.model.state_dict().items())


def test_updates_run_every_n_games_that_showed_the_sheet(weak_weights: Path) -> None:
    learner = ReaderLearner.start(weak_weights, ReaderLearning(every=2, updates=5))
    assert not learner.add_game(person_examples(0, 30)).updated
    assert not learner.add_game(CellExamples.empty()).updated  # a game without looks does not count
    assert learner.add_game(person_examples(2, 30)).updated


def test_a_resumed_learner_has_the_committed_weights_and_cells_and_ignores_later_files(weak_weights: Path,
                                                                                       tmp_path: Path) -> None:
    folder = tmp_path / "reader"
    learner = ReaderLearner.start(weak_weights, ReaderLearning(updates=10), folder)
    learner.add_game(person_examples(0, 45))
    state = learner.state()
    learner.add_game(person_examples(1, 45))  # written, but never committed: a crash before the commit
    resumed = ReaderLearner.resume(folder, state, ReaderLearning(updates=10))
    assert resumed.games == 1 and len(resumed.examples) == 45 and resumed.current == state["current"]
    images, _ = style_cells("marker", 100)
    reference = CellClassifier(load_classifier(folder / state["current"]).model)
    assert np.array_equal(resumed.classifier.scores(images), reference.scores(images))
    with pytest.raises(ValueError, match="learning state .* incomplete"):
        ReaderLearner.resume(folder, {"games": 1}, ReaderLearning())
