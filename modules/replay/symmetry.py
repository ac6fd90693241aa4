"""Board symmetries (rotations and reflections) as index maps over observations and actions: replay augmentation.

Why: Noughts & Crosses is invariant under the 8 symmetries of the square (the dihedral group D4), and so is
Ultimate when the whole 9x9 grid is turned: a turn maps subgrids to subgrids and each cell's place inside its
subgrid the same way, so the cell that sends the next player to a subgrid still sends them to the turned one.
The learner sees each sampled transition under a random symmetry, which gives it eight views of every game and
pulls the values of symmetric moves together (the 3x3 measurements: docs/learning.md, "Why the fast configs differ
from the paper").

Only the cell-indexed parts move: the robot's and the user's mark features, the temporal features and the game
moves among the actions (with their masks). Dialogue words and commands name no square, so they stay put; the
reward, the outcome and the done flags are the same in every orientation.
"""
from __future__ import annotations

import re
from typing import Sequence

import torch

from ncbot.envs.games.symmetries import square_symmetries  # noqa: F401  (re-exported: the 3x3 and 9x9 maps)

AUGMENT_CHOICES = ("none", "d4")
CELL_FEATURE = re.compile(r"^(robot_move|human_move|time)\[(\d+)\]$")


def game_symmetries(game: str) -> torch.Tensor:
    """(G, cells) the board symmetries of ``game``: the maps its rules are unchanged under (``Game.symmetries``)."""
    from ncbot.envs.games import make_game

    return make_game(game).symmetries()


class BoardSymmetries:
    """Per-row random board symmetries applied to batches of transitions (see module doc).

    `feature_index[g]` gathers an observation into its image under g (image[j] = observation[feature_index[g, j]]);
    `action_map[g]` sends an action to its image; `action_index[g]` gathers a per-action mask into its image.
    """

    def __init__(self, feature_names: Sequence[str], cells: int, n_actions: int, seed: int = 0,
                 device: torch.device | str = "cpu", image: torch.Tensor | None = None) -> None:
        if image is None:  # a square board's 8 (``image``: a declared game's, ``game_symmetries``)
            side = round(cells ** 0.5)
            if side * side != cells or side not in (3, 9):
                raise ValueError(f"board symmetries need a 3x3 or 9x9 board, got {cells} cells")
            image = square_symmetries(side)  # (8, cells)
        if image.shape[1] != cells:
            raise ValueError(f"board symmetries map {image.shape[1]} cells, the board has {cells}")
        self.count = image.shape[0]
        preimage = torch.argsort(image, dim=1)  # the cell that lands on each cell
        features = len(feature_names)
        self.feature_index = torch.arange(features).repeat(self.count, 1)
        for position, name in enumerate(feature_names):
            match = CELL_FEATURE.match(name)
            if match is None:
                continue
            cell = int(match.group(2))
            slice_start = position - cell  # the slice's cell 0
            self.feature_index[:, position] = slice_start + preimage[:, cell]
        self.action_map = torch.arange(n_actions).repeat(self.count, 1)
        self.action_map[:, :cells] = image
        self.action_index = torch.arange(n_actions).repeat(self.count, 1)
        self.action_index[:, :cells] = preimage
        # on the device of the sampled batches they turn: the draws and the gathers stay there
        self.feature_index, self.action_map, self.action_index = (
            self.feature_index.to(device), self.action_map.to(device), self.action_index.to(device))
        self.generator = torch.Generator(device=device).manual_seed(seed)

    @classmethod
    def from_env(cls, env, seed: int = 0, device: torch.device | str = "cpu") -> "BoardSymmetries":
        """The symmetries of a dialogue env's observation and action layout."""
        return cls(env.feature_names, env.cells, env.n_actions, seed, device, game_symmetries(env.game))

    def draw(self, rows: int) -> torch.Tensor:
        """(rows,) int64 symmetry indices, uniform over the board's (8 on a square), from this object's own generator."""
        return torch.randint(0, self.count, (rows,), generator=self.generator, device=self.generator.device)

    def observations(self, observation: torch.Tensor, which: torch.Tensor) -> torch.Tensor:
        return observation.gather(1, self.feature_index.index_select(0, which))

    def actions(self, action: torch.Tensor, which: torch.Tensor) -> torch.Tensor:
        return self.action_map[which, action.reshape(-1)].reshape(action.shape)

    def masks(self, mask: torch.Tensor, which: torch.Tensor) -> torch.Tensor:
        return mask.gather(1, self.action_index.index_select(0, which))

    def transitions(self, observation: torch.Tensor, action: torch.Tensor, next_observation: torch.Tensor,
                    next_mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """A random symmetry per row, the same for the state, the action and the next state of that row."""
        which = self.draw(observation.shape[0])
        return (self.observations(observation, which), self.actions(action, which),
                self.observations(next_observation, which), self.masks(next_mask, which))

    def state_dict(self) -> dict:
        return {"generator": self.generator.get_state()}

    def load_state_dict(self, state: dict) -> None:
        self.generator.set_state(state["generator"])


def make_symmetries(augment: str, env, seed: int, device: torch.device | str = "cpu") -> BoardSymmetries | None:
    """`buffer.augment`: None for `none`, the env's board symmetries for `d4`."""
    if augment not in AUGMENT_CHOICES:
        raise ValueError(f"unknown buffer.augment {augment!r}; expected one of {', '.join(AUGMENT_CHOICES)}")
    return BoardSymmetries.from_env(env, seed, device) if augment == "d4" else None
