"""The game sheet's shape when it is not lying flat: a curled edge, a fold's crease (field conditions).

Drawn per game by `ncbot.robot_sim.conditions` (ranges `curl_*`, `fold_*`), used by `ncbot.robot_sim.dressing` to build the
sheet as a bent mesh (its shading then comes from the scene's lights) and by the scene to put the robot's pen
on the bent surface.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SheetShape:
    """How the game sheet departs from a flat plane: a curled edge and/or a fold's crease (all heights in m).

    A sheet that was rolled or stored in a bag curls up along one edge; one that was folded in half and
    opened again keeps a crease that stands up as a low tent, its two halves sloping to the table (the
    light then falls differently on each half: a shading step along the crease)."""

    curl: float = 0.0            # height of the curled edge above the table
    curl_edge: int = 0           # which edge curls: 0..3 = +x, +y, -x, -y of the sheet's own frame
    curl_start: float = 0.5      # where the curl begins, as a fraction of the way from the centre to that edge
    fold: float = 0.0            # height of the crease above the table
    fold_angle: float = 0.0      # the crease's direction in the sheet's frame (rad)
    fold_offset: float = 0.0     # the crease's distance from the centre, as a fraction of the side

    @property
    def flat(self) -> bool:
        return self.curl == 0.0 and self.fold == 0.0

    def height(self, x: np.ndarray, y: np.ndarray, side: float) -> np.ndarray:
        """Height (m) above the table of the sheet's points at local (x, y) m from its centre (any shape)."""
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        z = np.zeros(np.broadcast(x, y).shape)
        half = side / 2
        if self.curl > 0:
            along = (x, y, -x, -y)[self.curl_edge] / half          # 1 at the curled edge
            t = np.clip((along - self.curl_start) / (1.0 - self.curl_start), 0.0, None)
            z = z + self.curl * t * t                              # a smooth bend, steepest at the edge
        if self.fold > 0:
            distance = (x * -math.sin(self.fold_angle) + y * math.cos(self.fold_angle)) - self.fold_offset * side
            # each half slopes from the crease down to the table at its far corner (a tent, not a ridge)
            reach = half * math.sqrt(2) + abs(self.fold_offset) * side
            z = z + self.fold * np.clip(1.0 - np.abs(distance) / reach, 0.0, None)
        return z

    def summary(self) -> dict[str, float]:
        return {"sheet_curl_m": round(self.curl, 4), "sheet_fold_m": round(self.fold, 4)}


def sample_sheet_shape(rng: np.random.Generator, curl: tuple[float, tuple[float, float]],
                       fold: tuple[float, tuple[float, float]]) -> SheetShape:
    """One game's sheet shape: `curl` and `fold` are (probability, (low, high) height in m); curled and
    folded independently (a sheet may be both)."""
    curl_height = float(rng.uniform(*curl[1])) if rng.random() < curl[0] else 0.0
    edge, start = int(rng.integers(4)), float(rng.uniform(0.3, 0.7))
    fold_height = float(rng.uniform(*fold[1])) if rng.random() < fold[0] else 0.0
    # a sheet folded in half (or in a third): the crease runs across, roughly parallel to an edge
    angle = float(rng.integers(2)) * math.pi / 2 + float(rng.uniform(-0.15, 0.15))
    offset = float(rng.choice([0.0, 1 / 6, -1 / 6])) + float(rng.uniform(-0.03, 0.03))
    return SheetShape(curl_height, edge, start, fold_height, angle, offset)
