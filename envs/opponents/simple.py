"""The cheap batched opponents: ``random`` (the paper's simulated user), ``rule`` (win, else block, else random) and
``winner:P`` (the random user that takes a game-winning square with probability P)."""
from __future__ import annotations

import torch

from ncbot.envs.opponents.base import Opponent, masked_uniform_choice, no_argument, register_opponent


class RandomOpponent(Opponent):
    """Uniform among the legal cells: one rand + argmax over the whole batch."""

    name = "random"

    def _select(self, boards, last_move, legal, player, generator, owners):
        return masked_uniform_choice(legal, generator)


class RuleOpponent(Opponent):
    """Take a winning cell if there is one, else block the opponent's, else play at random: the game's own scores
    (``Game.rule_scores``). On Ultimate the same rule is applied at two levels, in this order of preference: win the
    game, block a game-winning cell of the opponent, take a subgrid, block the opponent taking a subgrid, random.
    Ties are broken uniformly at random.
    """

    name = "rule"

    def _select(self, boards, last_move, legal, player, generator, owners):
        return masked_uniform_choice(legal, generator, self.rules.rule_scores(boards, player, owners))


class WinnerOpponent(Opponent):
    """The paper's random user, except that with probability ``share`` it takes a square that wins the game at once
    when it has one. Why: a training user (``env.opponent``) that punishes the positions where the robot is left
    without a safe move more often than the random user does, while playing like it everywhere else, so the
    learner sees more of the rare losses the random user inflicts (evaluation keeps ``eval.opponent: random``)."""

    name = "winner"

    def __init__(self, share: float, game: str = "standard", free_move: str = "anywhere", seed: int = 0) -> None:
        super().__init__(game, free_move, seed)
        self.share = float(share)

    def _select(self, boards, last_move, legal, player, generator, owners):
        wins = self.rules.winning_cells(boards, player, owners) & legal
        take = (torch.rand(legal.shape[0], generator=generator) < self.share) & wins.any(1)
        return torch.where(take, masked_uniform_choice(wins, generator), masked_uniform_choice(legal, generator))


def _random_factory(arg, *, game, free_move, seed):
    no_argument("random", arg)
    return RandomOpponent(game, free_move, seed)


def _rule_factory(arg, *, game, free_move, seed):
    no_argument("rule", arg)
    return RuleOpponent(game, free_move, seed)


register_opponent("random", _random_factory)
register_opponent("rule", _rule_factory)


def _winner_factory(arg, *, game, free_move, seed):
    try:
        share = float(arg) if arg is not None else None
    except ValueError:
        share = None
    if share is None or not 0.0 <= share <= 1.0:
        raise ValueError(f"opponent 'winner' needs the share of winning squares it takes, 0..1, e.g. 'winner:0.5'; "
                         f"got 'winner:{arg or ''}'")
    return WinnerOpponent(share, game, free_move, seed)


register_opponent("winner", _winner_factory, "winner:P")
