"""A model of how one person plays, fitted to their logged moves: the simulated opponent play learns against.

Why: a few dozen games are far too few transitions to learn a new way of playing from them alone, but they are
plenty to see how a person chooses: whether they take a winning square, block the robot's, make a fork, play as well
as exact play would, prefer some squares. The model scores every legal square by those features (takes a game-winning
square, blocks the robot's, makes a fork, takes the square the robot would fork from, is among the best squares by
exact play, which square it is) and picks by a softmax; its weights are the maximum-likelihood fit to the person's
moves with an L2 pull towards zero, which is the uniformly random user the agent was trained against. So with no
games it is that user, and with each game it plays more like the person; the agent then learns against it in
simulation (`ncbot.pipelines.online.play_learner`), as much as the per-game compute allows.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from ncbot.envs.games import Game, make_game
from ncbot.envs.opponents.base import Opponent

ROBOT, PERSON = 1, 2  # board codes as the env writes them


@dataclass
class PersonMove:
    """One move the person made: the board before it (env codes), the legal squares, and the square chosen."""

    board: torch.Tensor   # int8 (cells,)
    legal: torch.Tensor   # bool (cells,)
    cell: int


N_TACTICS = 5  # the features before the one-hot square: wins, blocks, forks, blocks a fork, best by exact play


def move_features(rules: Game, boards: torch.Tensor) -> torch.Tensor:
    """(B, cells, 5 + cells) float: does the square win the game for the person now, does it block the robot's win,
    does it make a fork for the person, is it the square the robot would fork from, is it among the best squares by
    exact play (the game's solver; never on a game without one), and which square it is (one-hot).
    `rules`: the game object (``ncbot.envs.games``), whatever the game."""
    wins, blocks = rules.winning_cells(boards, PERSON), rules.winning_cells(boards, ROBOT)
    forks, robot_forks = fork_cells(rules, boards, PERSON), fork_cells(rules, boards, ROBOT)
    batch, cells = boards.shape
    solver = rules.solver()
    best = torch.zeros(batch, cells, dtype=torch.bool) if solver is None else solver.optimal_cells(boards, PERSON)
    where = torch.eye(cells).expand(batch, cells, cells)
    tactics = torch.stack([wins, blocks, forks, robot_forks, best], dim=-1).float()
    return torch.cat([tactics, where], dim=-1)


def fork_cells(rules: Game, boards: torch.Tensor, player: int) -> torch.Tensor:
    """(B, cells) bool: the empty cells after which ``player`` has two or more cells that win at once (a fork: one
    mark cannot block both). Why a feature: a perfect player beats a weaker one by forks, which the win and block
    features cannot tell from any other square."""
    batch, cells = boards.shape
    empty = boards == 0
    after = boards[:, None, :].repeat(1, cells, 1)   # (B, cells taken, cells)
    diagonal = torch.arange(cells)
    after[:, diagonal, diagonal] = torch.where(empty, player, after[:, diagonal, diagonal])
    threats = rules.winning_cells(after.reshape(batch * cells, cells), player).reshape(batch, cells, cells)
    return empty & (threats.sum(dim=-1) >= 2)


class PersonModel(Opponent):
    """The fitted person as an env opponent (batched): a softmax over the legal squares' feature scores."""

    name = "person-model"

    def __init__(self, game: str = "standard", free_move: str = "anywhere", seed: int = 0, l2: float = 1.0) -> None:
        super().__init__(game, free_move, seed)
        self.l2 = float(l2)
        self.weights = torch.zeros(N_TACTICS + self.n_cells)  # zero: the uniformly random user

    def logits(self, boards: torch.Tensor, legal: torch.Tensor) -> torch.Tensor:
        scores = move_features(self.rules, boards) @ self.weights
        return scores.masked_fill(~legal, float("-inf"))

    def _select(self, boards, last_move, legal, player, generator, owners):
        if player != PERSON:  # the model is of the person's seat; boards are read from it
            raise ValueError("the person model plays the user's seat (board code 2)")
        probabilities = torch.softmax(self.logits(boards.long(), legal), dim=1).nan_to_num(0.0)
        empty = ~legal.any(dim=1)
        probabilities[empty, 0] = 1.0
        return torch.multinomial(probabilities, 1, generator=generator).squeeze(1)

    def fit(self, moves: list[PersonMove], steps: int = 100) -> float:
        """Maximum likelihood of `moves` with the L2 pull to uniform (full-batch L-BFGS from the current weights);
        returns the mean log-likelihood per move (log 1/|legal| for the uniform user)."""
        if not moves:
            return 0.0
        boards = torch.stack([move.board.long() for move in moves])
        legal = torch.stack([move.legal for move in moves])
        chosen = torch.tensor([move.cell for move in moves])
        features = move_features(self.rules, boards)
        weights = self.weights.clone().requires_grad_(True)
        optimiser = torch.optim.LBFGS([weights], max_iter=steps, line_search_fn="strong_wolfe")

        def loss() -> torch.Tensor:
            optimiser.zero_grad()
            logits = (features @ weights).masked_fill(~legal, float("-inf"))
            value = torch.nn.functional.cross_entropy(logits, chosen, reduction="sum") + self.l2 * weights.pow(2).sum()
            value.backward()
            return value

        with torch.enable_grad():
            optimiser.step(loss)
        self.weights = weights.detach()
        return self.log_likelihood(moves)

    def log_likelihood(self, moves: list[PersonMove]) -> float:
        """Mean log-probability the model gives the squares the person chose."""
        boards = torch.stack([move.board.long() for move in moves])
        legal = torch.stack([move.legal for move in moves])
        chosen = torch.tensor([move.cell for move in moves])
        return float(torch.log_softmax(self.logits(boards, legal), dim=1).gather(1, chosen[:, None]).mean())


def person_moves(moves: list[tuple[int, int]], robot_first: bool, game: str, free_move: str) -> list[PersonMove]:
    """The person's moves of one game, each with the board before it and its legal squares, from the game's
    (cell, player) moves in order (player 1 the robot, 2 the person), replayed with the game's rules."""
    rules = make_game(game, free_move)
    state = rules.new()
    robot_mark = 1 if robot_first else 2  # the rules' marks: 1 moves first
    found = []
    for cell, player in moves:
        if player == PERSON:
            board = torch.tensor([0 if v == 0 else (ROBOT if v == robot_mark else PERSON) for v in state.board],
                                 dtype=torch.int8)
            legal = torch.zeros(len(state.board), dtype=torch.bool)
            legal[list(rules.legal(state))] = True
            found.append(PersonMove(board, legal, int(cell)))
        try:
            state = rules.play(state, int(cell))
        except ValueError:  # a claimed move the rules refuse (a person who lied): the rest cannot be replayed
            break
    return found
