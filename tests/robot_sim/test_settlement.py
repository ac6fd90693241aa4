"""What a robot game settles for the reader that learns from play (`robot_sim.settlement`), the simulated person's
handwriting (`handwriting:` in a conditions file) and wrong claims; no rendering."""
from __future__ import annotations

import numpy as np
import pytest

from ncbot.robot_sim.conditions import PRESETS, SceneConditions, load_conditions, sample_conditions, sample_handwriting
from ncbot.robot_sim.human import HumanConfig, SimulatedHuman
from ncbot.robot_sim.settlement import GameViews, claim_moves, labelled_moves, moves_from_boards
from ncbot.robot_sim.sheet import HUMAN_INK, MarkSpec, SheetCanvas
from ncbot.vision.data.frames import make_frame
from ncbot.vision.labels import CROSS, NOUGHT

BOARDS = ["000010000", "200010000", "200010001", "200210001", "200210101"]  # 1 robot, 2 person, after each move


def test_moves_are_read_off_the_true_boards_in_order() -> None:
    assert moves_from_boards(BOARDS) == [(4, 1), (0, 2), (8, 1), (3, 2), (6, 1)]
    with pytest.raises(ValueError, match="differ by one new mark"):
        moves_from_boards(["000010000", "200010001"])


def test_the_first_player_draws_crosses() -> None:
    moves = moves_from_boards(BOARDS)
    assert labelled_moves(moves, robot_first=True)[:2] == [(4, CROSS), (0, NOUGHT)]
    assert labelled_moves(moves, robot_first=False)[:2] == [(4, NOUGHT), (0, CROSS)]


def test_a_person_who_lies_moves_only_their_own_marks_to_cells_that_stayed_empty() -> None:
    moves = moves_from_boards(BOARDS)
    rng = np.random.default_rng(0)
    assert claim_moves(moves, 9, 0.0, rng) == moves
    claimed = claim_moves(moves, 9, 1.0, rng)
    assert [m for m in claimed if m[1] == 1] == [m for m in moves if m[1] == 1], "the robot's moves are not disputed"
    person = [cell for cell, player in claimed if player == 2]
    assert set(person) <= {1, 2, 5, 7} and len(set(person)) == 2, "claimed in cells no one drew in"
    human = SimulatedHuman(scene=None, game=None, config=HumanConfig(wrong_claims=0.5), seed=3)
    again = SimulatedHuman(scene=None, game=None, config=HumanConfig(wrong_claims=0.5), seed=3)
    assert human.settle(moves, 9) == again.settle(moves, 9), "one seed, the same claims"
    with pytest.raises(ValueError, match="wrong_claims must be a share"):
        SimulatedHuman(scene=None, game=None, config=HumanConfig(wrong_claims=1.5))


def test_views_are_the_cells_the_reader_cuts_after_the_logs_jpeg() -> None:
    views = GameViews(3, jpeg_quality=80)
    frame = make_frame(3, 9_123_456)
    views.add(frame.image, moves=2)
    views.add(np.zeros((240, 320, 3), np.uint8), moves=3)  # no sheet in view: not a view
    taken = views.take()
    assert len(taken) == 1 and taken[0].cells.shape == (9, 40, 40) and taken[0].moves == 2
    assert views.unread == 1 and views.take() == []


def test_handwriting_in_a_conditions_file_is_checked_and_drawn_per_game(tmp_path) -> None:
    path = tmp_path / "sketchy.yaml"
    path.write_text("base: lab\nhandwriting: [sketch, hershey]\n")
    ranges = load_conditions(path)
    assert ranges.handwriting == ("sketch", "hershey") and PRESETS["lab"].handwriting == ("pen",)
    drawn = {sample_handwriting(ranges, seed) for seed in range(20)}
    assert drawn == {"sketch", "hershey"} and sample_handwriting(ranges, 5) == sample_handwriting(ranges, 5)
    assert sample_conditions(ranges, 7) == SceneConditions(seed=7), "only the hand changed: still the lab"
    for bad in ("handwriting: [biro]", "handwriting: []", "handwriting: sketch"):
        (tmp_path / "bad.yaml").write_text(f"base: lab\n{bad}\n")
        with pytest.raises(ValueError, match="handwriting must be a non-empty list of pen"):
            load_conditions(tmp_path / "bad.yaml")


def test_a_mark_is_drawn_in_the_persons_handwriting() -> None:
    pictures = {}
    for style in ("pen", "sketch", "hershey"):
        canvas = SheetCanvas(3, 300)
        mark = MarkSpec(4, "nought", 11, HUMAN_INK, style=style)
        canvas.draw(mark, 1.0)
        pictures[style] = canvas.image.copy()
        assert mark.strokes(3, 300), "the hand always has a path to follow (a font glyph: the pen model's)"
    assert not np.array_equal(pictures["pen"], pictures["sketch"])
    assert not np.array_equal(pictures["pen"], pictures["hershey"])
