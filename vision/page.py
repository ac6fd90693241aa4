"""Finding the paper sheet in a camera frame and warping it flat (steps 2-3 of the paper's Algorithm 1).

The frame is white-balanced first (vision.illumination.balance_frame: a colour cast or dim light). The page
is then the largest bright, unsaturated region (colour-based, threshold chosen per frame by Otsu so uneven
light does not matter much), grown over the parts of the same sheet that lie in a soft shadow (grey, not
too dark, and not across a sharp brightness step: the sheet's own edge); its convex hull is simplified to
four corners, ordered as the camera sees them (top-left first), so a sheet rotated by less than 45
degrees keeps its cell numbering.
"""
from __future__ import annotations

import cv2
import numpy as np

from ncbot.vision.illumination import balance_frame, shade_and_hue

MIN_PAGE_FRACTION = 0.03  # of the frame area: anything smaller is not the game sheet
MAX_PAGE_FRACTION = 0.92  # a "page" filling the whole frame is a uniform image (its corners are not seen)
FILLED_FRACTION = 0.6    # paper over this much of a frame without a page outline: the frame is the page
MIN_WHITENESS = 90        # value - 1.5 x saturation of paper: darker than this is not a white sheet
PAPER_RATIO = 0.66        # paper is at least this fraction of the median paper whiteness (uneven light)
PAGE_HUE_RATIO = 0.1      # against the fitted paper colour, a channel off grey by more: not the page (pastel clutter) ...
PAGE_BRIGHT_RATIO = 0.8   # ... if also about as bright as the paper (ink blurred into paper is darker)
SHADOW_LEVEL = 0.22       # paper in a shadow: at least this fraction of the lit paper's brightness ...
SHADOW_CHROMA = 0.2       # ... and about as grey (channel spread / brightness below this, once white-balanced)
CHROMA_BLUR = 7           # half-resolution pixels over which a shadowed pixel's hue is judged
SHARP_EDGE = 0.1          # log-brightness step per half-resolution pixel: the page's own edge, not a soft shadow


def check_frame(frame: np.ndarray) -> np.ndarray:
    """Return the frame as HxWx3 uint8 BGR, or raise the one-line error every reader shares."""
    if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8:
        raise ValueError(f"frame must be a uint8 numpy image; got {type(frame).__name__} {getattr(frame, 'dtype', '')}")
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.ndim == 3 and frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    if frame.ndim != 3 or frame.shape[2] != 3 or min(frame.shape[:2]) < 32:
        raise ValueError(f"frame must be an HxWx3 BGR image at least 32 pixels a side; got shape {frame.shape}")
    return frame


def page_mask(frame: np.ndarray) -> np.ndarray:
    """uint8 mask of bright, unsaturated ('paper white') pixels: Otsu on value - 1.5 x saturation, raised if needed."""
    hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
    # saturation counts 1.5x: light skin and pastel objects are bright but clearly coloured; paper (even
    # tinted by warm light) much less so
    whiteness = cv2.addWeighted(hsv[:, :, 2], 1.0, hsv[:, :, 1], -1.5, 0.0)
    otsu, _ = cv2.threshold(whiteness, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    threshold = max(otsu, MIN_WHITENESS - 1)
    bright = whiteness > threshold
    if bright.any():  # pale objects (pastel clutter) fall between the table and the paper: cut them off too
        threshold = max(threshold, PAPER_RATIO * float(np.median(whiteness[bright])))
    return np.where(whiteness > threshold, 255, 0).astype(np.uint8)


def order_corners(points: np.ndarray) -> np.ndarray:
    """Four corners of a convex quad -> float32 (4, 2) ordered top-left, top-right, bottom-right, bottom-left.

    Top-left is the corner nearest the frame's origin (least x + y); the others follow clockwise as the
    camera sees them (by angle around the centre). Picking each corner by its own extreme (least y - x for
    top-right, ...) named one point twice when two corners tied, e.g. a sheet's top and right corners at
    the same y - x, and the page was lost."""
    pts = np.asarray(points, np.float32).reshape(4, 2)
    centre = pts.mean(axis=0)
    clockwise = pts[np.argsort(np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0]), kind="stable")]
    first = int(clockwise.sum(axis=1).argmin())
    return np.roll(clockwise, -first, axis=0)


def find_page(frame: np.ndarray) -> np.ndarray | None:
    """Corners (4, 2) float32 of the largest paper-coloured quadrilateral, or None if there is none."""
    return locate_page(frame)[0]


def locate_page(frame: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """(corners or None, paper mask of the frame): the mask also tells where a hand covers the page."""
    return locate_balanced_page(balance_frame(check_frame(frame)))


def locate_balanced_page(frame: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """locate_page on a frame already white-balanced by vision.illumination.balance_frame."""
    mask = page_mask(frame)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    # bridge thin dark lines (a grid line drawn to the page edge) that would cut the page in two, and cut
    # off thin bright things touching it (a white pen) that would pull the page's hull out of shape
    body = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((7, 7), np.uint8))
    body = cv2.morphologyEx(body, cv2.MORPH_OPEN, np.ones((11, 11), np.uint8))
    body = _grow_into_shadow(frame, body)
    without_clutter = _cut_pastel_clutter(frame, body)
    corners = _page_quad(without_clutter, frame.shape[0] * frame.shape[1])
    if corners is None and without_clutter is not body:
        corners = _page_quad(body, frame.shape[0] * frame.shape[1])
    if corners is None and cv2.countNonZero(body) > FILLED_FRACTION * body.size:
        # a scan or a close-up: the sheet fills the picture, so the picture is the page
        h, w = mask.shape
        corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float32)
    return corners, mask


def _grow_into_shadow(frame: np.ndarray, body: np.ndarray) -> np.ndarray:
    """The paper body extended over the parts of the same sheet that lie in a soft shadow.

    The whiteness test only keeps the lit part of a sheet half in shadow (shadowed paper can be darker
    than a lit table). Paper in shadow is still grey and not very dark, and a shadow's edge is soft while
    the sheet's own edge is sharp whatever the light (paper and table darken together): so the body grows
    through grey, not-too-dark pixels, but never across a sharp brightness step. Done at half resolution
    after a grey closing (thin ink and grid lines are neither steps nor holes), a few milliseconds.
    """
    if not body.any():
        return body
    h, w = body.shape
    small = cv2.resize(frame, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
    small = cv2.morphologyEx(small, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    seed = cv2.resize(body, (w // 2, h // 2), interpolation=cv2.INTER_NEAREST) > 0
    # channel mean (numpy's per-pixel channel reductions cost ~20 ms here; cv2.transform does not)
    level = cv2.transform(small.astype(np.float32), np.full((1, 3), 1 / 3, np.float32))
    paper = float(np.median(level[seed])) if seed.any() else 0.0
    if paper < 20:
        return body
    # hue is a broad property of paper or table, while sensor noise amplified by the white balance and
    # JPEG's colour blocks are per pixel: the channel spread is judged on a smoothed copy, against grey and
    # against the lit paper's own colour (a cast the white balance left in tints the shadowed paper too,
    # unless the lit paper clipped to white), whichever is closer
    smooth = cv2.blur(small, (CHROMA_BLUR, CHROMA_BLUR)).astype(np.float32)
    tint = np.median(small[seed], axis=0).astype(np.float32)
    brightness = np.maximum(cv2.blur(level, (CHROMA_BLUR, CHROMA_BLUR)), 1.0)
    chroma = np.minimum(_spread(smooth), _spread(smooth * (tint.mean() / np.maximum(tint, 1.0)))) / brightness
    log = cv2.GaussianBlur(np.log(level + 0.03 * paper), (0, 0), 1.0)
    step = np.hypot(cv2.Sobel(log, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(log, cv2.CV_32F, 0, 1, ksize=3)) / 8
    # the sheet's edge, one pixel thicker: with a smooth grey table beside the shadowed paper, a gap of one
    # pixel in the edge would let the growth leak out (and then give up)
    edge = cv2.dilate((step >= SHARP_EDGE).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    free = ((level > SHADOW_LEVEL * paper) & (chroma < SHADOW_CHROMA) & ~edge) | seed
    count, labels = cv2.connectedComponents(free.astype(np.uint8), connectivity=4)
    keep = np.zeros(count, bool)
    keep[np.unique(labels[seed])] = True
    keep[0] = False
    # shadowed paper is a broad piece along the shadow's edge; bits of a grey table that leak in through a
    # gap in the page's edge are speckled and joined by thin links: an opening cuts those off
    extra = (keep[labels] & ~seed).astype(np.uint8)
    extra = cv2.morphologyEx(extra, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9)))
    if not extra.any():
        return body
    count, labels = cv2.connectedComponents(extra, connectivity=4)
    touching = np.zeros(count, bool)
    touching[np.unique(labels[cv2.dilate(seed.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0])] = True
    # a piece running off the picture is table (the sheet is wholly in view, or its corners are not)
    edge = np.r_[labels[0], labels[-1], labels[:, 0], labels[:, -1]]
    touching[np.unique(edge)] = False
    touching[0] = False
    grown = touching[labels]
    if grown.sum() > 3 * seed.sum():  # mostly "shadowed paper" around a small lit piece: a grey table
        return body
    grown = cv2.dilate(grown.astype(np.uint8) * 255, np.ones((3, 3), np.uint8))  # back out to the edge
    return cv2.bitwise_or(body, cv2.resize(grown, (w, h), interpolation=cv2.INTER_NEAREST))


def _spread(bgr: np.ndarray) -> np.ndarray:
    """Per pixel: largest minus smallest channel."""
    b, g, r = cv2.split(bgr)
    return cv2.max(cv2.max(b, g), r) - cv2.min(cv2.min(b, g), r)


def _cut_pastel_clutter(frame: np.ndarray, body: np.ndarray) -> np.ndarray:
    """The page body without pale clutter of another hue touching it (vision.illumination).

    The global whiteness test merges a mint sticky note or a pastel cup touching the sheet into the page,
    which bends the page's corners (and the hand test then sees "not paper" along the warped page's rim).
    Judged against a smooth fit of the paper's own colour under this light, such clutter is off-hue while
    paper dimmed by a vignette or whitened by clipping is not. Judged at half resolution (it only has to
    cut clutter off; the page's straight edges still come from the full-resolution mask).
    """
    contours, _ = cv2.findContours(body, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return body
    x, y, w, h = cv2.boundingRect(max(contours, key=cv2.contourArea))
    pad = max(w, h) // 10
    x0, y0 = max(0, x - pad), max(0, y - pad)
    x1, y1 = min(frame.shape[1], x + w + pad), min(frame.shape[0], y + h + pad)
    if min(x1 - x0, y1 - y0) < 32:
        return body
    small = (max(8, (x1 - x0) // 2), max(8, (y1 - y0) // 2))
    crop = cv2.resize(frame[y0:y1, x0:x1], small, interpolation=cv2.INTER_AREA)
    crop_body = cv2.resize(body[y0:y1, x0:x1], small, interpolation=cv2.INTER_NEAREST)
    # only what the whiteness test took for page; opened, so neither noise, thin ink nor the slivers of
    # table that half resolution mixes into the page's edge count
    brightness, off_hue = shade_and_hue(crop, crop_body)
    clutter = (off_hue > PAGE_HUE_RATIO) & (brightness > PAGE_BRIGHT_RATIO) & (crop_body > 0)
    clutter = cv2.morphologyEx(clutter.astype(np.uint8), cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    if not clutter.any():
        return body
    clutter = cv2.resize(clutter, (x1 - x0, y1 - y0), interpolation=cv2.INTER_NEAREST)
    out = body.copy()
    out[y0:y1, x0:x1][clutter > 0] = 0
    return cv2.morphologyEx(out, cv2.MORPH_OPEN, np.ones((11, 11), np.uint8))


def _page_quad(mask: np.ndarray, frame_area: int) -> np.ndarray | None:
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return None
    page = max(contours, key=cv2.contourArea)
    if not MIN_PAGE_FRACTION * frame_area <= cv2.contourArea(page) <= MAX_PAGE_FRACTION * frame_area:
        return None
    hull = cv2.convexHull(page)
    perimeter = cv2.arcLength(hull, True)
    for eps in (0.01, 0.02, 0.03, 0.045, 0.06, 0.08):
        quad = cv2.approxPolyDP(hull, eps * perimeter, True)
        if len(quad) == 4:
            break
    else:
        return None
    corners = order_corners(quad)
    if len({tuple(c) for c in corners.tolist()}) < 4 or not cv2.isContourConvex(corners.astype(np.int32)):
        return None
    return corners


def warp(frame: np.ndarray, corners: np.ndarray, size: int) -> np.ndarray:
    """Projective warp of the quadrilateral `corners` (TL, TR, BR, BL) to a size x size square."""
    target = np.array([[0, 0], [size, 0], [size, size], [0, size]], np.float32)
    H = cv2.getPerspectiveTransform(np.asarray(corners, np.float32), target)
    return cv2.warpPerspective(frame, H, (size, size), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
