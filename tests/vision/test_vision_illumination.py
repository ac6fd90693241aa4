"""Judging paper against its own local colour: tinted light, vignettes and clipped strips are paper, skin is not."""
import cv2
import numpy as np
import pytest

from ncbot.vision.illumination import non_paper, paper_field

SIDE = 160


def _lit_page(tint=(1.0, 0.93, 1.08), clip_gain=1.25, seed=0) -> np.ndarray:
    """A bare page under a tinted light with a strong gradient (clipped white on the left) and a dark vignette."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:SIDE, 0:SIDE].astype(np.float32) / SIDE - 0.5
    gain = clip_gain - 0.5 * (xx + 0.5)                       # bright (clipping) left, dim right
    vignette = 1 - 0.5 * (xx ** 2 + yy ** 2) * 2              # dark corners
    paper = np.array([236, 242, 245], np.float32)
    light = (gain * vignette)[:, :, None] * np.array(tint, np.float32)[None, None, :]
    page = paper * light + rng.normal(0, 4, (SIDE, SIDE, 3))
    return np.clip(page, 0, 255).astype(np.uint8)


def test_a_tinted_vignetted_clipped_page_is_all_paper() -> None:
    page = _lit_page()
    seed_mask = np.full((SIDE, SIDE), 255, np.uint8)
    seed_mask[:, int(0.6 * SIDE):] = 0  # the global test missed the dim side: the fit must still cover it
    wrong = non_paper(page, seed_mask)
    assert wrong.mean() < 0.02, wrong.mean()  # single noisy pixels in the dimmest corner at most
    blobs = cv2.morphologyEx(wrong.astype(np.uint8), cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    assert blobs.sum() == 0


def test_skin_and_a_dark_sleeve_are_not_paper_under_the_same_light() -> None:
    page = _lit_page(clip_gain=1.1).astype(np.float32)  # (skin clipped to white would be white: nobody can tell)
    light = page / np.array([236, 242, 245], np.float32)
    page[40:90, 40:90] = np.array([170, 190, 230], np.float32) * light[40:90, 40:90]   # pale skin
    page[100:150, 20:60] = np.array([60, 60, 70], np.float32) * light[100:150, 20:60]  # dark sleeve
    page = np.clip(page, 0, 255).astype(np.uint8)
    seed_mask = np.full((SIDE, SIDE), 255, np.uint8)
    wrong = non_paper(page, seed_mask)
    assert wrong[45:85, 45:85].mean() > 0.95 and wrong[105:145, 25:55].mean() > 0.95
    outside = np.ones_like(wrong)
    outside[35:95, 35:95] = False
    outside[95:155, 15:65] = False
    assert wrong[outside].mean() < 0.02


def test_paper_field_follows_the_light_and_ignores_ink() -> None:
    page = _lit_page(clip_gain=1.0)
    inked = page.copy()
    inked[::16, :] = 30  # grid-like ink lines
    field = paper_field(inked, np.full((SIDE, SIDE), 255, np.uint8))
    error = np.abs(field - page.astype(np.float32)).mean(axis=2)
    assert np.median(error) < 5 and np.percentile(error, 95) < 12


@pytest.mark.parametrize("dark, hue", [(0.78, 0.085), (0.0, 0.1)])
def test_thresholds_are_parameters(dark, hue) -> None:
    page = _lit_page()
    out = non_paper(page, np.full((SIDE, SIDE), 255, np.uint8), dark=dark, hue=hue)
    assert out.shape == (SIDE, SIDE) and out.dtype == bool
