"""Exact evaluation on 3x3: every branch of the random user's game moves, each with its exact probability.

Why: 3000 sampled games can only say "loss rate < 0.1 % at 95 %"; the claim "this agent never loses to the
random user" needs every game the random user can play. On 3x3 the random user picks uniformly among the free
squares and, before its k-th move, always sees the same number of them (8, 6, 4, 2 when the robot starts;
9, 7, 5, 3, 1 when the user starts). So the games are the rows of one mixed-radix table: row r plays, at the
user's k-th move, the d_k-th free square (d_k = the k-th digit of r), and every row has probability exactly
1 / (number of rows). Rows of games that end early share their prefix; the weights still add up exactly.

The robot's side runs unchanged: the env's own `step` with the greedy policy, its dialogue acts and its masks.
The dialogue's own chance (the user's words and their ASR confidences, which enter the observation) is NOT
enumerated: each run draws one realisation per branch from the env seed, and `dialogue_seeds` repeats the whole
enumeration under several realisations (a loss under ANY of them is reported). Positions reachable by `minimax`
(or any other user) are a subset of these, so "no losing branch" also means the agent never loses to minimax
under those dialogue draws.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import torch

from ncbot.pipelines.evaluate.games import OUTCOME_DRAW, OUTCOME_ROBOT_WON, play_games

USER_MARK = 2
CELLS = 9
# free squares the random user chooses among before each of its moves, by who opens
USER_CHOICES = {"robot": (8, 6, 4, 2), "human": (9, 7, 5, 3, 1)}


def branch_digits(radices: tuple[int, ...]) -> torch.Tensor:
    """(prod(radices), len(radices)) int64: row r holds the mixed-radix digits of r (most significant first)."""
    count = math.prod(radices)
    rows = torch.arange(count)
    digits = []
    for position in range(len(radices)):
        below = math.prod(radices[position + 1:])
        digits.append((rows // below) % radices[position])
    return torch.stack(digits, dim=1)


class BranchUser:
    """The random user, unrolled: in batch row r it plays branch r of the user's move tree (see module doc).

    An env opponent (`select` with `rows`): the env passes the rows that move now; the user's move number is
    the count of its marks on the board, so an auto-reset row simply starts its branch again.
    """

    name = "branches"

    def __init__(self, first: str) -> None:
        if first not in USER_CHOICES:
            raise ValueError(f"first must be one of {', '.join(USER_CHOICES)}, got {first!r}")
        self.radices = torch.tensor(USER_CHOICES[first])
        self.digits = branch_digits(USER_CHOICES[first])

    @property
    def branches(self) -> int:
        return self.digits.shape[0]

    def select(self, boards: torch.Tensor, last_move: torch.Tensor, legal: torch.Tensor, player: int,
               generator=None, rows: torch.Tensor | None = None) -> torch.Tensor:
        if rows is None or legal.shape[1] != CELLS:
            raise ValueError("BranchUser plays 3x3 games inside the dialogue env only (it needs the moving rows)")
        move_number = (boards == player).sum(dim=1).long()
        free = legal.sum(dim=1)
        expected = self.radices[move_number.clamp(max=len(self.radices) - 1)]
        if bool((move_number >= len(self.radices)).any()) or not bool((free == expected).all()):
            raise ValueError("BranchUser found a board whose free squares do not match its seat's branch table")
        digit = self.digits[rows, move_number]
        rank = legal.long().cumsum(dim=1) - 1  # rank of each free square among the free ones, in cell order
        return ((rank == digit.unsqueeze(1)) & legal).long().argmax(dim=1)


class MoveRecorder:
    """A `play_games` logger that keeps each row's first game as a move list (robot +cell+1, user -(cell+1))."""

    def __init__(self, rows: int) -> None:
        self.moves = torch.zeros(rows, CELLS, dtype=torch.int64)
        self.count = torch.zeros(rows, dtype=torch.int64)
        self.counting = torch.ones(rows, dtype=torch.bool)

    def _append(self, rows: torch.Tensor, codes: torch.Tensor) -> None:
        index = rows.nonzero().squeeze(1)
        self.moves[index, self.count[index]] = codes[index]
        self.count[index] += 1

    def record_steps(self, td, env=None, **_: Any) -> None:
        action = td.get("action").reshape(-1)
        user_move = td.get(("next", "user_move")).reshape(-1)
        self._append(self.counting & (action < CELLS), action + 1)  # the robot moves first within a step
        self._append(self.counting & (user_move >= 0), -(user_move + 1))
        self.counting &= ~td.get(("next", "done")).reshape(-1)

    def line(self, row: int) -> str:
        """One game as text, e.g. "user b2, robot a1, user c3"."""
        names = []
        for code in self.moves[row, : self.count[row]].tolist():
            cell = abs(code) - 1
            names.append(f"{'robot' if code > 0 else 'user'} {'abc'[cell % 3]}{cell // 3 + 1}")
        return ", ".join(names)


@dataclass
class ExactResult:
    """Exact probabilities over the random user's game moves for one seat (mean over the dialogue draws)."""

    seat: str
    branches: int  # user-move branches per dialogue draw (each has probability 1 / branches)
    dialogue_seeds: list[int]
    win: float
    draw: float
    loss: float  # includes games cut at the action limit
    task_success: float
    worst_loss: float  # the highest loss probability over the dialogue draws
    avg_length: float  # actions per game, exact expectation
    losing_lines: list[str] = field(default_factory=list)  # distinct lost games over all draws

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def enumerable(game: str) -> bool:
    """Whether exact evaluation covers `game`: a board of 3x3 squares, whose random user's branches it enumerates."""
    from ncbot.envs.games import make_game

    return make_game(game).n_cells == CELLS


def exact_seat(config, policy, first: str, dialogue_seeds: list[int]) -> ExactResult:
    """Enumerate every user-move branch with ``first`` (robot | human) opening, under each dialogue draw; see the
    module doc. The result's ``seat`` is the robot's (``run_env.robot_seat``)."""
    from ncbot.modules.networks.recurrent import memory_env
    from ncbot.pipelines.run_env import make_run_env, robot_seat

    if not enumerable(config.env.game):  # the user's choices are then checked move by move (BranchUser)
        raise ValueError(f"exact evaluation enumerates 3x3 games only; this agent plays {config.env.game!r}")
    if not dialogue_seeds:
        raise ValueError("exact evaluation needs at least one dialogue seed")
    wins, draws, losses, lengths, losing = [], [], [], [], []
    user = BranchUser(first)  # stateless: the same branch table under every dialogue draw
    for seed in dialogue_seeds:
        recorder = MoveRecorder(user.branches)

        def make_env(batch_size: int, seed: int = seed, user: BranchUser = user):
            env = make_run_env(config.env, batch_size=batch_size, seed=seed, first=first, opponent=user)
            return memory_env(env, policy)  # agent.memory: each branch's dialogue carries its own hidden state

        records = play_games(make_env, policy, user.branches, logger=recorder)
        outcomes, length = records.outcomes, records.lengths
        lost_games = (outcomes != OUTCOME_ROBOT_WON) & (outcomes != OUTCOME_DRAW)  # unfinished games count as lost
        wins.append(float((outcomes == OUTCOME_ROBOT_WON).double().mean()))
        draws.append(float((outcomes == OUTCOME_DRAW).double().mean()))
        losses.append(float(lost_games.double().mean()))
        lengths.append(float(length.double().mean()))
        losing.extend(recorder.line(row) for row in lost_games.nonzero().squeeze(1).tolist())
    mean = lambda values: sum(values) / len(values)  # noqa: E731
    return ExactResult(seat=robot_seat(first), branches=user.branches, dialogue_seeds=list(dialogue_seeds),
                       win=mean(wins), draw=mean(draws), loss=mean(losses), task_success=mean(wins) + mean(draws),
                       worst_loss=max(losses), avg_length=mean(lengths), losing_lines=sorted(set(losing)))


def exact_checkpoint(checkpoint_path, *, first: str = "alternate", seed: int = 0,
                     dialogue_seeds: int = 8) -> list[ExactResult]:
    """`ncbot eval --exhaustive`: exact results per seat for a saved 3x3 agent; `first` robot | human | alternate
    (both, robot-first then human-first).

    Dialogue draws use env seeds seed, seed + 1, ..., seed + dialogue_seeds - 1.
    """
    from ncbot.pipelines.agents import load_agent

    from ncbot.pipelines.run_env import check_first

    check_first(first)
    if dialogue_seeds < 1:
        raise ValueError(f"--dialogue-seeds must be a positive number of dialogue draws, got {dialogue_seeds}")
    config, policy = load_agent(checkpoint_path)
    seeds = [seed + offset for offset in range(dialogue_seeds)]
    return [exact_seat(config, policy, one, seeds) for one in (("robot", "human") if first == "alternate" else (first,))]
