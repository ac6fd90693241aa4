"""The seeded generators: same seed -> same pixels, marks drawn where asked, progress animates a drawing."""
import cv2
import numpy as np
import pytest

from ncbot.vision.data import CLEAN_SEED, NOISY_SEED, TEST_SEED, TRAIN_SEED
from ncbot.vision.data.cells import make_cells
from ncbot.vision.data.frames import make_frame
from ncbot.vision.data.sequences import make_move_sequence
from ncbot.vision.sheet import cell_center, draw_sheet
from ncbot.vision.strokes import draw_mark


def test_seeds_for_training_and_testing_differ() -> None:
    assert len({CLEAN_SEED, NOISY_SEED, TRAIN_SEED, TEST_SEED}) == 4
    assert TEST_SEED > TRAIN_SEED + 1_000_000  # the default training draws far fewer seeds than that


def test_cells_are_deterministic_and_balanced() -> None:
    a, la = make_cells(30, 5, noisy=True)
    b, lb = make_cells(30, 5, noisy=True)
    c, _ = make_cells(30, 6, noisy=True)
    assert a.shape == (30, 40, 40) and a.dtype == np.uint8
    assert np.array_equal(a, b) and np.array_equal(la, lb)
    assert not np.array_equal(a, c)
    assert np.bincount(la, minlength=3).tolist() == [10, 10, 10]


def test_marks_put_ink_where_asked_and_progress_draws_part() -> None:
    inks = []
    for progress in (0.0, 0.3, 1.0):
        img = np.full((100, 100, 3), 255, np.uint8)
        draw_mark(img, "nought", (30, 60), 40, np.random.default_rng(3), progress=progress, ink=(200, 0, 0))
        inks.append(int((img.min(axis=2) < 200).sum()))
        if progress == 1.0:
            ys, xs = np.nonzero(img.min(axis=2) < 200)
            assert abs(xs.mean() - 30) < 8 and abs(ys.mean() - 60) < 8
            assert img[ys, xs, 0].mean() > img[ys, xs, 2].mean()  # blue ink (BGR) stays blue
    assert inks[0] == 0 < inks[1] < inks[2]


@pytest.mark.parametrize("style", ["pen", "sketch", "hershey", "hasty", "marker"])
def test_every_style_draws_on_gray_images(style: str) -> None:
    img = np.full((60, 60), 250, np.uint8)
    draw_mark(img, "cross", (30, 30), 40, np.random.default_rng(0), style=style)
    assert (img < 150).sum() > 20


def test_draw_mark_rejects_bad_input() -> None:
    img = np.zeros((10, 10), np.uint8)
    with pytest.raises(ValueError, match="kind"):
        draw_mark(img, "triangle", (5, 5), 5, np.random.default_rng(0))
    with pytest.raises(ValueError, match="progress"):
        draw_mark(img, "cross", (5, 5), 5, np.random.default_rng(0), progress=2.0)
    with pytest.raises(ValueError, match="uint8"):
        draw_mark(img.astype(float), "cross", (5, 5), 5, np.random.default_rng(0))


def test_sheet_layout_puts_cells_between_the_lines() -> None:
    page = draw_sheet(3, 300, 300)
    gray = page.mean(axis=2)
    for cell in range(9):
        x, y = cell_center(3, cell, 300, 300)
        assert gray[int(y), int(x)] > 200  # a cell centre is paper, not a grid line
    assert (gray < 100).sum() > 500       # the grid is drawn
    with pytest.raises(ValueError, match="grid must be 3"):
        draw_sheet(4)


def test_frames_are_deterministic_with_a_truth_board() -> None:
    a, b = make_frame(3, 11), make_frame(3, 11)
    assert a.image.shape == (480, 640, 3) and np.array_equal(a.image, b.image)
    assert len(a.board) == 9 and set(a.board) <= {"", "x", "o"}
    assert a.board == b.board and not np.array_equal(a.image, make_frame(3, 12).image)
    assert len(make_frame(9, 3).board) == 81


def test_move_sequence_draws_the_move_under_a_hand() -> None:
    seq = make_move_sequence(3, 4, before=1, drawing=2, after=1)
    assert seq.hand == [False, True, True, False]
    assert seq.known_board[seq.move] == "" and seq.symbol in ("x", "o")
    assert not np.array_equal(seq.frames[0], seq.frames[-1])


def test_training_tuning_and_heldout_handwriting_stay_apart() -> None:
    from ncbot.vision.strokes import HELDOUT_STYLES, STYLES, TRAINING_STYLES, TUNING_STYLES
    from ncbot.vision.training import DefaultTraining

    groups = [set(TRAINING_STYLES), set(TUNING_STYLES), set(HELDOUT_STYLES)]
    assert set.union(*groups) == set(STYLES) and sum(map(len, groups)) == len(STYLES)
    recipe = DefaultTraining()
    assert set(recipe.cell_styles) | set(recipe.harsh_styles) <= set(TRAINING_STYLES)


def _bleed(style: str) -> float:
    """Share of a mark's inked pixels that are only partly inked (an edge), over 12 marks of width 8 px."""
    partial = inked = 0
    for seed in range(12):
        img = np.full((160, 160), 250, np.uint8)
        draw_mark(img, "nought", (80, 80), 110, np.random.default_rng(seed), width=8.0, style=style, opacity=1.0,
                  ink=(0, 0, 0))
        darkness = (250 - img.astype(float)) / 250
        inked += int((darkness > 0.05).sum())
        partial += int(((darkness > 0.05) & (darkness < 0.8)).sum())
    return partial / inked


def test_marker_ink_bleeds_at_its_edges_and_pen_ink_does_not() -> None:
    # the tuning handwriting is a felt tip: its coverage is blurred, so far more of its ink is edge than a pen's
    assert _bleed("marker") > 1.5 * _bleed("pen")
    assert _bleed("hasty") < 1.2 * _bleed("pen")  # the training variant keeps the pen's ink


def test_marker_noughts_are_not_the_pen_loops() -> None:
    # a rounded polygon or teardrop: the ink strays from the best-fitting ellipse far more than a pen loop's
    def stray(style: str) -> float:
        out = []
        for seed in range(20):
            img = np.full((200, 200), 255, np.uint8)
            draw_mark(img, "nought", (100, 100), 140, np.random.default_rng(seed), width=3.0, style=style,
                      opacity=1.0, ink=(0, 0, 0))
            ys, xs = np.nonzero(img < 128)
            pts = np.stack([xs, ys], 1).astype(np.float32)
            (cx, cy), (w, h), angle = cv2.fitEllipse(pts)
            drawn = np.zeros_like(img)
            cv2.ellipse(drawn, ((cx, cy), (w, h), angle), 255, 1)
            distance = cv2.distanceTransform(255 - drawn, cv2.DIST_L2, 3)
            out.append(float(np.median(distance[ys, xs])) / max(w, h))
        return float(np.median(out))

    assert stray("marker") > 1.5 * stray("pen")
