"""Self-play training: the simulated user's game moves come from frozen past versions of the agent itself.

Why a pool of snapshots, not the live network: an opponent that changes with every update makes the MDP the
learner sees non-stationary within one replay buffer; frozen snapshots taken every ``snapshot_every_frames``
change it slowly, and sampling among several of them (plus a share of the paper's uniformly random user) keeps
the agent from over-fitting to its own latest habits.

The sign of the target. The paper keeps the opponent inside the env: every stored transition is a ROBOT decision
(s, a, r, s'), where s' is the robot's next decision point AFTER the user (here: a snapshot) replied. From the
robot's point of view the snapshot is just part of the env's dynamics, so the target stays
``y = r + gamma * max_a' Q_target(s', a')`` with r the robot's reward; no negation is needed. A negamax target
(``r - gamma * max Q(s')``) would be right only if opponent moves were stored as transitions of the same learner
in alternating perspectives, which this set-up never does. The perspective flip happens in the opponent's INPUT
instead: a snapshot reads the board with its own marks on the "robot" planes (``TurnFeatures.batch``), as the agent
learnt to see its own moves, so every snapshot plays to win for the user's side.

Each snapshot move: the paper's one-step masks with the exact rules (take a winning cell; never a cell after
which the robot wins at once, unless every cell is such), then the best Q-value, with ``epsilon`` random moves.
Wired into a run by the ``selfplay`` config section (see ``SelfPlayConfig``) as the env's opponent and the ``SelfPlay``
hook; snapshots live in memory, so a resumed run restarts its pool from the resumed weights.
"""
from __future__ import annotations

import copy
import torch
from torch import nn

from ncbot.envs.opponents.base import Opponent
from ncbot.modules.policies.deep_lookahead import win_in_one
from ncbot.modules.search.guided_mcts import TurnFeatures
from ncbot.pipelines.config import SelfPlayConfig
from ncbot.pipelines.train.hooks import TrainingHook


class SnapshotPool(Opponent):
    """The env's opponent in self-play: each user move is made by a uniformly chosen frozen snapshot (or random)."""

    name = "selfplay"

    def __init__(self, game: str, free_move: str, temporal: bool, settings: SelfPlayConfig, seed: int = 0,
                 threats: bool = False) -> None:
        super().__init__(game, free_move, seed)
        self.settings = settings
        self.features = TurnFeatures(game, temporal, free_move, threats)
        self.engine = self.rules.search_engine()
        self.snapshots: list[nn.Module] = []
        self.added = 0
        self._next_frames = 0

    def add(self, qnet: nn.Module) -> None:
        """Freeze a copy of ``qnet`` (a TensorDictModule or a plain module) into the pool."""
        self.features.check_reads(getattr(qnet, "module", qnet))
        module = copy.deepcopy(getattr(qnet, "module", qnet)).eval().cpu()  # the user's moves are made in the CPU env
        for parameter in module.parameters():
            parameter.requires_grad_(False)
        self.snapshots.append(module)
        self.snapshots = self.snapshots[-self.settings.pool_size:]
        self.added += 1

    def maybe_add(self, qnet: nn.Module, frames: int) -> bool:
        """Snapshot ``qnet`` when ``frames`` reached the next snapshot point (the first call always does)."""
        if frames < self._next_frames and self.snapshots:
            return False
        self.add(qnet)
        every = self.settings.snapshot_every_frames
        self._next_frames = (frames // every + 1) * every
        return True

    @torch.no_grad()
    def _select(self, boards, last_move, legal, player, generator, owners):
        rows = boards.shape[0]
        noise = torch.rand(legal.shape, generator=generator)
        random_cells = (noise + legal).argmax(1)  # uniform among legal cells
        if not self.snapshots:
            return random_cells
        draw = torch.rand(rows, generator=generator)
        who = torch.randint(0, len(self.snapshots), (rows,), generator=generator)
        by_snapshot = draw >= self.settings.random_share
        explore = torch.rand(rows, generator=generator) < self.settings.epsilon
        features = self.features.batch(boards, player, last_move)
        q = torch.full(legal.shape, float("-inf"))
        for index, snapshot in enumerate(self.snapshots):
            mine = (by_snapshot & (who == index)).nonzero().flatten()
            if mine.numel():
                q[mine] = snapshot(features[mine])[:, :self.n_cells]
        q = q.masked_fill(~legal, float("-inf"))
        allowed = self._one_step_masks(boards, last_move, legal, player, owners, by_snapshot & ~explore)
        chosen = (q.masked_fill(~allowed, float("-inf")) + noise * 1e-6).argmax(1)
        return torch.where(by_snapshot & ~explore, chosen, random_cells)

    def _one_step_masks(self, boards, last_move, legal, player, owners, rows_mask) -> torch.Tensor:
        """Algorithm 2 on game moves, exact (bitboards): the winning cells if any, else those that do not lose at once."""
        allowed = legal.clone()
        board_rows, legal_rows = boards.tolist(), legal.tolist()
        owner_rows = owners.tolist() if owners is not None else None
        for row in rows_mask.nonzero().flatten().tolist():
            moves = [c for c, ok in enumerate(legal_rows[row]) if ok]
            if len(moves) < 2:
                continue
            pos = self.engine.from_board(board_rows[row], player, int(last_move[row]),
                                         owner_rows[row] if owner_rows else None)
            turn = self.engine.turn(pos)
            after = {m: self.engine.play(pos, m) for m in moves}
            keep = [m for m in moves if self.engine.result(after[m]) == turn]
            keep = keep or [m for m in moves if not win_in_one(self.engine, after[m])] or moves
            allowed[row] = False
            allowed[row, keep] = True
        return allowed


class SelfPlay(TrainingHook):
    """The run's side of self-play: the pool snapshots the learning network at the start (the starting or the
    resumed weights, before the first game is dealt) and every ``snapshot_every_frames``; the report says how many."""

    def __init__(self, pool: SnapshotPool) -> None:
        self.pool = pool

    def on_training_start(self, loop) -> None:
        self.pool.maybe_add(loop.parts.qnet, loop.counters["frames"])

    def on_collected(self, loop, batch) -> None:
        self.pool.maybe_add(loop.parts.qnet, loop.counters["frames"])

    def on_training_end(self, loop, report: dict) -> None:
        report["selfplay"] = {"snapshots_taken": self.pool.added, "snapshots_held": len(self.pool.snapshots)}


__all__ = ["SelfPlay", "SelfPlayConfig", "SnapshotPool"]
