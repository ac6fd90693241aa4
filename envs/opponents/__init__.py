"""Opponents for the simulated user and for evaluation, chosen by name: see ``make_opponent``.

>>> opp = make_opponent("mcts:100", game="ultimate", free_move="anywhere", seed=0)
>>> cells = opp.select(boards, last_move, legal, player, generator)  # (B,) int64 legal cells

Built-in names: ``random``, ``rule``, ``minimax`` (3x3 only), ``mcts:N``, ``openspiel-mcts:N`` (OpenSpiel's
``MCTSBot``; needs the optional package open_spiel, imported only when such an opponent is built). Higher layers add their own kinds
with ``register_opponent`` (the learning pipeline registers ``agent:CHECKPOINT``).
"""
from ncbot.envs.opponents.base import Opponent, make_opponent, opponent_choices, register_opponent
from ncbot.envs.opponents import simple, minimax, mcts, openspiel  # noqa: F401  (importing registers the built-in kinds)
from ncbot.envs.opponents.mcts import MCTSOpponent, uct_search
from ncbot.envs.opponents.minimax import MinimaxOpponent
from ncbot.envs.opponents.simple import RandomOpponent, RuleOpponent

__all__ = [
    "Opponent",
    "make_opponent",
    "register_opponent",
    "opponent_choices",
    "RandomOpponent",
    "RuleOpponent",
    "MinimaxOpponent",
    "MCTSOpponent",
    "uct_search",
]
