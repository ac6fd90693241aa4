"""Generated photos of a declared game's rows x cols sheet: read back as their true board, a move drawn on them
recognised, and `ncbot vision generate --grid ROWSxCOLS` writing them."""
import json

import numpy as np
import pytest

from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.frames import make_frame, random_scene
from ncbot.vision.data.sequences import make_move_sequence
from ncbot.vision.grid import read_page
from ncbot.vision.recogniser import MoveRecogniser
from tests.learning_helpers import ncbot


@pytest.mark.parametrize("grid, seed", [((4, 4), 700), ((4, 4), 701), ((6, 7), 702), ((6, 7), 703)])
def test_generated_declared_frames_read_back_as_their_board(grid, seed) -> None:
    frame = make_frame(grid, TEST_SEED + seed)
    assert len(frame.board) == grid[0] * grid[1] and any(frame.board)
    reading = read_page(frame.image, grid)
    assert reading.cells == frame.board


def test_a_rectangular_scene_has_rows_down_and_square_cells_where_the_reader_finds_them() -> None:
    rng = np.random.default_rng(TEST_SEED + 704)
    scene = random_scene((6, 7), rng)
    crossings = scene.grid_crossings()
    assert crossings.shape == (7, 8, 2)
    top, left = crossings[0, 1] - crossings[0, 0], crossings[1, 0] - crossings[0, 0]
    assert np.linalg.norm(top) == pytest.approx(np.linalg.norm(left), rel=0.25)  # square cells, seen at a slant
    quad = crossings[[2, 2, 3, 3], [4, 5, 5, 4]]   # cell c3 (row 2, col 4) = 2 * 7 + 4
    centre = np.array(scene.cell_in_frame(18))
    assert np.allclose(centre, quad.mean(axis=0), atol=1)
    frame = make_frame((6, 7), TEST_SEED + 702)
    found = read_page(frame.image, (6, 7)).grid_corners
    rng = np.random.default_rng(TEST_SEED + 702)
    truth = random_scene((6, 7), rng).grid_crossings()[[0, 0, -1, -1], [0, -1, -1, 0]]
    assert np.abs(found - truth).max() < 2  # the reader's grid lies where the generator drew it


def test_a_move_drawn_on_a_6x7_sheet_is_recognised_never_from_a_hand_frame() -> None:
    seq = make_move_sequence((6, 7), TEST_SEED + 705, before=3, drawing=4, after=5, still_hand=1)
    recogniser = MoveRecogniser((6, 7))
    for frame, hand in zip(seq.frames, seq.hand):
        result = recogniser.update(frame, seq.known_board)
        if result.status == "move":
            assert not hand, "a move was reported from a frame showing the hand"
            break
    assert (result.status, result.move, result.label) == ("move", seq.move, seq.symbol)


def test_cli_generates_declared_frames_and_sequences_and_refuses_a_bad_grid(tmp_path) -> None:
    out = ncbot("vision", "generate", "frames", "--grid", "6x7", "--n", "2", "--seed", "5", "--out", str(tmp_path / "f"))
    assert out.returncode == 0, out.stderr
    records = [json.loads(line) for line in (tmp_path / "f" / "labels.jsonl").read_text().splitlines()]
    assert [r["image"] for r in records] == ["frame_6x7_5.png", "frame_6x7_6.png"]
    assert all(r["grid"] == "6x7" and len(r["cells"]) == 42 and (tmp_path / "f" / r["image"]).is_file() for r in records)
    seq = ncbot("vision", "generate", "sequence", "--grid", "4x4", "--out", str(tmp_path / "s"))
    assert seq.returncode == 0, seq.stderr
    records = [json.loads(line) for line in (tmp_path / "s" / "labels.jsonl").read_text().splitlines()]
    assert records and all(len(r["known_board"]) == 16 and 0 <= r["move"] < 16 for r in records)
    for bad in ("2x12", "4"):
        refused = ncbot("vision", "generate", "frames", "--grid", bad, "--out", str(tmp_path / "bad"))
        assert refused.returncode == 2 and "Traceback" not in refused.stderr
        assert refused.stderr.strip().splitlines() == [f"ncbot: error: --grid must be 3, 9 or ROWSxCOLS with 3..9 each; got {bad}"]
    assert not (tmp_path / "bad").exists()
