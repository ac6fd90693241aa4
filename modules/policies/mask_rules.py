"""The one-step look-ahead rules of the paper (section 4 and 4b) and the TensorDict keys every mask rule reads.

A rule maps the env's `action_mask` (available actions), `lookahead_reward` (one-step reward of every action) and
`winning_actions` (the paper's set A when non-empty) to (explore mask, greedy mask). The deeper rules of
`ncbot.modules.policies.deep_lookahead` build on these keys; `ncbot.modules.policies.masks` names every rule in one table.

When every allowed action has a negative look-ahead reward, the paper leaves the greedy choice open (Algorithm 2
takes the argmax over A minus A_hat, which is then empty). The option ``agent.all_negative`` decides:
``available`` falls back to the whole set A (this project's first reading; with ``env.taken_squares: refused``
A holds the squares already taken, most of the fallback on Ultimate: docs/env.md), ``untaken`` to A without the squares taken
to the robot's knowledge (the env's ``board`` key), following section 3: "all game moves were allowed from the
subset of those not taken yet (to the robot's knowledge)". Exploration (epsilon picks in A) is the same in both.
"""
from __future__ import annotations

from collections.abc import Callable

import torch

AVAILABLE_KEY = "action_mask"
LOOKAHEAD_REWARD_KEY = "lookahead_reward"
WINNING_KEY = "winning_actions"
BOARD_KEY = "board"  # (B, cells) the robot's knowledge of the board, nonzero = taken
EXPLORE_MASK_KEY = "explore_mask"
GREEDY_MASK_KEY = "greedy_mask"

MaskRule = Callable[..., tuple[torch.Tensor, torch.Tensor]]  # (available, reward, winning, untaken=None)
ALL_NEGATIVE_CHOICES = ("available", "untaken")


def check_all_negative(all_negative: str) -> str:
    """``all_negative`` if it is one of ALL_NEGATIVE_CHOICES; one-line ValueError otherwise."""
    if not isinstance(all_negative, str) or all_negative not in ALL_NEGATIVE_CHOICES:
        raise ValueError(f"all_negative must be one of {', '.join(ALL_NEGATIVE_CHOICES)}; got {all_negative!r}")
    return all_negative


def untaken_actions(board: torch.Tensor, n_actions: int) -> torch.Tensor:
    """(..., n_actions) bool: every act except the game moves on squares taken on ``board`` (..., cells)."""
    cells = board.shape[-1]
    talk = torch.ones(*board.shape[:-1], n_actions - cells, dtype=torch.bool, device=board.device)
    return torch.cat([board == 0, talk], dim=-1)


def all_moves_negative(available: torch.Tensor, reward: torch.Tensor, cells: int) -> torch.Tensor:
    """(...,) bool: the state allows at least one game move (the first ``cells`` actions) and every allowed game
    move has a negative look-ahead reward, the states where the ``all_negative`` reading decides the greedy move."""
    moves = available[..., :cells]
    return moves.any(-1) & ~(moves & (reward[..., :cells] >= 0)).any(-1)


def fallback(set_a: torch.Tensor, untaken: torch.Tensor | None) -> torch.Tensor:
    """The greedy mask when nothing in ``set_a`` is safe: ``set_a`` itself (``all_negative="available"``, ``untaken``
    None) or ``set_a`` without the taken squares (``"untaken"``), ``set_a`` if that would leave nothing."""
    return set_a if untaken is None else nonempty_or(set_a & untaken, set_a)


def nonempty_or(mask: torch.Tensor, fallback: torch.Tensor) -> torch.Tensor:
    """Rows of `mask` with no True entry are replaced by the same row of `fallback`."""
    return torch.where(mask.any(-1, keepdim=True), mask, fallback)


def no_lookahead(available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor,
                 untaken: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """DQN-Original: plain masked DQN; repeated or losing moves are only discouraged by their -5 reward (it has no
    look-ahead, so no fallback: ``untaken`` is ignored)."""
    return available, available


def variant_lookahead(
    available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor, untaken: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """DQN-Variant: the greedy choice skips the available actions tied for the lowest reward when it is negative.

    Exploration is unchanged (uniform over available actions); there is no win-forcing. When every available
    action ties at a negative lowest reward, the greedy mask falls back to ``fallback(available, untaken)``.
    """
    masked_reward = torch.where(available, reward, torch.full_like(reward, float("inf")))
    lowest = masked_reward.min(-1, keepdim=True).values
    worst = available & (reward == lowest) & (lowest < 0)
    return available, nonempty_or(available & ~worst, fallback(available, untaken))


def one_step_lookahead(
    available: torch.Tensor, reward: torch.Tensor, winning: torch.Tensor, untaken: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Proposed (Algorithm 2): A = winning actions if any else available; greedy over A minus A_hat (negative reward).

    Epsilon picks uniformly in A; the greedy argmax falls back to ``fallback(A, untaken)`` when every action of A
    has a negative reward (A itself, or A without the taken squares: ``all_negative``).
    """
    set_a = nonempty_or(winning & available, available)
    a_hat = reward < 0
    return set_a, nonempty_or(set_a & ~a_hat, fallback(set_a, untaken))
