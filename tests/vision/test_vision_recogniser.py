"""Algorithm 1 on frame sequences of a person drawing a move with a hand over the sheet."""
import cv2
import numpy as np
import pytest
import torch

from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.frames import make_frame
from ncbot.vision.data.sequences import make_move_sequence
from ncbot.vision.page import find_page
from ncbot.vision.recogniser import MoveRecogniser

torch.set_num_threads(1)


def _run(rec: MoveRecogniser, seq):
    rec.reset()
    statuses = []
    for frame, hand in zip(seq.frames, seq.hand):
        result = rec.update(frame, seq.known_board)
        statuses.append(result.status)
        if hand:  # a frame showing the hand is never read into the vote (skipped, or too few frames yet)
            assert result.status in ("moving", "occluded", "no_page") or result.cells is None, statuses
        if result.status == "move":
            assert not hand, "a move was reported from a frame showing the hand"
            return result, statuses
    return None, statuses


@pytest.mark.parametrize("grid, seed, still", [(3, 1, 0), (3, 2, 0), (3, 3, 2), (3, 4, 1), (9, 5, 1)])
def test_move_reported_within_three_clean_frames_never_with_the_hand(grid, seed, still) -> None:
    seq = make_move_sequence(grid, TEST_SEED + 500 + seed, before=3, drawing=4, after=4, still_hand=still)
    result, statuses = _run(MoveRecogniser(grid), seq)
    assert result is not None, statuses
    assert (result.move, result.label) == (seq.move, seq.symbol)
    first_clean_after = max(i for i, h in enumerate(seq.hand) if h) + 1
    assert len(statuses) - first_clean_after <= 3, statuses
    assert "moving" in statuses or "occluded" in statuses


# Scenes that once defeated the hand test, each now judged against the page's own paper colour:
# a lavender light clipped to white along one side; a mint sticky note touching a 9x9 sheet (merged into
# the page, it bent the corners); bold filled "0" glyphs (blobs as wide as a palm's opening); a 9x9 sheet
# under a dark vignette with a corner that jitters (the motion test warps all three frames alike); an arm
# across a 9x9 sheet's edge that cuts a piece off the page (the hand then lies outside the found page);
# a hand drawing at the sheet's edge with only its pen over the page (changed pixels around the page).
@pytest.mark.parametrize("grid, seed, still, styles", [
    (9, TEST_SEED + 400_003, 0, ("pen",)),
    (9, TEST_SEED + 180_012, 0, ("sketch", "hershey")),
    (3, TEST_SEED + 80_013, 1, ("pen",)),
    (9, TEST_SEED + 180_011, 2, ("sketch", "hershey")),
    (3, TEST_SEED + 180_053, 2, ("sketch", "hershey")),
    (9, TEST_SEED + 80_005, 2, ("pen",)),
])
def test_scenes_that_fooled_the_hand_test(grid, seed, still, styles) -> None:
    seq = make_move_sequence(grid, seed, before=3, drawing=4, after=5, still_hand=still, styles=styles)
    result, statuses = _run(MoveRecogniser(grid), seq)
    assert result is not None, statuses
    assert (result.move, result.label) == (seq.move, seq.symbol)
    first_clean_after = max(i for i, h in enumerate(seq.hand) if h) + 1
    assert len(statuses) - first_clean_after <= 3, statuses
    assert "occluded" not in statuses[:3], statuses  # nothing on the sheet before the hand came


def test_sequence_evaluation_reports(tmp_path) -> None:
    from ncbot.vision.recogniser_eval import TUNING_SEED, evaluate_sequences, write_report

    result = evaluate_sequences(3, 2, TUNING_SEED)
    summary = result.summary()
    assert summary["sequences"] == 2 and summary["on_target"] == 2 and summary["reported_from_hand_frame"] == 0
    assert sum(result.hand_frame_status.values()) == 2 * 4 + 1  # 4 drawing frames each, + 1 still-hand frame
    paths = write_report([result], tmp_path, "rec")
    assert [p.name for p in paths] == ["rec.md", "rec.json", "rec.png"] and all(p.stat().st_size > 0 for p in paths)
    assert "**2/2**" in paths[0].read_text()
    with pytest.raises(ValueError, match="at least one"):
        evaluate_sequences(3, 0)


def test_no_move_while_the_board_is_unchanged() -> None:
    seq = make_move_sequence(3, TEST_SEED + 520, before=5, drawing=0, after=0)
    rec = MoveRecogniser(3)
    statuses = [rec.update(f, seq.known_board).status for f in seq.frames]
    assert statuses[:2] == ["waiting", "waiting"] and set(statuses) == {"waiting"}


def test_already_known_marks_are_not_moves() -> None:
    frame = make_frame(3, TEST_SEED + 521)
    rec = MoveRecogniser(3)
    results = [rec.update(frame.image, frame.board) for _ in range(3)]
    assert results[-1].status == "waiting" and results[-1].probabilities.shape == (9, 3)
    empty_known = [""] * 9
    if any(frame.board):
        rec.reset()
        result = [rec.update(frame.image, empty_known) for _ in range(3)][-1]
        assert result.status == "move" and frame.board[result.move] == result.label


def test_page_not_found() -> None:
    table = np.full((480, 640, 3), 60, np.uint8)
    result = MoveRecogniser(3).update(table, [""] * 9)
    assert result.status == "no_page" and "sheet" in result.detail


def test_env_style_boards_and_bad_arguments() -> None:
    frame = make_frame(3, TEST_SEED + 522)
    rec = MoveRecogniser(3)
    assert rec.update(frame.image, np.zeros(9, np.int8)).status == "waiting"
    with pytest.raises(ValueError, match="9 cells"):
        rec.update(frame.image, [""] * 8)
    with pytest.raises(ValueError, match="tau"):
        MoveRecogniser(3, tau=-1)
    with pytest.raises(ValueError, match="grid must be 3"):
        MoveRecogniser(5)


def test_recognise_loop_stops_at_the_move() -> None:
    seq = make_move_sequence(3, TEST_SEED + 530, before=2, drawing=3, after=5)
    result = MoveRecogniser(3, gamma_ms=0).recognise(iter(seq.frames), seq.known_board)
    assert result.status == "move" and result.move == seq.move


def _away(frame: np.ndarray, scale: float) -> np.ndarray:
    """The same view with the sheet further from the camera: scaled about the frame's centre, table around it."""
    h, w = frame.shape[:2]
    m = cv2.getRotationMatrix2D((w / 2, h / 2), 0.0, scale)
    return cv2.warpAffine(frame, m, (w, h), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_REPLICATE)


def _first_move(rec: MoveRecogniser, frames, known):
    statuses = [rec.update(f, known) for f in frames]
    return next((r for r in statuses if r.status == "move"), None), [r.status for r in statuses]


def test_a_sheet_nudged_away_mid_turn_is_still_read() -> None:
    # random preset, seed 11, game 13: the person nudged the sheet while drawing, its page came out 5 % smaller
    # and every later frame was judged "part of the sheet is hidden" until the turn ran out
    seq = make_move_sequence(3, TEST_SEED + 530, before=3, drawing=3, after=6)
    frames = seq.frames[:3] + [_away(f, 0.94) for f in seq.frames[3:]]
    rec = MoveRecogniser(3)
    rec.reset()
    result, statuses = _first_move(rec, frames, seq.known_board)
    assert result is not None and (result.move, result.label) == (seq.move, seq.symbol), statuses


def test_an_arm_resting_over_a_corner_of_the_sheet_is_not_a_clean_frame() -> None:
    # the arm hides a corner of the page and lies outside the page found without it: the page shrank against
    # its grid (which the arm leaves whole), so no move is read while it rests there
    seq = make_move_sequence(3, TEST_SEED + 530, before=3, drawing=3, after=6)
    rec = MoveRecogniser(3)
    rec.reset()
    corners = find_page(seq.frames[0])
    tl = corners[0]
    arm = np.array([tl + (-80, -80), tl + (140, -80), tl + (-80, 140)], np.int32)  # over the top-left corner
    frames = [f.copy() for f in seq.frames]
    for f in frames[3:]:
        cv2.fillConvexPoly(f, arm, (120, 150, 200))
    result, statuses = _first_move(rec, frames, seq.known_board)
    assert result is None, statuses
    assert statuses[-1] == "occluded", statuses
