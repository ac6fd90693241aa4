"""Hand-drawn noughts and crosses as pen strokes.

We have no photos of real handwriting, so marks are drawn from a small stroke model with human variation:
noughts are open or overlapping loops (ellipses, eggs, wobbly radius, spiral drift), crosses are two
curved strokes with tilt, uneven lengths and an off-centre crossing. Pen width, pressure (ink opacity)
and colour vary. A mark is a list of polylines in the order a person draws them, so `progress` can show
a mark half drawn (the robot simulator animates a human hand with it).

`style="pen"` is the training style and `style="hasty"` the same stroke model with wider ranges (a
hurried pen: flatter, lumpier, slanted, re-traced, more open or overlapping loops; bowed, re-traced
crosses), also for training. `style="marker"` (a felt-tip's rounded-polygon or teardrop loops with soft
edges, cursive ")(" or dabbed straight crosses) is the TUNING handwriting: a stroke model of its own, never
trained on, on which training choices are judged. `style="hershey"` (OpenCV's vector fonts) and
`style="sketch"` (spline loops and re-traced strokes) are the HELD-OUT handwriting: never trained or tuned
on, only evaluated.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

MARK_KINDS = ("nought", "cross")
TRAINING_STYLES = ("pen", "hasty")   # drawn for training (and "pen" for tuning photos of the reader)
TUNING_STYLES = ("marker",)          # judges training choices; never trained on
HELDOUT_STYLES = ("sketch", "hershey")  # figures only: never trained or tuned on
STYLES = ("pen", "sketch", "hershey", "hasty", "marker")
_SUBPIXEL_BITS = 4
_SUBPIXEL = 1 << _SUBPIXEL_BITS


@dataclass
class Stroke:
    """One pen-down polyline: points (N, 2) in pixels and the pen width (pixels) at each point."""

    points: np.ndarray
    widths: np.ndarray


def _lengths(points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(points, axis=0), axis=1)


def _pressure_widths(n: int, width: float, rng: np.random.Generator) -> np.ndarray:
    """Pen width along a stroke: thinner where the pen lands and lifts, a slow pressure wave between."""
    t = np.linspace(0.0, 1.0, n)
    ramp = np.clip(np.minimum(t, 1.0 - t) / 0.08, 0.55, 1.0)
    wave = 1.0 + 0.18 * np.sin(2 * np.pi * (rng.uniform(0.5, 2.0) * t + rng.uniform(0, 1)))
    return np.maximum(width * ramp * wave, 0.8)


def _pen_nought(size: float, width: float, rng: np.random.Generator) -> list[Stroke]:
    radius = 0.5 * size * rng.uniform(0.72, 1.0)
    aspect = rng.uniform(0.5, 1.15)
    tilt = rng.uniform(0, np.pi)
    start = rng.uniform(0, 2 * np.pi)
    sweep = 2 * np.pi * rng.choice([rng.uniform(0.80, 0.97), rng.uniform(0.97, 1.08), rng.uniform(1.08, 1.35)])
    direction = rng.choice([-1.0, 1.0])
    n = 64
    t = np.linspace(0.0, 1.0, n)
    angle = start + direction * sweep * t
    wobble = np.ones(n)
    for k in (1, 2, 3):
        wobble += rng.normal(0, 0.05 / k) * np.sin(k * angle + rng.uniform(0, 2 * np.pi))
    drift = 1.0 + rng.uniform(-0.14, 0.14) * t  # spiral: the loop does not close on itself
    x = radius * wobble * drift * np.cos(angle)
    y = radius * aspect * wobble * drift * np.sin(angle)
    rot = np.array([[np.cos(tilt), -np.sin(tilt)], [np.sin(tilt), np.cos(tilt)]])
    points = np.stack([x, y], axis=1) @ rot.T
    if rng.random() < 0.15:  # a small entry tick where the pen lands
        tick = points[0] + (points[0] - points[1]) * np.linspace(3, 0, 4)[:, None]
        points = np.concatenate([tick, points[1:]])
    return [Stroke(points, _pressure_widths(len(points), width, rng))]


def _bezier(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, n: int) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)[:, None]
    return (1 - t) ** 2 * p0 + 2 * (1 - t) * t * p1 + t**2 * p2


@dataclass(frozen=True)
class CrossHand:
    """How a hand draws a cross: two bowed arms about 90 degrees apart (ranges drawn per mark, per arm)."""

    tilt_deg: float        # the whole mark turned by up to this
    angle_sd: float        # each arm's angle off 45 / 135 degrees (normal sd, degrees)
    length: tuple[float, float]  # arm length, in mark sizes
    shift: float           # where along an arm the other one crosses it, +- this share of its length
    bow: float             # the arm's bow, +- this share of its length
    hook: float            # chance of a hook where the pen lifts ...
    hook_length: float     # ... reaching up to this share of the arm
    retrace: float = 0.0   # chance that an arm is gone over twice (a little off the first pass)


PEN_CROSS = CrossHand(tilt_deg=22, angle_sd=9, length=(0.72, 1.15), shift=0.18, bow=0.14, hook=0.15, hook_length=0.1)
# the pen cross drawn in a hurry: more tilt, bowed and uneven arms, an arm sometimes gone over twice
HASTY_CROSS = CrossHand(tilt_deg=30, angle_sd=14, length=(0.6, 1.2), shift=0.25, bow=0.25, hook=0.25,
                        hook_length=0.14, retrace=0.25)


def _cross(size: float, width: float, rng: np.random.Generator, hand: CrossHand) -> list[Stroke]:
    tilt = np.deg2rad(rng.uniform(-hand.tilt_deg, hand.tilt_deg))
    strokes = []
    for base in (45.0, 135.0):
        angle = np.deg2rad(base + rng.normal(0, hand.angle_sd)) + tilt
        length = size * rng.uniform(*hand.length)
        along = np.array([np.cos(angle), np.sin(angle)])
        normal = np.array([-along[1], along[0]])
        shift = rng.uniform(-hand.shift, hand.shift) * length  # where along this stroke the other one crosses it
        p0 = -along * (length / 2 + shift)
        p2 = along * (length / 2 - shift)
        for _ in range(2 if hand.retrace and rng.random() < hand.retrace else 1):
            p1 = (p0 + p2) / 2 + normal * rng.uniform(-hand.bow, hand.bow) * length
            points = _bezier(p0, p1, p2, 24)
            if rng.random() < 0.5:
                points = points[::-1]
            if rng.random() < hand.hook:  # a hook where the pen lifts
                hook_dir = normal * rng.choice([-1, 1]) - along * 0.5
                points = np.concatenate([points, points[-1] + hook_dir * np.linspace(0.03, hand.hook_length, 3)[:, None] * length])
            strokes.append(Stroke(points, _pressure_widths(len(points), width, rng)))
            if hand.retrace:  # a second pass starts a little off the first
                p0, p2 = p0 + rng.normal(0, 0.04 * size, 2), p2 + rng.normal(0, 0.04 * size, 2)
    if rng.random() < 0.5:
        strokes.reverse()
    return strokes


def _catmull_rom_loop(knots: np.ndarray, per_span: int) -> np.ndarray:
    k = len(knots)
    out = []
    for i in range(k):
        p0, p1, p2, p3 = knots[i - 1], knots[i], knots[(i + 1) % k], knots[(i + 2) % k]
        t = np.linspace(0, 1, per_span, endpoint=False)[:, None]
        out.append(0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                          + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3))
    return np.concatenate(out)


def _sketch_nought(size: float, width: float, rng: np.random.Generator) -> list[Stroke]:
    """A lumpy spline loop through a few jittered knots, sometimes traced twice."""
    k = int(rng.integers(5, 8))
    angles = np.sort(rng.uniform(0, 2 * np.pi, k)) if rng.random() < 0.3 else np.linspace(0, 2 * np.pi, k, endpoint=False)
    radii = 0.5 * size * rng.uniform(0.65, 1.0) * rng.uniform(0.8, 1.15, k)
    knots = np.stack([radii * np.cos(angles), radii * rng.uniform(0.7, 1.0) * np.sin(angles)], axis=1)
    loop = _catmull_rom_loop(knots, 10)
    loops = [loop]
    if rng.random() < 0.5:
        loops.append(loop * rng.uniform(0.9, 1.08) + rng.normal(0, 0.04 * size, 2))
    points = np.concatenate(loops + [loops[-1][:1]])
    return [Stroke(points, _pressure_widths(len(points), width, rng))]


def _sketch_cross(size: float, width: float, rng: np.random.Generator) -> list[Stroke]:
    """Each arm drawn as two or three quick overlapping passes."""
    strokes = []
    for base in (45.0, 135.0):
        angle = np.deg2rad(base + rng.normal(0, 12))
        along = np.array([np.cos(angle), np.sin(angle)])
        length = size * rng.uniform(0.7, 1.1)
        for _ in range(int(rng.integers(1, 4))):
            jitter = rng.normal(0, 0.04 * size, 2)
            p0, p2 = -along * length / 2 + jitter, along * length / 2 + rng.normal(0, 0.04 * size, 2)
            points = np.linspace(p0, p2, 12)
            strokes.append(Stroke(points, _pressure_widths(len(points), width * 0.8, rng)))
    return strokes


def _hasty_nought(size: float, width: float, rng: np.random.Generator) -> list[Stroke]:
    """The pen loop drawn in a hurry: wider aspect range, lumpier and egg-shaped, slanted, bigger gaps and
    overlaps, sometimes a second lap over the first."""
    radius = 0.5 * size * rng.uniform(0.6, 1.0)
    aspect = rng.uniform(0.35, 1.2)
    start = rng.uniform(0, 2 * np.pi)
    sweep = 2 * np.pi * rng.choice([rng.uniform(0.70, 0.95), rng.uniform(0.95, 1.1), rng.uniform(1.1, 1.6)])
    if rng.random() < 0.3:  # re-traced: a second lap
        sweep += 2 * np.pi * rng.uniform(0.6, 1.0)
    direction = rng.choice([-1.0, 1.0])
    n = int(64 * sweep / (2 * np.pi)) + 8
    t = np.linspace(0.0, 1.0, n)
    angle = start + direction * sweep * t
    wobble = 1.0 + rng.uniform(-0.2, 0.2) * np.cos(angle - rng.uniform(0, 2 * np.pi))  # egg
    for k in (1, 2, 3, 4):
        wobble += rng.normal(0, 0.09 / k) * np.sin(k * angle + rng.uniform(0, 2 * np.pi))
    drift = 1.0 + rng.uniform(-0.25, 0.25) * t
    x = radius * wobble * drift * np.cos(angle)
    y = radius * aspect * wobble * drift * np.sin(angle)
    x = x + rng.uniform(-0.4, 0.4) * y  # slant
    tilt = rng.uniform(0, np.pi)
    rot = np.array([[np.cos(tilt), -np.sin(tilt)], [np.sin(tilt), np.cos(tilt)]])
    points = np.stack([x, y], axis=1) @ rot.T
    return [Stroke(points, _pressure_widths(len(points), width, rng))]


def _marker_widths(n: int, width: float) -> np.ndarray:
    """A felt tip lays an even line, a little wider where it lands (a dab)."""
    widths = np.full(n, width)
    widths[: min(3, n)] *= 1.35
    return widths


def _marker_nought(size: float, width: float, rng: np.random.Generator) -> list[Stroke]:
    """A felt-tip's quick loop: a rounded polygon (superellipse, from diamond to box) or a teardrop."""
    half = 0.5 * size * rng.uniform(0.75, 1.0)
    across = half * rng.uniform(0.65, 1.0)
    lap = rng.uniform(0.92, 1.12)
    t = np.linspace(0.0, 2 * np.pi * lap, 80)
    if rng.random() < 0.6:
        power = 2.0 / rng.uniform(1.3, 3.5)
        phase = rng.uniform(0, 2 * np.pi)
        c, s = np.cos(t + phase), np.sin(t + phase)
        x, y = half * np.sign(c) * np.abs(c) ** power, across * np.sign(s) * np.abs(s) ** power
    else:  # teardrop, its point where the pen lands
        x = across * np.sin(t) * np.abs(np.sin(t / 2)) ** rng.uniform(0.8, 1.6)
        y = -half * np.cos(t)
    if rng.random() < 0.5:
        x = -x
    turn = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    points = np.stack([x, y], axis=1) @ rot.T
    return [Stroke(points, _marker_widths(len(points), width))]


def _marker_cross(size: float, width: float, rng: np.random.Generator) -> list[Stroke]:
    """A cursive x (two arcs back to back, ")(") or two straight dabbed strokes."""
    tilt = np.deg2rad(rng.uniform(-12, 12))
    rot = np.array([[np.cos(tilt), -np.sin(tilt)], [np.sin(tilt), np.cos(tilt)]])
    strokes = []
    if rng.random() < 0.5:
        radius = 0.5 * size * rng.uniform(0.95, 1.2)
        reach = np.deg2rad(rng.uniform(50, 62))
        gap = rng.uniform(-0.04, 0.05) * size
        for sign in (-1.0, 1.0):  # ")" on the left, "(" on the right, apexes touching near the centre
            a = np.linspace(-reach, reach, 20)
            centre = -sign * (radius - gap / 2)
            points = np.stack([centre + sign * radius * np.cos(a), radius * np.sin(a)], axis=1)
            strokes.append(Stroke(points @ rot.T, _marker_widths(len(points), width)))
    else:
        for base in (45.0, 135.0):
            angle = np.deg2rad(base + rng.normal(0, 6))
            along = np.array([np.cos(angle), np.sin(angle)])
            length = size * rng.uniform(0.8, 1.1)
            points = np.linspace(-along * length / 2, along * length / 2, 16)
            strokes.append(Stroke(points @ rot.T, _marker_widths(len(points), width)))
    return strokes


_HERSHEY_FONTS = (cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_COMPLEX,
                  cv2.FONT_HERSHEY_TRIPLEX, cv2.FONT_HERSHEY_SCRIPT_SIMPLEX, cv2.FONT_HERSHEY_SCRIPT_COMPLEX,
                  cv2.FONT_HERSHEY_PLAIN)


def _draw_hershey(img: np.ndarray, kind: str, center: tuple[float, float], size: float,
                  rng: np.random.Generator, ink: tuple[int, int, int]) -> None:
    """OpenCV's vector-font glyphs "X"/"O" (upper or lower case), scaled to the mark size."""
    font = int(rng.choice(_HERSHEY_FONTS)) | (cv2.FONT_ITALIC if rng.random() < 0.3 else 0)
    text = ("X" if kind == "cross" else "O") if rng.random() < 0.7 else ("x" if kind == "cross" else "o")
    thickness = max(1, int(round(size * rng.uniform(0.05, 0.11))))
    (w, h), _ = cv2.getTextSize(text, font, 1.0, thickness)
    scale = size * rng.uniform(0.75, 1.0) / max(w, h)
    thickness = max(1, int(round(thickness * min(scale, 1.5))))
    (w, h), base = cv2.getTextSize(text, font, scale, thickness)
    org = (int(round(center[0] - w / 2)), int(round(center[1] + h / 2)))
    colour = ink if img.ndim == 3 else int(round(_gray(ink)))
    cv2.putText(img, text, org, font, scale, colour, thickness, cv2.LINE_AA)


def _gray(ink: tuple[int, int, int]) -> float:
    b, g, r = ink
    return 0.114 * b + 0.587 * g + 0.299 * r


def mark_strokes(kind: str, size: float, rng: np.random.Generator, width: float | None = None,
                 style: str = "pen") -> list[Stroke]:
    """Strokes of one mark centred on (0, 0), in drawing order (not for style "hershey")."""
    if kind not in MARK_KINDS:
        raise ValueError(f"mark kind {kind!r} is unknown; expected one of {MARK_KINDS}")
    if width is None and style == "marker":  # a felt tip: always broad
        width = max(1.0, size * rng.uniform(0.09, 0.18))
    elif width is None and style == "hasty":  # from a fine liner to a felt tip
        width = max(1.0, size * rng.uniform(0.025, 0.16))
    elif width is None:  # mostly ballpoint; sometimes a felt-tip, which makes a small mark nearly a blob
        width = max(1.0, size * (rng.uniform(0.035, 0.10) if rng.random() < 0.85 else rng.uniform(0.10, 0.16)))
    if style == "pen":
        return _pen_nought(size, width, rng) if kind == "nought" else _cross(size, width, rng, PEN_CROSS)
    if style == "sketch":
        return _sketch_nought(size, width, rng) if kind == "nought" else _sketch_cross(size, width, rng)
    if style == "hasty":
        return _hasty_nought(size, width, rng) if kind == "nought" else _cross(size, width, rng, HASTY_CROSS)
    if style == "marker":
        return _marker_nought(size, width, rng) if kind == "nought" else _marker_cross(size, width, rng)
    raise ValueError(f"stroke style {style!r} has no polylines; expected one of {tuple(s for s in STYLES if s != 'hershey')}")


def _render(img: np.ndarray, strokes: list[Stroke], offset: np.ndarray, progress: float,
            ink: tuple[int, int, int], opacity: float, soften: float = 0.0) -> None:
    """Draw the first `progress` of the strokes' total length, blending ink by coverage x opacity
    (coverage blurred by `soften` px: a felt tip's ink bleeds into the paper)."""
    all_points = np.concatenate([s.points for s in strokes]) + offset
    pad = float(max(s.widths.max() for s in strokes)) + 2 + 3 * soften
    x0 = int(max(np.floor(all_points[:, 0].min() - pad), 0))
    y0 = int(max(np.floor(all_points[:, 1].min() - pad), 0))
    x1 = int(min(np.ceil(all_points[:, 0].max() + pad), img.shape[1]))
    y1 = int(min(np.ceil(all_points[:, 1].max() + pad), img.shape[0]))
    if x1 <= x0 or y1 <= y0:
        return
    coverage = np.zeros((y1 - y0, x1 - x0), np.uint8)
    budget = progress * sum(float(_lengths(s.points).sum()) for s in strokes)
    origin = np.array([x0, y0], float)
    for stroke in strokes:
        points = stroke.points + offset - origin
        seg = _lengths(points)
        for i, length in enumerate(seg):
            if budget <= 0:
                break
            a, b = points[i], points[i + 1]
            if length > budget:
                b = a + (b - a) * (budget / length)
            budget -= length
            thickness = max(1, int(round((stroke.widths[i] + stroke.widths[i + 1]) / 2)))
            pa = tuple(int(v) for v in np.round(a * _SUBPIXEL))
            pb = tuple(int(v) for v in np.round(b * _SUBPIXEL))
            cv2.line(coverage, pa, pb, 255, thickness, cv2.LINE_AA, _SUBPIXEL_BITS)
    alpha = coverage.astype(np.float32) * (opacity / 255.0)
    if soften > 0:
        alpha = cv2.GaussianBlur(alpha, (0, 0), soften)
    region = img[y0:y1, x0:x1].astype(np.float32)
    if img.ndim == 3:
        alpha = alpha[:, :, None]
        colour = np.array(ink, np.float32)[: img.shape[2]]
    else:
        colour = np.float32(_gray(ink))
    img[y0:y1, x0:x1] = np.clip(region * (1 - alpha) + colour * alpha, 0, 255).astype(np.uint8)


def draw_mark(img: np.ndarray, kind: str, center: tuple[float, float], size: float,
              rng: np.random.Generator, progress: float = 1.0, ink: tuple[int, int, int] = (40, 30, 20),
              width: float | None = None, style: str = "pen", opacity: float | None = None) -> None:
    """Draw a hand-drawn nought or cross into `img` (uint8, HxW gray or HxWx3 BGR) in place.

    center/size are in pixels (size ~ the mark's diameter); `rng` decides the person's hand, so the same
    seed draws the same mark and growing `progress` (0..1) from the same seed animates one drawing.
    `ink` is BGR (turned to gray on a gray image); `width` is the pen width in pixels (random if None).
    """
    if img.dtype != np.uint8 or img.ndim not in (2, 3):
        raise ValueError(f"draw_mark needs a uint8 HxW or HxWx3 image; got {img.dtype} with shape {img.shape}")
    if not 0.0 <= progress <= 1.0:
        raise ValueError(f"progress must be in [0, 1]; got {progress}")
    if size <= 0:
        raise ValueError(f"mark size must be positive pixels; got {size}")
    if style not in STYLES:
        raise ValueError(f"stroke style {style!r} is unknown; expected one of {STYLES}")
    if kind not in MARK_KINDS:
        raise ValueError(f"mark kind {kind!r} is unknown; expected one of {MARK_KINDS}")
    if style == "hershey":
        if progress > 0:
            _draw_hershey(img, kind, center, size, rng, ink)
        return
    strokes = mark_strokes(kind, size, rng, width=width, style=style)
    if opacity is None:
        opacity = rng.uniform(0.75, 1.0)
    soften = 0.25 * float(strokes[0].widths.mean()) if style == "marker" else 0.0
    if progress > 0:
        _render(img, strokes, np.asarray(center, float), progress, ink, opacity, soften)
