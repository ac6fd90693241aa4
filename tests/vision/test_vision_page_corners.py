"""The page's corners are named once each, whatever the sheet's turn (seen with the random preset, seed 11, game 13).

A sheet whose top and right corners lay on the same y - x line (turned ~25 degrees, seen in perspective) had
one corner named twice by the old per-extreme ordering, so the page was dropped in about half of the frames
of the person's turn and their three moves went unseen."""
from __future__ import annotations

import cv2
import numpy as np

from ncbot.vision.page import find_page, order_corners

# the quad the page finder fitted on that game's frames (640x480): (573, 285) and (401, 113) tie on y - x
TIED = np.array([[573, 285], [250, 434], [148, 183], [401, 113]], np.float32)
EXPECTED = np.array([[148, 183], [401, 113], [573, 285], [250, 434]], np.float32)  # TL, TR, BR, BL


def test_tied_corners_are_each_named_once() -> None:
    for shift in range(4):  # whatever order the contour lists them in
        assert np.array_equal(order_corners(np.roll(TIED, shift, axis=0)), EXPECTED)


def test_an_upright_sheet_keeps_its_corner_names() -> None:
    square = np.array([[10, 10], [90, 12], [88, 95], [12, 90]], np.float32)
    for shift in range(4):
        assert np.array_equal(order_corners(np.roll(square, shift, axis=0)), square)


def test_a_white_sheet_on_a_light_table_with_tied_corners_is_found() -> None:
    rng = np.random.default_rng(0)
    frame = np.full((480, 640, 3), 118, np.uint8)  # light grey laminate
    cv2.fillConvexPoly(frame, EXPECTED.astype(np.int32), (178, 182, 184))  # the sheet, a little darker than white
    for a, b in ((0.33, 0.33), (0.67, 0.67)):  # two grid lines each way, drawn on the sheet
        tl, tr, br, bl = EXPECTED
        cv2.line(frame, tuple((tl + a * (bl - tl)).astype(int)), tuple((tr + b * (br - tr)).astype(int)), (40, 40, 40), 3)
        cv2.line(frame, tuple((tl + a * (tr - tl)).astype(int)), tuple((bl + b * (br - bl)).astype(int)), (40, 40, 40), 3)
    noisy = np.clip(frame.astype(np.int16) + rng.normal(0, 2.6, frame.shape).round().astype(np.int16), 0, 255)
    corners = find_page(noisy.astype(np.uint8))
    assert corners is not None
    assert float(np.abs(corners - EXPECTED).max()) < 10, corners  # the morphology rounds the acute corners a little
