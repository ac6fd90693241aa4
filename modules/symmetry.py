"""The 8 symmetries of the 3x3 board (rotations and reflections) applied to replay transitions.

Why: the game and the random user are symmetric, so (g s, g a, r, g s') is as true a transition as (s, a, r, s')
for every symmetry g. Without it the Q-network has to learn each of up to 8 equivalent positions from its own
visits, and the rarely visited ones stay imprecise: the near-tied choices that decide the last few lost games
(the reply to an edge opening, the follow-up after corner-centre) are made in exactly such positions.
Only the cell-indexed parts change: the move features (`robot_move[c]`, `human_move[c]`, `time[c]`), the
GameMove actions and the move columns of the action mask; the dialogue features and acts stay as they are.
"""
from __future__ import annotations

import re

import torch
from tensordict import TensorDictBase

SIZE = 3
CELLS = SIZE * SIZE
CELL_FEATURE = re.compile(r"^(robot_move|human_move|time)\[(\d+)\]$")


def square_symmetries() -> torch.Tensor:
    """(8, 9) int64: row g maps each cell c to its image g(c) (identity first)."""
    rows, cols = torch.meshgrid(torch.arange(SIZE), torch.arange(SIZE), indexing="ij")
    images = []
    for flip in (False, True):
        r, c = (rows, cols) if not flip else (rows, SIZE - 1 - cols)
        for _ in range(4):
            images.append((r * SIZE + c).reshape(-1))
            r, c = c, SIZE - 1 - r  # rotate a quarter turn
    return torch.stack(images)


class BoardSymmetries:
    """Gather tables that move features, actions and action masks through the 8 board symmetries."""

    def __init__(self, feature_names: list[str], n_actions: int) -> None:
        images = square_symmetries()
        inverse = torch.argsort(images, dim=1)  # inverse[g, t] = the cell that g sends to t
        n_features = len(feature_names)
        cell_of = {}
        for index, name in enumerate(feature_names):
            match = CELL_FEATURE.match(name)
            if match:
                cell_of[index] = (match.group(1), int(match.group(2)))
        if len(cell_of) < 2 * CELLS or any(cell >= CELLS for _, cell in cell_of.values()):
            raise ValueError("board symmetries apply to the 3x3 game only (its move features name 9 cells)")
        index_of = {key: index for index, key in cell_of.items()}
        feature_source = torch.arange(n_features).repeat(8, 1)
        action_source = torch.arange(n_actions).repeat(8, 1)
        for g in range(8):
            for index, (kind, cell) in cell_of.items():
                feature_source[g, index] = index_of[(kind, int(inverse[g, cell]))]
            action_source[g, :CELLS] = inverse[g]
        self.images = images
        self.feature_source = feature_source  # new[:, j] = old[:, feature_source[g, j]]
        self.action_source = action_source  # new_mask[:, a] = old_mask[:, action_source[g, a]]

    def apply(self, transitions: TensorDictBase, which: torch.Tensor) -> TensorDictBase:
        """Each row i moved through symmetry which[i] (0 = identity), in place; returns `transitions`."""
        features = self.feature_source[which]
        actions = self.action_source[which]
        for key in ("observation", ("next", "observation")):
            transitions.set(key, transitions.get(key).gather(-1, features))
        for key in ("action_mask", ("next", "action_mask")):
            transitions.set(key, transitions.get(key).gather(-1, actions))
        action = transitions.get("action")
        moved = self.images[which, action.clamp(max=CELLS - 1)]
        transitions.set("action", torch.where(action < CELLS, moved, action))
        return transitions

    def randomise(self, transitions: TensorDictBase, generator: torch.Generator | None = None) -> TensorDictBase:
        """Every row through a uniformly drawn symmetry (1 of 8): same data volume, symmetric distribution."""
        which = torch.randint(0, 8, (transitions.shape[0],), generator=generator)
        return self.apply(transitions, which)
