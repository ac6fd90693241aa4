"""The person's move as the robot perceives it: the env opponent whose moves are the recogniser's, and the camera
frame conversions the closed loop (`ncbot.robot_sim.play`) uses."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ncbot.fileio import atomic_write_bytes


class PerceivedHumanOpponent:
    """An env opponent whose moves are whatever the robot perceived the simulated human draw."""

    def __init__(self, perceive: Callable[[np.ndarray], int]) -> None:
        self.perceive = perceive

    def select(self, boards, last_move, legal, player, generator=None):
        import torch

        moves = [self.perceive(row.numpy().astype(bool)) for row in legal]
        return torch.tensor(moves, dtype=torch.int64)


def rgb_to_bgr(frame: np.ndarray) -> np.ndarray:
    """A rendered RGB frame as the BGR image OpenCV and the reader take."""
    return np.ascontiguousarray(frame[:, :, ::-1])


def write_png_atomic(path: Path, image_bgr: np.ndarray) -> None:
    """A BGR image as PNG, written atomically (a snapshot is never half a file)."""
    import cv2

    ok, data = cv2.imencode(".png", image_bgr)
    if not ok:
        raise ValueError(f"could not encode the snapshot for {path}")
    atomic_write_bytes(data.tobytes(), path)
