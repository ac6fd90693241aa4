"""Named photo conditions for generated frames: "clean" (the lab-like default) and "harsh" (a new user's photo).

"harsh" is what a person's phone or a cheap camera gives in an ordinary room, each drawn from a range per
scene: a soft shadow across the sheet (a person or a lamp arm between the light and the table), a tungsten
or fluorescent colour cast the camera did not white-balance away, dim light (so more sensor noise), a cheap
wide-angle lens (barrel distortion: straight grid lines bow), a little motion blur and strong JPEG
compression. The ranges live here, in one place, so tests, figures and `ncbot vision eval` agree on them.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

CONDITIONS = ("clean", "harsh")


@dataclass(frozen=True)
class HarshRanges:
    """Ranges the "harsh" condition set draws from (uniform unless said otherwise)."""

    shadow_chance: float = 0.75
    shadow_depth: tuple[float, float] = (0.25, 0.55)       # fraction of the light the shadow takes away
    shadow_softness: tuple[float, float] = (10.0, 35.0)  # px, Gaussian sigma of the penumbra (a soft shadow)
    casts: tuple[str, ...] = ("tungsten", "fluorescent", "tungsten", "daylight")
    exposure: tuple[float, float] = (0.4, 1.0)           # overall light level (dim room .. bright room)
    noise_sigma: tuple[float, float] = (2.0, 6.0)        # gray levels at full exposure; grows as light dims
    lens_k: tuple[float, float] = (0.05, 0.25)           # barrel k1 (radius in focal lengths)
    motion_px: tuple[float, float] = (1.0, 7.0)          # length of the motion-blur streak
    jpeg_quality: tuple[int, int] = (30, 75)


HARSH = HarshRanges()
# channel gains (B, G, R) the camera left in: warm incandescent light, green-ish tube light, a slightly blue day
CAST_GAINS = {"tungsten": ((0.5, 0.72), (0.78, 0.9), (1.0, 1.0)),
              "fluorescent": ((0.85, 0.97), (1.0, 1.0), (0.72, 0.88)),
              "daylight": ((1.0, 1.0), (0.92, 1.0), (0.8, 0.92))}


def check_conditions(name: str) -> str:
    """Return `name` if it is a known condition set, else raise one clear ValueError."""
    if name not in CONDITIONS:
        raise ValueError(f"conditions must be one of {', '.join(CONDITIONS)}; got {name!r}")
    return name


@dataclass
class Harsh:
    """One draw of the harsh conditions for a scene (fixed per scene, like the camera)."""

    light: np.ndarray          # (H, W, 3) float gain: shadow x colour cast x exposure
    lens_k: float
    motion: np.ndarray         # normalised motion-blur kernel
    noise_sigma: float
    jpeg_quality: int
    cast: str


def draw_harsh(rng: np.random.Generator, width: int, height: int, page_corners: np.ndarray,
               ranges: HarshRanges = HARSH) -> Harsh:
    """Draw one set of harsh conditions; the shadow's edge crosses the page (corners in frame pixels)."""
    light = np.ones((height, width), np.float32)
    if rng.random() < ranges.shadow_chance:
        # a half-plane or a band (an arm, a lamp post) whose soft edge passes through the page
        inside = page_corners.mean(axis=0) + rng.uniform(-0.3, 0.3, 2) * np.ptp(page_corners, axis=0)
        angle = rng.uniform(0, 2 * np.pi)
        normal = np.array([np.cos(angle), np.sin(angle)])
        yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
        distance = (xx - inside[0]) * normal[0] + (yy - inside[1]) * normal[1]
        shade = (distance > 0).astype(np.float32)
        if rng.random() < 0.4:
            shade *= distance < rng.uniform(0.25, 0.6) * np.ptp(page_corners, axis=0).max()
        shade = cv2.GaussianBlur(shade, (0, 0), float(rng.uniform(*ranges.shadow_softness)))
        light = 1.0 - float(rng.uniform(*ranges.shadow_depth)) * shade
    cast = str(rng.choice(ranges.casts))
    gains = np.array([rng.uniform(*g) for g in CAST_GAINS[cast]], np.float32)
    exposure = float(rng.uniform(*ranges.exposure))
    length = float(rng.uniform(*ranges.motion_px))
    kernel = motion_kernel(length, float(rng.uniform(0, np.pi)))
    return Harsh(light[:, :, None] * (gains * exposure)[None, None, :], float(rng.uniform(*ranges.lens_k)), kernel,
                 float(rng.uniform(*ranges.noise_sigma)) / np.sqrt(exposure),
                 int(rng.integers(ranges.jpeg_quality[0], ranges.jpeg_quality[1] + 1)), cast)


def motion_kernel(length: float, direction: float) -> np.ndarray:
    """Normalised kernel of a straight motion-blur streak `length` px long at angle `direction` (radians)."""
    size = int(np.ceil(length)) | 1
    kernel = np.zeros((size, size), np.float32)
    half = (length - 1) / 2
    c = size // 2
    cv2.line(kernel, (int(round(c - half * np.cos(direction))), int(round(c - half * np.sin(direction)))),
             (int(round(c + half * np.cos(direction))), int(round(c + half * np.sin(direction)))), 1.0, 1, cv2.LINE_AA)
    return kernel / kernel.sum()


def _focal(width: int) -> float:
    return 0.5 * width / np.tan(np.deg2rad(57.2) / 2)


def lens_maps(k: float, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """cv2.remap maps for barrel distortion k (the frame's corners stay where they were: a slight zoom)."""
    f = _focal(width)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    dx, dy = (xx - width / 2) / f, (yy - height / 2) / f
    corner = ((width / 2) ** 2 + (height / 2) ** 2) / f ** 2
    scale = (1 + k * (dx * dx + dy * dy)) / (1 + k * corner)
    return (width / 2 + dx * scale * f).astype(np.float32), (height / 2 + dy * scale * f).astype(np.float32)


def distort_points(points: np.ndarray, k: float, width: int, height: int) -> np.ndarray:
    """Where undistorted frame points appear through the lens of `lens_maps` (fixed-point inversion)."""
    f = _focal(width)
    centre = np.array([width / 2, height / 2])
    src = (np.asarray(points, np.float64) - centre) / f
    corner = ((width / 2) ** 2 + (height / 2) ** 2) / f ** 2
    out = src.copy()
    for _ in range(30):
        out = src * (1 + k * corner) / (1 + k * (out ** 2).sum(axis=-1, keepdims=True))
    return (out * f + centre).astype(np.float32)
