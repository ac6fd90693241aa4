"""The two cheap batched opponents: ``random`` (the paper's simulated user) and ``rule`` (win, else block, else random)."""
from __future__ import annotations

from envs.opponents.base import Opponent, masked_uniform_choice, no_argument, register_opponent
from envs.opponents.lines import subgrid_owners, subgrid_taking_cells, winning_cells


class RandomOpponent(Opponent):
    """Uniform among the legal cells: one rand + argmax over the whole batch."""

    name = "random"

    def _select(self, boards, last_move, legal, player, generator, owners):
        return masked_uniform_choice(legal, generator)


class RuleOpponent(Opponent):
    """Take a winning cell if there is one, else block the opponent's, else play at random.

    On Ultimate the same rule is applied at two levels, in this order of preference: win the game, block a
    game-winning cell of the opponent, take a subgrid, block the opponent taking a subgrid, random. Ties are
    broken uniformly at random.
    """

    name = "rule"

    def _select(self, boards, last_move, legal, player, generator, owners):
        other = 3 - player
        if self.game == "standard":
            scores = 2 * winning_cells(boards, player).long() + winning_cells(boards, other).long()
        else:
            owners = subgrid_owners(boards) if owners is None else owners
            takes_mine = subgrid_taking_cells(boards, player, owners)
            takes_theirs = subgrid_taking_cells(boards, other, owners)
            scores = (
                8 * winning_cells(boards, player, owners, takes_mine).long()
                + 4 * winning_cells(boards, other, owners, takes_theirs).long()
                + 2 * takes_mine.long()
                + takes_theirs.long()
            )
        return masked_uniform_choice(legal, generator, scores)


def _random_factory(arg, *, game, free_move, seed):
    no_argument("random", arg)
    return RandomOpponent(game, free_move, seed)


def _rule_factory(arg, *, game, free_move, seed):
    no_argument("rule", arg)
    return RuleOpponent(game, free_move, seed)


register_opponent("random", _random_factory)
register_opponent("rule", _rule_factory)
