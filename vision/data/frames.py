"""Seeded camera frames of a game sheet on a table, with the true board.

A scene is a white page with a dark-ink grid (3x3, 9x9 or a declared game's rows x cols, laid out by
`ncbot.vision.sheet`) and hand-drawn marks, lying on a textured table
among clutter, seen by a pinhole camera (Pepper's mouth camera: ~57 deg horizontal field of view) tilted
up to 30 deg from the sheet normal and rotated +-15 deg, under uneven, tinted light with sensor noise and
JPEG artefacts. A hand and arm holding a pen can reach over the sheet from the far side (the player sits
opposite the robot). A `Scene` is fixed once drawn at random; `render` then draws any board in it, a
half-drawn mark and a hand, which is how the recogniser's frame sequences are made.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ncbot.vision.data.cells import random_ink
from ncbot.vision.data.conditions import Harsh, check_conditions, distort_points, draw_harsh, lens_maps
from ncbot.vision.sheet import Grid, built_in_like, draw_sheet, grid_box, grid_layout, grid_shape
from ncbot.vision.strokes import draw_mark

SYMBOL_KIND = {"x": "cross", "o": "nought"}
TABLE_BGR = ((60, 90, 130), (40, 60, 90), (90, 110, 120), (70, 70, 70), (110, 80, 50), (50, 90, 50),
             (120, 120, 125), (30, 30, 35), (80, 120, 160))
SKIN_BGR = ((150, 180, 225), (120, 150, 200), (90, 120, 170), (60, 85, 130), (45, 60, 95), (170, 190, 230))
#: How a grid is photographed, by the built-in size it is like (`built_in_like`): the page aspects drawn from,
#: the sheet's share of the page's shorter side, the least page height as a fraction of the frame's. A 9x9
#: grid is only readable when it fills the view: the robot leans in (bigger page, less margin).
VIEW = {3: ((1.0, 1.0, 1.414, 1 / 1.414, 1.2), (0.7, 0.95), 0.5),
        9: ((1.0, 1.1, 1 / 1.1), (0.9, 1.0), 0.72)}


@dataclass
class Mark:
    """One mark on the page: where, how big, which pen and which hand (a seed) draw it."""

    kind: str
    center: tuple[float, float]
    size: float
    ink: tuple[int, int, int]
    seed: int
    style: str


@dataclass
class Scene:
    """Everything fixed about one photo set-up; `render` adds the board, a hand and sensor noise."""

    grid: Grid
    page: np.ndarray                 # BGR page with the grid, no marks
    grid_rect: tuple[float, float, float, float, float]  # (left, top, width, height, cell step) on the page
    homography: np.ndarray           # page pixels -> frame pixels
    background: np.ndarray           # BGR frame without the page
    light: np.ndarray                # (H, W, 3) float gain: gradient, vignette, tint
    noise_sigma: float
    jpeg_quality: int | None
    blur_sigma: float
    inks: tuple[tuple[int, int, int], tuple[int, int, int]]
    styles: tuple[str, ...]
    mark_seed: int
    marks: dict[int, Mark] = field(default_factory=dict)
    harsh: Harsh | None = None       # the "harsh" condition set's shadow, cast, lens, blur (None: clean)

    @property
    def size(self) -> tuple[int, int]:
        return self.background.shape[1], self.background.shape[0]

    def page_corners(self) -> np.ndarray:
        """Page corners in the frame (TL, TR, BR, BL of the page), float32 (4, 2)."""
        h, w = self.page.shape[:2]
        pts = np.array([[0, 0], [w, 0], [w, h], [0, h]], np.float32)[None]
        return self._through_lens(cv2.perspectiveTransform(pts, self.homography)[0])

    def grid_crossings(self) -> np.ndarray:
        """The grid-line crossings as they lie in the frame (lens included), float32 (rows+1, cols+1, 2): the
        truth the reader's lattice estimates."""
        rows, cols = grid_shape(self.grid)
        left, top, across, down, _ = self.grid_rect
        gx, gy = np.linspace(0, across, cols + 1), np.linspace(0, down, rows + 1)
        pts = np.stack(np.meshgrid(left + gx, top + gy), -1).reshape(1, -1, 2).astype(np.float32)
        return self._through_lens(cv2.perspectiveTransform(pts, self.homography)[0]).reshape(rows + 1, cols + 1, 2)

    def _through_lens(self, points: np.ndarray) -> np.ndarray:
        if self.harsh is None:
            return points
        return distort_points(points, self.harsh.lens_k, *self.size)

    def cell_on_page(self, cell: int) -> tuple[float, float]:
        """Page pixel of a row-major cell's centre (the sheet's layout, moved to where the sheet lies)."""
        rows, cols = grid_shape(self.grid)
        if not 0 <= cell < rows * cols:
            raise ValueError(f"cell must be in [0, {rows * cols}); got {cell}")
        left, top, _, _, step = self.grid_rect
        row, col = divmod(cell, cols)
        return left + (col + 0.5) * step, top + (row + 0.5) * step

    def cell_in_frame(self, cell: int) -> tuple[float, float]:
        """Frame pixel of a cell's centre (where a hand drawing there puts the pen)."""
        p = np.array([[self.cell_on_page(cell)]], np.float32)
        return tuple(float(v) for v in self._through_lens(cv2.perspectiveTransform(p, self.homography)[0])[0])

    def mark(self, cell: int, symbol: str) -> Mark:
        """The mark a person draws in `cell` in this scene (fixed per cell and symbol)."""
        key = cell * 2 + (symbol == "x")
        if key not in self.marks:
            rng = np.random.default_rng([self.mark_seed, key])
            x, y = self.cell_on_page(cell)
            step = self.grid_rect[4]
            jitter = rng.uniform(-0.1, 0.1, 2) * step
            center = (x + jitter[0], y + jitter[1])
            self.marks[key] = Mark(SYMBOL_KIND[symbol], center, step * (rng.uniform(0.45, 0.78) if rng.random() < 0.85 else rng.uniform(0.32, 0.45)),
                                   self.inks[symbol == "x"], int(rng.integers(2**31)),
                                   self.styles[int(rng.integers(len(self.styles)))])
        return self.marks[key]


def _table(rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    base = np.array(TABLE_BGR[int(rng.integers(len(TABLE_BGR)))], np.float32) + rng.normal(0, 15, 3)
    low = cv2.resize(rng.normal(0, 1, (6, 8)).astype(np.float32), (width, height), interpolation=cv2.INTER_CUBIC)
    grain = np.sin(np.linspace(0, rng.uniform(20, 80), height, dtype=np.float32) + rng.uniform(0, 6))[:, None]
    grain = grain * rng.uniform(0, 8) + rng.normal(0, 3, (height, width)).astype(np.float32)
    table = base[None, None, :] + (low * rng.uniform(5, 20) + grain)[:, :, None]
    return np.clip(table, 0, 255).astype(np.uint8)


def _clutter(img: np.ndarray, rng: np.random.Generator) -> None:
    """Objects on the table: boxes, cups, pens, sticky notes (never as big and white as the page)."""
    h, w = img.shape[:2]
    for _ in range(int(rng.integers(2, 9))):
        colour = tuple(int(v) for v in rng.integers(0, 230, 3))
        centre = (int(rng.uniform(0, w)), int(rng.uniform(0, h)))
        kind = rng.integers(4)
        if kind == 0:
            box = cv2.boxPoints((centre, (float(rng.uniform(20, 160)), float(rng.uniform(20, 120))), float(rng.uniform(0, 180))))
            cv2.fillPoly(img, [box.astype(np.int32)], colour, cv2.LINE_AA)
        elif kind == 1:
            cv2.circle(img, centre, int(rng.uniform(10, 50)), colour, -1, cv2.LINE_AA)
        elif kind == 2:
            end = (centre[0] + int(rng.uniform(-120, 120)), centre[1] + int(rng.uniform(-120, 120)))
            cv2.line(img, centre, end, colour, int(rng.integers(3, 10)), cv2.LINE_AA)
        else:  # a small sticky note, bright but coloured
            note = tuple(int(v) for v in (rng.uniform(60, 140), rng.uniform(200, 250), rng.uniform(200, 255)))
            size = float(rng.uniform(25, 55))
            box = cv2.boxPoints((centre, (size, size), float(rng.uniform(0, 90))))
            cv2.fillPoly(img, [box.astype(np.int32)], note, cv2.LINE_AA)


def _hand_drawn_grid(sheet: np.ndarray, rng: np.random.Generator, ink: tuple[int, int, int], width: float) -> None:
    """A # drawn by a person: four slightly slanted, bowed lines that overshoot or stop short."""
    left, top, side = grid_box(3, sheet.shape[1], sheet.shape[0])
    step = side / 3
    for k in (1, 2):
        for vertical in (False, True):
            a = np.array([left + rng.uniform(-0.06, 0.06) * side, top + k * step + rng.uniform(-0.04, 0.04) * side])
            b = np.array([left + side + rng.uniform(-0.06, 0.06) * side, top + k * step + rng.uniform(-0.04, 0.04) * side])
            bow = rng.uniform(-0.02, 0.02) * side
            t = np.linspace(0, 1, 20)[:, None]
            pts = a + (b - a) * t + np.array([0.0, 1.0]) * bow * np.sin(np.pi * t)
            if vertical:
                pts = pts[:, ::-1]
            cv2.polylines(sheet, [np.round(pts * 16).astype(np.int32)], False, ink, max(1, int(round(width))),
                          cv2.LINE_AA, 4)


def _camera_homography(rng: np.random.Generator, page_w: int, page_h: int, width: int, height: int,
                       min_span: float = 0.5) -> np.ndarray:
    """Page pixels -> frame pixels for a pinhole camera tilted <= 30 deg and rolled <= 15 deg."""
    focal = 0.5 * width / np.tan(np.deg2rad(57.2) / 2)
    K = np.array([[focal, 0, width / 2], [0, focal, height / 2], [0, 0, 1]])
    for _ in range(1000):
        tilt = np.deg2rad(rng.uniform(0, 30))
        roll = np.deg2rad(rng.uniform(-15, 15))
        yaw = np.deg2rad(rng.uniform(-10, 10))
        ct, st, cr, sr, cy, sy = np.cos(tilt), np.sin(tilt), np.cos(roll), np.sin(roll), np.cos(yaw), np.sin(yaw)
        Rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
        Rx = np.array([[1, 0, 0], [0, ct, -st], [0, st, ct]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        R = Ry @ Rx @ Rz
        metres = rng.uniform(0.2, 0.3) / max(page_w, page_h)  # page side in metres per page pixel
        span = rng.uniform(min_span, 0.9) * height  # how tall the page looks: sets the camera distance
        distance = focal * max(page_w, page_h) * metres / span * rng.uniform(0.85, 1.0)
        offset = rng.uniform(-0.1, 0.1, 2) * distance
        corners = np.array([[0, 0], [page_w, 0], [page_w, page_h], [0, page_h]], float)
        local = np.c_[(corners - [page_w / 2, page_h / 2]) * metres, np.zeros(4)]
        cam = local @ R.T + np.array([offset[0], offset[1], distance])
        proj = cam @ K.T
        image_pts = proj[:, :2] / proj[:, 2:3]
        margin = 0.04 * width
        inside = (image_pts[:, 0].min() > margin and image_pts[:, 0].max() < width - margin
                  and image_pts[:, 1].min() > margin and image_pts[:, 1].max() < height - margin)
        if inside and np.ptp(image_pts[:, 1]) > 0.9 * min_span * height:
            return cv2.getPerspectiveTransform(corners.astype(np.float32), image_pts.astype(np.float32))
    raise RuntimeError("could not place the page inside the frame")  # pragma: no cover - 1000 tries suffice


def random_scene(grid: Grid, rng: np.random.Generator, width: int = 640, height: int = 480,
                 styles: tuple[str, ...] = ("pen",), conditions: str = "clean") -> Scene:
    """Draw a random set-up: page shape and grid, pose, table, clutter, lighting, pens; "harsh" conditions
    add a shadow, a colour cast, dim light, lens distortion, motion blur and JPEG (vision.data.conditions).
    Only a 3x3 grid is ever hand-drawn: a declared grid is printed, as the robot's sheets are."""
    aspects, share, min_span = VIEW[built_in_like(grid)]  # a one-line ValueError for a grid it cannot draw
    check_conditions(conditions)
    aspect = float(rng.choice(aspects))
    page_w = 560 if aspect <= 1 else int(560 / aspect)
    page_h = int(page_w * aspect)
    paper = tuple(int(v) for v in np.clip(np.array([240, 244, 246]) + rng.normal(0, 6, 3), 200, 255))
    page = np.empty((page_h, page_w, 3), np.uint8)
    page[:] = paper
    sub = int(min(page_w, page_h) * rng.uniform(*share))
    grid_ink = tuple(int(v) for v in rng.integers(10, 70, 3))
    line_width = max(1.0, sub / rng.uniform(110, 220))
    if grid == 3 and rng.random() < 0.35:
        sheet = np.empty((sub, sub, 3), np.uint8)
        sheet[:] = paper
        _hand_drawn_grid(sheet, rng, grid_ink, line_width)
    else:
        sheet = draw_sheet(grid, sub, sub, border=bool(rng.random() < 0.4), line_width=line_width,
                           ink=grid_ink, paper=paper)
    x0 = int(rng.uniform(0.02, 0.98) * (page_w - sub))
    y0 = int(rng.uniform(0.02, 0.98) * (page_h - sub))
    page[y0:y0 + sub, x0:x0 + sub] = sheet
    left, top, across, down, step = grid_layout(grid, sub, sub)
    homography = _camera_homography(rng, page_w, page_h, width, height, min_span)
    background = _table(rng, width, height)
    _clutter(background, rng)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    angle = rng.uniform(0, 2 * np.pi)
    ramp = (np.cos(angle) * (xx / width - 0.5) + np.sin(angle) * (yy / height - 0.5))
    gain = rng.uniform(0.8, 1.05) + rng.uniform(0.0, 0.45) * ramp
    vignette = 1 - rng.uniform(0, 0.25) * (((xx / width - 0.5) ** 2 + (yy / height - 0.5) ** 2) * 2)
    tint = 1 + rng.normal(0, 0.05, 3)
    light = (gain * vignette)[:, :, None] * tint[None, None, :]
    same_pen = rng.random() < 0.3
    ink_o = random_ink(rng)
    inks = (ink_o, ink_o if same_pen else random_ink(rng))
    scene = Scene(grid, page, (x0 + left, y0 + top, across, down, step), homography, background, light.astype(np.float32),
                  noise_sigma=float(rng.uniform(1, 7)),
                  jpeg_quality=int(rng.integers(55, 96)) if rng.random() < 0.5 else None,
                  blur_sigma=float(rng.uniform(0, 1.0)), inks=inks, styles=styles,
                  mark_seed=int(rng.integers(2**31)))
    if conditions == "harsh":  # drawn after everything else: a clean scene of the same seed stays the same
        scene.harsh = draw_harsh(rng, width, height, scene.page_corners())
    return scene


@dataclass
class Hand:
    """A hand holding a pen whose tip is at `tip` (frame pixels), arm coming from `edge`."""

    tip: tuple[float, float]
    skin: tuple[int, int, int]
    sleeve: tuple[int, int, int]
    from_angle: float   # direction the arm comes from (radians, 0 = from the right, -pi/2 = from the top)
    scale: float        # hand size in pixels (width of the palm)


def random_hand(rng: np.random.Generator, tip: tuple[float, float], scale: float | None = None) -> Hand:
    """A person's hand reaching a point, mostly from the far (top) side of the frame."""
    return Hand(tip=tip, skin=tuple(int(v) for v in np.clip(np.array(SKIN_BGR[int(rng.integers(len(SKIN_BGR)))]) + rng.normal(0, 10, 3), 0, 255)),
                sleeve=tuple(int(v) for v in rng.integers(0, 200, 3)),
                from_angle=float(-np.pi / 2 + rng.uniform(-0.9, 0.9)),
                scale=float(scale if scale is not None else rng.uniform(55, 85)))


def _draw_hand(img: np.ndarray, hand: Hand) -> None:
    """Arm, sleeve, palm, fingers and pen as filled shapes with a soft shadow."""
    h, w = img.shape[:2]
    tip = np.array(hand.tip, float)
    away = np.array([np.cos(hand.from_angle), np.sin(hand.from_angle)])
    side = np.array([-away[1], away[0]])
    s = hand.scale
    palm = tip + away * 0.9 * s + side * 0.25 * s
    wrist = palm + away * 0.6 * s
    elbow = wrist + away * max(w, h)  # far enough to leave the frame
    shadow = np.zeros((h, w), np.float32)
    layers = []
    arm = np.array([wrist + side * 0.33 * s, elbow + side * 0.5 * s, elbow - side * 0.5 * s, wrist - side * 0.33 * s])
    sleeve_start = wrist + away * 0.9 * s
    sleeve = np.array([sleeve_start + side * 0.42 * s, elbow + side * 0.55 * s, elbow - side * 0.55 * s, sleeve_start - side * 0.42 * s])
    layers.append(("poly", arm, hand.skin))
    layers.append(("poly", sleeve, hand.sleeve))
    layers.append(("ellipse", (palm, (0.55 * s, 0.42 * s), np.degrees(hand.from_angle)), hand.skin))
    for f in (-0.18, 0.0, 0.18):  # fingers curled towards the pen tip
        base = palm - away * 0.3 * s + side * f * s
        layers.append(("line", (base, tip + away * 0.25 * s + side * (0.12 + f * 0.4) * s, max(3, int(0.16 * s))), hand.skin))
    pen_back = tip + away * 1.3 * s - side * 0.35 * s
    layers.append(("line", (tip, pen_back, max(2, int(0.07 * s))), (30, 30, 40)))
    for kind, geom, _ in layers:
        _shape(shadow, kind, geom, 1.0, offset=side * 0.15 * s + away * -0.05 * s)
    shadow = cv2.GaussianBlur(shadow, (0, 0), 0.25 * s)
    img[:] = np.clip(img.astype(np.float32) * (1 - 0.35 * shadow[:, :, None]), 0, 255).astype(np.uint8)
    for kind, geom, colour in layers:
        _shape(img, kind, geom, colour)


def _shape(img: np.ndarray, kind: str, geom, colour, offset=(0.0, 0.0)) -> None:
    offset = np.asarray(offset, float)
    if kind == "poly":
        cv2.fillPoly(img, [np.round(geom + offset).astype(np.int32)], colour, cv2.LINE_AA)
    elif kind == "ellipse":
        centre, axes, angle = geom
        cv2.ellipse(img, tuple(int(v) for v in np.round(centre + offset)), tuple(int(v) for v in axes), angle, 0, 360,
                    colour, -1, cv2.LINE_AA)
    else:
        a, b, thickness = geom
        cv2.line(img, tuple(int(v) for v in np.round(a + offset)), tuple(int(v) for v in np.round(b + offset)),
                 colour, thickness, cv2.LINE_AA)


def render(scene: Scene, board: list[str], rng: np.random.Generator, partial: tuple[int, str, float] | None = None,
           hand: Hand | None = None) -> np.ndarray:
    """The frame (H, W, 3 uint8 BGR) showing `board`; `partial` = (cell, symbol, progress) half drawn."""
    n_cells = int(np.prod(grid_shape(scene.grid)))
    if len(board) != n_cells:
        raise ValueError(f"board must have {n_cells} cells; got {len(board)}")
    page = scene.page.copy()
    todo = [(c, s, 1.0) for c, s in enumerate(board) if s]
    if partial is not None:
        todo.append(partial)
    for cell, symbol, progress in todo:
        if symbol not in SYMBOL_KIND:
            raise ValueError(f"board cell {symbol!r} is unknown; expected 'x', 'o' or ''")
        m = scene.mark(cell, symbol)
        draw_mark(page, m.kind, m.center, m.size, np.random.default_rng(m.seed), progress=progress, ink=m.ink, style=m.style)
    width, height = scene.size
    scale = _page_scale(scene)
    small = cv2.resize(page, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) if scale < 1 else page
    S = np.diag([1 / scale, 1 / scale, 1]) if scale < 1 else np.eye(3)
    H = scene.homography @ S
    warped = cv2.warpPerspective(small, H, (width, height), flags=cv2.INTER_LINEAR)
    mask = cv2.warpPerspective(np.full(small.shape[:2], 255, np.uint8), H, (width, height), flags=cv2.INTER_LINEAR)
    alpha = (mask.astype(np.float32) / 255.0)[:, :, None]
    frame = scene.background.astype(np.float32) * (1 - alpha) + warped.astype(np.float32) * alpha
    frame = np.clip(frame, 0, 255).astype(np.uint8)
    if hand is not None:
        _draw_hand(frame, hand)
    out = frame.astype(np.float32) * scene.light
    harsh = scene.harsh
    if harsh is not None:
        out *= harsh.light
        out = cv2.remap(out, *lens_maps(harsh.lens_k, width, height), cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        out = cv2.filter2D(out, -1, harsh.motion)
    if scene.blur_sigma > 0.3:
        out = cv2.GaussianBlur(out, (0, 0), scene.blur_sigma)
    out += rng.normal(0, scene.noise_sigma if harsh is None else harsh.noise_sigma, out.shape).astype(np.float32)
    out = np.clip(out, 0, 255).astype(np.uint8)
    quality = scene.jpeg_quality if harsh is None else harsh.jpeg_quality
    if quality is not None:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, quality])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return out


def _page_scale(scene: Scene) -> float:
    """Shrink factor so the page is pre-filtered to about its size in the frame (no aliasing of thin ink)."""
    corners = scene.page_corners()
    span = max(np.ptp(corners[:, 0]), np.ptp(corners[:, 1]))
    return float(min(1.0, 1.3 * span / max(scene.page.shape[:2])))


def random_board(grid: Grid, rng: np.random.Generator, fill: float | None = None) -> list[str]:
    """A board with each cell empty / x / o (fill = chance a cell is marked), row-major over rows x cols."""
    rows, cols = grid_shape(grid)
    fill = rng.uniform(0.2, 0.8) if fill is None else fill
    return [("x" if rng.random() < 0.5 else "o") if rng.random() < fill else "" for _ in range(rows * cols)]


@dataclass
class Frame:
    """A generated photo and its truth."""

    image: np.ndarray
    board: list[str]
    page_corners: np.ndarray
    hand: bool


def make_frame(grid: Grid, seed: int, width: int = 640, height: int = 480, hand: bool = False,
               styles: tuple[str, ...] = ("pen",), conditions: str = "clean") -> Frame:
    """One random photo of a board on a 3x3, 9x9 or declared rows x cols grid; same seed -> same pixels
    ("harsh": see vision.data.conditions)."""
    rng = np.random.default_rng(seed)
    scene = random_scene(grid, rng, width, height, styles, conditions)
    board = random_board(grid, rng)
    hand_obj = None
    if hand:
        hand_obj = random_hand(rng, scene.cell_in_frame(int(rng.integers(len(board)))))
    return Frame(render(scene, board, rng, hand=hand_obj), board, scene.page_corners(), hand)

