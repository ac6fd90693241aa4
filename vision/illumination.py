"""Judging "is this paper?" against the page's own paper colour, not against one global colour.

Light on a table is uneven and tinted: a gradient, a dark vignette, a colour cast, and bright spots where
the camera clips the tint away (the paper turns pure white there). One global threshold or one median
colour then calls a whole dim corner or a clipped strip "not paper", which the hand test reads as a hand
that never leaves. So the paper's colour is modelled as a smooth field over the page (a quadratic surface
per channel, fitted robustly: ink, hands and shadows are outliers), every pixel is divided by it (white
balance against the local paper), and only then judged: darker than the paper around it, or of another
hue. A channel the camera clipped is not judged: there the true colour is unknown.
"""
from __future__ import annotations

import cv2
import numpy as np

SAMPLE_STEP = 4          # fit on every 4th pixel of the (small) page warp: plenty for 6 coefficients
FIT_ROUNDS = 3           # robust re-fits, each dropping pixels far from the previous fit
INLIER_RATIO = 0.12      # a pixel within 12% of the fitted paper colour in every channel counts as paper
CLIPPED = 250            # a channel this bright may be clipped by the camera: it cannot tell paper from skin
FIELD_STEP = 8           # the fitted field is evaluated every 8 pixels and resized up
MIN_INLIERS = 0.2        # fewer paper-like samples than this fraction: keep the previous fit
DARK_RATIO = 0.78        # brightness below this fraction of the local paper: not paper (sleeve, shadow, dark skin)
HUE_RATIO = 0.085        # a channel off the pixel's own grey by more than this (after white balance): another hue (skin)


def _design(h: int, w: int, step: int) -> np.ndarray:
    """(N, 6) quadratic terms 1, x, y, x^2, xy, y^2 on a grid of pixel centres scaled to [-1, 1]."""
    y, x = np.mgrid[step // 2:h:step, step // 2:w:step].astype(np.float32)
    x = x.ravel() / (w / 2) - 1
    y = y.ravel() / (h / 2) - 1
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)


def paper_field(page_bgr: np.ndarray, seed_mask: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 smooth estimate of the bare paper's colour under this light, everywhere on the page.

    seed_mask (uint8, 255 = paper-white by the global test) picks the first fit's samples; later rounds
    keep every sample close to the current fit, so dim paper the global test missed joins in.
    """
    h, w = page_bgr.shape[:2]
    values = page_bgr[SAMPLE_STEP // 2::SAMPLE_STEP, SAMPLE_STEP // 2::SAMPLE_STEP].reshape(-1, 3).astype(np.float32)
    design = _design(h, w, SAMPLE_STEP)
    use = seed_mask[SAMPLE_STEP // 2::SAMPLE_STEP, SAMPLE_STEP // 2::SAMPLE_STEP].ravel() > 127
    if use.mean() < MIN_INLIERS:  # the global test found little paper: start from the brightest half
        use = values.sum(axis=1) >= np.median(values.sum(axis=1))
    for _ in range(FIT_ROUNDS):
        coef = _least_squares(design[use], values[use])
        fit = np.clip(design @ coef, 1.0, 255.0)
        inliers = (np.abs(values / fit - 1) < INLIER_RATIO).all(axis=1)
        if inliers.mean() < MIN_INLIERS:
            break
        use = inliers
    # a quadratic is smooth: evaluate it on a coarse grid and let a linear resize fill in
    coarse_w, coarse_h = max(2, w // FIELD_STEP), max(2, h // FIELD_STEP)
    y, x = np.mgrid[0:coarse_h, 0:coarse_w].astype(np.float32)
    x, y = (x + 0.5) * (w / coarse_w) / (w / 2) - 1, (y + 0.5) * (h / coarse_h) / (h / 2) - 1
    terms = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1)
    coarse = np.clip(terms @ coef, 1.0, 255.0).astype(np.float32)
    return cv2.resize(coarse, (w, h), interpolation=cv2.INTER_LINEAR)


def _least_squares(design: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(6, 3) coefficients by the normal equations: a 6x6 solve (numpy's lstsq spins up BLAS threads
    that cost milliseconds on a busy machine for this tiny problem)."""
    a = design.astype(np.float64)
    gram = np.einsum("ni,nj->ij", a, a) + 1e-6 * np.eye(a.shape[1])
    return np.linalg.solve(gram, np.einsum("ni,nc->ic", a, values.astype(np.float64))).astype(np.float32)


def shade_and_hue(page_bgr: np.ndarray, seed_mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, against the local paper colour (paper_field): (brightness ratio, hue offset = the largest
    channel deviation from the pixel's own grey after white balance). Paper is (1, 0)."""
    field = paper_field(page_bgr, seed_mask)
    page = page_bgr.astype(np.float32)
    # a channel the camera clipped says nothing about hue or shade: there it matches the paper by definition
    ratio = cv2.divide(page, np.where(page >= CLIPPED, np.maximum(field, page), field))
    b, g, r = ratio[:, :, 0], ratio[:, :, 1], ratio[:, :, 2]
    brightness = (b + g + r) * (1.0 / 3.0)
    spread = np.maximum(np.maximum(b, g), r) - brightness, brightness - np.minimum(np.minimum(b, g), r)
    return brightness, np.maximum(*spread) / np.maximum(brightness, 1e-3)


def non_paper(page_bgr: np.ndarray, seed_mask: np.ndarray, dark: float = DARK_RATIO, hue: float = HUE_RATIO) -> np.ndarray:
    """bool (H, W): pixels that are not bare paper once white-balanced against the local paper colour.

    Darker than `dark` x the paper around it (ink, sleeves, shadows, dark skin), or of another hue
    (skin, coloured sleeves): pale skin in bright light is nearly as bright as paper but never as grey.
    """
    brightness, off_hue = shade_and_hue(page_bgr, seed_mask)
    return (brightness < dark) | (off_hue > hue)


WHITE_TOP = 0.05         # the brightest 5% of a thumbnail are taken to be paper when white-balancing a frame
WHITE_TARGET = 225.0     # a dim frame is brightened until that paper reads this bright
PAPER_CONTRAST = 1.6     # the brightest pixels must be this much brighter than the darker 30% to count as paper
MAX_GAIN = 4.0           # ... but no channel is amplified more than this (a dark frame stays dark, not noise)


def balance_frame(frame: np.ndarray) -> np.ndarray:
    """The frame white-balanced and brightened so the brightest paper-like pixels read neutral and bright.

    A tungsten or fluorescent cast makes paper orange or green (saturated, so not "white"), and dim light
    pushes it towards the table's level; both break any fixed test of "bright and unsaturated". The page is
    the largest bright thing in view, so the brightest few percent of the picture (a thumbnail: cheap, less
    noise) are mostly paper: their per-channel median is the light's colour and level. Channels are only
    ever gained up (a clean, neutral frame comes back nearly unchanged).
    """
    thumb = cv2.resize(frame, (160, 120), interpolation=cv2.INTER_AREA).reshape(-1, 3).astype(np.float32)
    level = thumb.sum(axis=1)
    top = thumb[level >= np.quantile(level, 1 - WHITE_TOP)]
    reference = np.maximum(np.median(top, axis=0), 1.0)
    brightest = float(reference.max())
    # brighten only when something stands out as paper: a dim uniform table is not made into a white page
    target = WHITE_TARGET if 3 * brightest > PAPER_CONTRAST * float(np.quantile(level, 0.3)) else brightest
    gains = np.clip(max(brightest, target) / reference, 1.0, MAX_GAIN)
    if (gains < 1.02).all():
        return frame
    lut = np.clip(np.arange(256, dtype=np.float32)[:, None] * gains[None, :], 0, 255).astype(np.uint8)
    return cv2.LUT(frame, lut.reshape(256, 1, 3))


def flatten(gray: np.ndarray, stroke: int, level: float = 220.0) -> np.ndarray:
    """A gray page or grid warp divided by its own paper shade, so a shadow's edge or a dim corner is gone.

    The paper shade is a grey closing wider than any pen stroke or grid line (`stroke` pixels), smoothed:
    ink keeps its contrast to the paper right next to it, wherever the light falls.
    """
    k = max(3, stroke | 1)
    f = 4 if k >= 24 else 2  # the shade is smooth: estimate it small (a wide blur costs milliseconds)
    small = cv2.resize(gray, (max(1, gray.shape[1] // f), max(1, gray.shape[0] // f)), interpolation=cv2.INTER_AREA)
    shade = cv2.morphologyEx(small, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k // f | 1, k // f | 1)))
    shade = cv2.GaussianBlur(shade, (0, 0), max(1.0, k / (2 * f)))
    shade = cv2.resize(shade, (gray.shape[1], gray.shape[0]), interpolation=cv2.INTER_LINEAR).astype(np.float32)
    return np.clip(gray.astype(np.float32) * (level / np.maximum(shade, 8.0)), 0, 255).astype(np.uint8)
