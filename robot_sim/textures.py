"""Procedural surface textures (no downloads): wood, laminate, linen, carpet, tiles, stone, paint, brick, panels.

Each is an RGBA uint8 image built from the surface's base colour and a seed with numpy only (smooth value
noise, stripes, grout lines), so a scene's look is reproducible from its seed and costs a few milliseconds.
"""
from __future__ import annotations

import numpy as np


def value_noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """Smooth noise in [0, 1] (size x size): random values on a cells x cells lattice, bilinearly upsampled."""
    import cv2

    lattice = rng.random((cells + 1, cells + 1)).astype(np.float32)
    return cv2.resize(lattice, (size, size), interpolation=cv2.INTER_CUBIC).clip(0.0, 1.0)


def _fractal(rng: np.random.Generator, size: int, octaves: tuple[int, ...] = (4, 16, 64)) -> np.ndarray:
    total = sum(value_noise(rng, size, c) / (k + 1) for k, c in enumerate(octaves))
    return (total - total.min()) / max(float(np.ptp(total)), 1e-6)


def _grid_lines(size: int, period: int, width: int) -> np.ndarray:
    idx = np.arange(size)
    line = (idx % period) < width
    return line[:, None] | line[None, :]


def _shade(colour: tuple[float, float, float], shade: np.ndarray) -> np.ndarray:
    """RGB image: the base colour times a per-pixel shade (about 1 on average)."""
    return np.clip(np.asarray(colour, np.float32)[None, None, :] * shade[:, :, None], 0.0, 1.0)


def surface_texture(kind: str, colour: tuple[float, float, float], seed: int, size: int = 512) -> np.ndarray:
    """An RGBA uint8 texture of `kind` in `colour` (RGB in [0, 1])."""
    rng = np.random.default_rng(seed)
    fine = _fractal(rng, size)
    if kind == "wood":
        ys = np.linspace(0, 1, size, dtype=np.float32)[:, None]
        warp = value_noise(rng, size, 3) * 1.2 + 0.15 * value_noise(rng, size, 24)
        grain = 0.5 + 0.5 * np.sin(2 * np.pi * (ys * float(rng.uniform(25, 45)) + warp))
        shade = 0.85 + 0.2 * grain ** 4 + 0.08 * (fine - 0.5)
    elif kind == "laminate":
        shade = 0.97 + 0.06 * (fine - 0.5) + 0.03 * (value_noise(rng, size, 128) - 0.5)
    elif kind == "linen":
        idx = np.arange(size, dtype=np.float32)
        weave = 0.5 * (np.sin(idx * 1.7)[:, None] + np.sin(idx * 1.9)[None, :])
        shade = 0.95 + 0.05 * weave + 0.08 * (fine - 0.5)
    elif kind == "carpet":
        speckle = rng.random((size, size)).astype(np.float32)
        shade = 0.85 + 0.25 * speckle * fine + 0.1 * (fine - 0.5)
    elif kind in ("tiles", "stone"):
        period = 64 if kind == "tiles" else 128
        tile = rng.uniform(0.88, 1.08, (size // period + 1, size // period + 1)).astype(np.float32)
        idx = np.arange(size) // period
        shade = tile[idx[:, None], idx[None, :]] + (0.25 if kind == "stone" else 0.06) * (fine - 0.5)
        shade = np.where(_grid_lines(size, period, 3), 0.55, shade)
    elif kind == "paint":
        shade = 0.97 + 0.05 * (fine - 0.5)
    elif kind == "brick":
        rows = np.arange(size)[:, None] // 32
        cols = (np.arange(size)[None, :] + (rows % 2) * 32) // 64
        brick = rng.uniform(0.8, 1.1, (size // 32 + 1, size // 64 + 2)).astype(np.float32)[rows, cols]
        mortar = (np.arange(size)[:, None] % 32 < 3) | ((np.arange(size)[None, :] + (rows % 2) * 32) % 64 < 3)
        shade = np.where(mortar, 1.35, brick + 0.15 * (fine - 0.5))
    elif kind == "panels":
        shade = np.where(_grid_lines(size, 128, 2), 0.6, 0.96 + 0.05 * (fine - 0.5))
    elif kind == "plain":
        shade = np.ones((size, size), np.float32)
    else:
        raise ValueError(f"texture kind must be one of wood, laminate, linen, carpet, tiles, stone, paint, brick, panels, plain; got {kind!r}")
    rgba = np.empty((size, size, 4), np.uint8)
    rgba[:, :, :3] = (255 * _shade(colour, shade.astype(np.float32))).astype(np.uint8)
    rgba[:, :, 3] = 255
    return rgba
