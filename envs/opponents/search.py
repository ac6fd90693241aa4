"""One Monte-Carlo tree search loop; how it picks children and scores leaves are hooks.

As OpenSpiel's ``MCTSBot`` separates the search from its evaluator, the loop here only walks the tree, asks the
evaluator for a leaf's value and backs it up. Two child-selection rules: ``UCT`` (UCB1, one random untried move
expanded per simulation: plain ``mcts:N``) and ``PUCT`` (AlphaZero-style, priors set by the evaluator when it
expands a node: the Q-guided search of ``ncbot.modules.search.guided_mcts``). One evaluator lives here, ``RandomRollout``
(a uniformly random playout); the Q-guided one lives in ``modules`` beside the network it reads.

Positions and moves are those of the bitboard engines (``ncbot.envs.opponents.bitboards``): sides 0 / 1 relative to
the mover of the searched position, results ``ONGOING``, 0, 1 or ``DRAW``. A node's ``value`` sums the leaf
values (win 1, draw 0.5, loss 0) for its ``mover``, the side whose move led to it (the root's mover is -1).
"""
from __future__ import annotations

import math
from typing import Callable, Protocol

from ncbot.envs.opponents.bitboards import DRAW

Rand = Callable[[], float]  # random.Random.random: all chance of a search comes from one such stream


class Node:
    """A search-tree node. ``moves``: for UCT the moves not expanded yet (consumed as children are made), for PUCT
    the moves the evaluator expanded the node with (None before), with their ``priors``. ``children``: UCT appends
    them in creation order; PUCT keeps one slot per move of ``moves`` (None until first selected). A list, not a
    dict by move: the UCB1 scan over a root's 81 children is the search's hot loop after the playouts."""

    __slots__ = ("pos", "move", "mover", "visits", "value", "moves", "priors", "children")

    def __init__(self, pos: tuple, move: int, mover: int, moves: list[int] | None = None) -> None:
        self.pos, self.move, self.mover, self.moves = pos, move, mover, moves
        self.visits, self.value = 0, 0.0
        self.priors: list[float] | None = None
        self.children: list = []


class TreePolicy(Protocol):
    def child(self, node: Node, rand: Rand) -> Node | None:
        """The child to descend to (created if new), or None when ``node`` is a leaf."""

    def choose(self, root: Node, rand: Rand) -> int:
        """The move to play once the simulations are spent."""


class Evaluator(Protocol):
    def evaluate(self, node: Node, rand: Rand) -> float:
        """The leaf's value in [0, 1] for ``node.mover``; may expand the node (set ``moves`` / ``priors``)."""


def run_search(root: Node, simulations: int, rand: Rand, policy: TreePolicy, evaluator: Evaluator) -> None:
    """``simulations`` times: descend with ``policy`` until a leaf or a new node, evaluate it, back the value up."""
    child_of, evaluate = policy.child, evaluator.evaluate
    for _ in range(simulations):
        node, path = root, [root]
        while True:
            child = child_of(node, rand)
            if child is None:
                break
            path.append(child)
            node = child
            if child.visits == 0:
                break
        value = evaluate(node, rand)
        mover = node.mover
        for visited in path:  # two sides: what the leaf's mover gains, the other side loses
            visited.visits += 1
            visited.value += value if visited.mover == mover else 1.0 - value


def result_value(result: int, mover: int) -> float:
    """A finished game's value for ``mover``: 1 won, 0.5 drawn, 0 lost."""
    return 1.0 if result == mover else 0.5 if result == DRAW else 0.0


class RandomRollout:
    """Scores a leaf by one uniformly random playout to the end of the game (the result itself if it is over)."""

    def __init__(self, engine) -> None:
        self.engine = engine

    def evaluate(self, node: Node, rand: Rand) -> float:
        result = self.engine.rollout(node.pos, rand)
        return 1.0 if result == node.mover else 0.5 if result == DRAW else 0.0  # result_value, inlined: hot


class UCT:
    """UCB1 over fully expanded nodes; a node with untried moves (``Node.moves``) expands one of them at random."""

    def __init__(self, engine, exploration: float) -> None:
        self.engine, self.exploration = engine, exploration

    def root(self, pos: tuple, moves: list[int]) -> Node:
        return Node(pos, -1, -1, list(moves))

    def child(self, node: Node, rand: Rand) -> Node | None:
        untried = node.moves
        if untried:
            i = int(rand() * len(untried))
            untried[i], untried[-1] = untried[-1], untried[i]
            move = untried.pop()
            engine = self.engine
            pos = engine.play(node.pos, move)
            child = Node(pos, move, engine.turn(node.pos), engine.moves(pos))
            node.children.append(child)
            return child
        if not node.children:
            return None
        log_parent, exploration = math.log(node.visits), self.exploration
        best, best_score = None, -1.0
        for child in node.children:
            score = child.value / child.visits + exploration * math.sqrt(log_parent / child.visits)
            if score > best_score:
                best, best_score = child, score
        return best

    def choose(self, root: Node, rand: Rand) -> int:
        """The most visited root move (ties: uniformly at random)."""
        most = max(child.visits for child in root.children)
        tied = sorted(child.move for child in root.children if child.visits == most)
        return tied[int(rand() * len(tied))]


class PUCT:
    """AlphaZero-style selection: value + ``c_puct`` * prior * sqrt(parent visits) / (1 + visits); an unvisited
    child counts as value 0.5. Children are created when first selected; a node without ``moves`` is a leaf."""

    def __init__(self, engine, c_puct: float, expand: Callable[[Node], bool] | None = None) -> None:
        """``expand``: expands a visited node the first time the search descends from it (sets ``moves`` and
        ``priors``; False for a finished game), for evaluators that score a leaf without expanding it: three leaves
        in four are visited once, so their priors are never read (the same search, a quarter of the prior reads)."""
        self.engine, self.c_puct, self.expand = engine, c_puct, expand

    def child(self, node: Node, rand: Rand) -> Node | None:
        if node.moves is None and (self.expand is None or not self.expand(node)):
            return None  # a leaf: not expanded yet (expand at evaluation), or its game is over
        sqrt_parent = math.sqrt(max(1, node.visits))
        c_puct, children = self.c_puct, node.children
        if not children:
            children.extend([None] * len(node.moves))
        best_score, best = -1.0, -1
        for i, (child, prior) in enumerate(zip(children, node.priors)):
            if child is None or child.visits == 0:
                score = 0.5 + c_puct * prior * sqrt_parent
            else:
                score = child.value / child.visits + c_puct * prior * sqrt_parent / (1 + child.visits)
            if score > best_score:
                best_score, best = score, i
        child = children[best]
        if child is None:
            move = node.moves[best]
            child = Node(self.engine.play(node.pos, move), move, self.engine.turn(node.pos))
            children[best] = child
        return child

    def choose(self, root: Node, rand: Rand) -> int:
        """The most visited root move; ties go to the higher prior, then uniformly at random."""
        visits = visits_by_move(root)
        prior = dict(zip(root.moves, root.priors))
        best = max(visits.values())
        tied = sorted(m for m, v in visits.items() if v == best)
        top_prior = max(prior[m] for m in tied)
        tied = [m for m in tied if prior[m] == top_prior]
        return tied[int(rand() * len(tied))]


def visits_by_move(root: Node) -> dict[int, int]:
    """Visit count of every root move that has a child (in creation order for UCT, move order for PUCT)."""
    return {child.move: child.visits for child in root.children if child is not None}
