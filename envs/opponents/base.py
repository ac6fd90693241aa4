"""The opponent interface and the name registry (``"random"``, ``"rule"``, ``"minimax"``, ``"mcts:100"``, ...).

Opponents work on whole batches of boards because the env runs many games at once. They receive the legal
mask from the caller (the env already computed it), so an opponent never disagrees with the env about what
is legal; its own rules knowledge is only used to look ahead. Names are resolved through a registry so that
``pipelines`` can add ``"agent:CHECKPOINT"`` without ``envs`` importing anything above it.
"""
from __future__ import annotations

from typing import Callable, Protocol

import torch

from ncbot.envs.core import check_free_move
from ncbot.envs.games import check_game, make_game

class Opponent:
    """A move chooser for batches of games; subclasses implement ``_select``.

    Board codes: 0 empty, 1 robot, 2 human; ``player`` is the code of the side choosing. ``last_move`` is -1
    at the start of a game. Rows whose legal mask is all False are ignored and get cell 0.
    """

    name: str = "opponent"

    def __init__(self, game: str = "standard", free_move: str = "anywhere", seed: int = 0) -> None:
        self.free_move = check_free_move(free_move)
        self.rules = make_game(game, self.free_move)  # the game object: its rules and what follows from them
        self.game = self.rules.id
        self.n_cells = self.rules.n_cells
        self.seed = int(seed)
        self._own_generator = torch.Generator().manual_seed(self.seed)

    def select(
        self,
        boards: torch.Tensor,
        last_move: torch.Tensor,
        legal: torch.Tensor,
        player: int,
        generator: torch.Generator | None = None,
        owners: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """(B,) int64 legal cells, one per row; ``generator`` (default: the opponent's own, seeded) drives all chance.

        ``owners`` (B, subgrids) optional, for a game whose state tracks subgrid owners (Ultimate): as board codes
        (0 open, 1, 2, 3 drawn). With ``free_move="anywhere"`` a subgrid can hold lines of both players and only the
        history tells who took it first; callers that track owners (the env, the arena) pass them so look-ahead
        opponents are exact.
        """
        boards, last_move, legal = self._check_inputs(boards, last_move, legal, player)
        if owners is not None:
            subgrids = self.rules.subgrids
            if not subgrids or tuple(owners.shape) != (boards.shape[0], subgrids):
                raise ValueError(f"owners must have shape ({boards.shape[0]}, {subgrids}) and only go with a game that "
                                 f"tracks subgrid owners; {self.rules.name} tracks {subgrids or 'none'}")
            owners = owners.to(torch.int8)
        generator = self._own_generator if generator is None else generator
        return self._select(boards, last_move, legal, int(player), generator, owners)

    __call__ = select

    def _select(
        self, boards: torch.Tensor, last_move: torch.Tensor, legal: torch.Tensor, player: int,
        generator: torch.Generator, owners: torch.Tensor | None,
    ) -> torch.Tensor:
        raise NotImplementedError

    def _check_inputs(
        self, boards: torch.Tensor, last_move: torch.Tensor, legal: torch.Tensor, player: int
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        if boards.dim() != 2 or boards.shape[1] != self.n_cells:
            raise ValueError(f"boards must have shape (B, {self.n_cells}) for the {self.game} game, got {tuple(boards.shape)}")
        batch = boards.shape[0]
        if legal.shape != boards.shape:
            raise ValueError(f"legal must have the boards' shape {tuple(boards.shape)}, got {tuple(legal.shape)}")
        last_move = last_move.reshape(-1)
        if last_move.shape[0] != batch:
            raise ValueError(f"last_move must hold {batch} entries (one per board), got {last_move.shape[0]}")
        if player not in (1, 2):
            raise ValueError(f"player must be 1 (robot) or 2 (human), got {player!r}")
        return boards, last_move.long(), legal.bool()

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, game={self.game!r}, free_move={self.free_move!r})"


def masked_uniform_choice(legal: torch.Tensor, generator: torch.Generator, scores: torch.Tensor | None = None) -> torch.Tensor:
    """A uniformly random cell among the legal ones with the highest score per row (0 for rows without any)."""
    noise = torch.rand(legal.shape, generator=generator, device=legal.device)
    key = noise if scores is None else scores.to(noise.dtype) * 2.0 + noise  # scores are integers: noise breaks ties
    key = key.masked_fill(~legal, -1.0)
    cells = key.argmax(dim=1)
    return torch.where(legal.any(dim=1), cells, torch.zeros_like(cells))


class OpponentFactory(Protocol):
    def __call__(self, arg: str | None, *, game: str, free_move: str, seed: int) -> Opponent: ...


_REGISTRY: dict[str, tuple[OpponentFactory, str]] = {}


def register_opponent(kind: str, factory: OpponentFactory | Callable[..., Opponent], usage: str | None = None) -> None:
    """Make ``make_opponent("kind")`` / ``make_opponent("kind:ARG")`` call ``factory(arg, game=, free_move=, seed=)``.

    ``usage`` is how the name is shown in error messages (e.g. ``"agent:CHECKPOINT"``). Registering a kind again
    replaces it, so a pipeline can re-register after reloading.
    """
    if not kind or ":" in kind:
        raise ValueError(f"opponent kind must be a non-empty name without ':', got {kind!r}")
    _REGISTRY[kind] = (factory, usage or kind)


def opponent_choices() -> list[str]:
    """The registered names as users write them, e.g. ``["random", "rule", "minimax", "mcts:N"]``."""
    return [usage for _, usage in _REGISTRY.values()]


def make_opponent(name: str, game: str = "standard", free_move: str = "anywhere", seed: int = 0) -> Opponent:
    """Build an opponent from its name (``kind`` or ``kind:ARG``); ValueError listing the choices if unknown."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"opponent must be a name, one of {', '.join(opponent_choices())}; got {name!r}")
    game = check_game(game)
    check_free_move(free_move)
    kind, _, arg = name.partition(":")
    if kind not in _REGISTRY:
        raise ValueError(f"unknown opponent {name!r}: choose one of {', '.join(opponent_choices())}")
    factory, _ = _REGISTRY[kind]
    return factory(arg if ":" in name else None, game=game, free_move=free_move, seed=seed)


def no_argument(kind: str, arg: str | None) -> None:
    """Reject ``kind:ARG`` for kinds that take no argument."""
    if arg is not None:
        raise ValueError(f"opponent {kind!r} takes no ':' argument, got {kind}:{arg}")


def simulation_count(kind: str, arg: str | None, example: int = 100) -> int:
    """The N of ``kind:N`` for search opponents; ValueError naming the expected form otherwise."""
    try:
        simulations = int(arg) if arg is not None else None
    except ValueError:
        simulations = None
    if simulations is None or simulations < 1:
        raise ValueError(f"opponent '{kind}' needs a positive simulation count, e.g. '{kind}:{example}'; "
                         f"got '{kind}:{arg or ''}'")
    return simulations
