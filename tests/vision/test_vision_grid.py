"""Reading whole boards from generated camera photos (unseen seeds) with the shipped weights."""
import numpy as np
import pytest
import torch

from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.frames import make_frame, random_scene, render
from ncbot.vision.grid import read_board, read_page
from ncbot.vision.page import find_page

torch.set_num_threads(1)


def _read(grid: int, n: int, seed: int, styles=("pen",)) -> tuple[int, float]:
    whole, right, total = 0, 0, 0
    for i in range(n):
        frame = make_frame(grid, seed + i, styles=styles)
        cells = read_board(frame.image, grid)
        hits = sum(a == b for a, b in zip(cells, frame.board))
        whole += hits == len(cells)
        right += hits
        total += len(cells)
    return whole, right / total


def test_reads_3x3_photos() -> None:
    whole, cell_accuracy = _read(3, 12, TEST_SEED + 100)
    assert whole >= 11 and cell_accuracy >= 0.98


def test_reads_3x3_photos_of_held_out_handwriting() -> None:
    whole, cell_accuracy = _read(3, 12, TEST_SEED + 200, styles=("sketch", "hershey"))
    assert whole >= 10 and cell_accuracy >= 0.97


def test_reads_9x9_photos() -> None:
    whole, cell_accuracy = _read(9, 3, TEST_SEED + 300)
    assert cell_accuracy >= 0.97


def test_page_corners_match_the_truth() -> None:
    frame = make_frame(3, TEST_SEED + 400)
    corners = find_page(frame.image)
    assert corners is not None
    assert np.abs(corners - frame.page_corners).max() < 12  # pixels


def test_reading_gives_probabilities_and_no_hand_on_a_clean_photo() -> None:
    frame = make_frame(3, TEST_SEED + 401)
    reading = read_page(frame.image, 3)
    assert reading.probabilities.shape == (9, 3) and np.allclose(reading.probabilities.sum(axis=1), 1, atol=1e-5)
    assert reading.cell_images.shape == (9, 40, 40) and not reading.occluded.any() and reading.hand_fraction == 0


def test_no_sheet_raises_a_clear_error() -> None:
    rng = np.random.default_rng(0)
    table = np.clip(rng.normal(90, 10, (480, 640, 3)), 0, 255).astype(np.uint8)
    with pytest.raises(ValueError, match="no paper sheet"):
        read_board(table, 3)


def test_blank_sheet_without_grid_raises() -> None:
    rng = np.random.default_rng(1)
    scene = random_scene(3, rng)
    scene.page[:] = scene.page.max()  # wipe the grid
    frame = render(scene, [""] * 9, rng)
    with pytest.raises(ValueError, match="no 3x3 grid"):
        read_board(frame, 3)


def test_bad_arguments() -> None:
    frame = make_frame(3, 5).image
    with pytest.raises(ValueError, match="grid must be 3"):
        read_board(frame, 4)
    with pytest.raises(ValueError, match="uint8"):
        read_board(frame.astype(np.float32), 3)
    with pytest.raises(ValueError, match="shape"):
        read_board(np.zeros((10, 10, 3), np.uint8), 3)


def _scan(seed: int) -> tuple[np.ndarray, list[str]]:
    """Another source of boards: a plain white picture, ruler-straight lines and font glyphs (no table)."""
    import cv2

    rng = np.random.default_rng(seed)
    side = int(rng.integers(300, 600))
    img = np.full((side, side, 3), 255, np.uint8)
    margin = side * rng.uniform(0.05, 0.15)
    step = (side - 2 * margin) / 3
    for k in (1, 2):
        at = int(margin + k * step)
        cv2.line(img, (at, int(margin)), (at, int(side - margin)), (0, 0, 0), 3)
        cv2.line(img, (int(margin), at), (int(side - margin), at), (0, 0, 0), 3)
    board = [str(rng.choice(["", "x", "o"])) for _ in range(9)]
    for cell, symbol in enumerate(board):
        if symbol:
            row, col = divmod(cell, 3)
            scale = step * 0.6 / 22
            (w, h), _ = cv2.getTextSize(symbol.upper(), cv2.FONT_HERSHEY_SIMPLEX, scale, 3)
            cv2.putText(img, symbol.upper(), (int(margin + (col + 0.5) * step - w / 2), int(margin + (row + 0.5) * step + h / 2)),
                        cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), 3, cv2.LINE_AA)
    return img, board


def test_reads_a_scan_that_is_all_page() -> None:
    right = 0
    for seed in range(4):
        img, board = _scan(seed)
        right += read_board(img, 3) == board
    assert right >= 3
