"""``taken_squares="misread"``: the robot's knowledge of the board can be wrong (the paper's "not taken yet (to the
robot's knowledge)"), as a believed board kept beside the true one; ``"offered"``: the same, and every square the robot
knows is taken is offered too (refused at -5 with a re-read).

Why a part of its own: the reading is one option of ``ncbot.envs.dialogue_env.DialogueGameEnv``, used only by the
paper configs; its four steps (offer from the belief, play the robot's accepted moves on it, read the user's moves
with seeded misreads, re-read the sheet after a refusal) work on the true board, the belief and the step tables, all
handed to it when the env is built. docs/env.md "Readings" says what is believed and what is true.
"""
from __future__ import annotations

from typing import Any

import torch

from ncbot.envs.core import REWARD_ILLEGAL, ROBOT, USER
from ncbot.envs.dialogue_tables import StepTables
from ncbot.envs.engine.base import Boards
from ncbot.envs.engine.tables import uniform_choice

BOARDS_FIELDS = ("board", "codes", "owners", "last_move", "n_marks", "move_order", "outcome")


class BelievedBoard:
    """The robot's believed board (``belief``) beside the true one (``boards``); see the module docstring."""

    def __init__(self, engine: Any, tables: StepTables, boards: Boards, misread_rate: float,
                 generator: torch.Generator, offer_taken: bool = False) -> None:
        self.engine, self.tables, self.boards, self.misread_rate = engine, tables, boards, misread_rate
        self.offer_taken = offer_taken  # "offered": the squares known taken are offered too
        self.generator = generator
        self.belief = engine.new(boards.board.shape[0])
        self.cells = engine.cells

    def refresh(self, context: torch.Tensor, dialogue_mask: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """What the step accepts and pays from the true board, what the robot is offered and observes
        (``action_mask``, ``lookahead_reward``, ``winning_actions``) from its believed board: (legal, mask, look-ahead,
        true look-ahead, winning moves or None).

        ``legal`` / true look-ahead: the true board's legal acts and one-step rewards (the reward of an accepted act,
        -5 for a refused one); ``mask`` / look-ahead: the same read off the belief. The believed board never decides
        the game (its ``outcome`` is the true one), so its offered squares are its empty (Ultimate: and reachable)
        squares while the true game goes on. Where the belief is the truth (no misread outstanding) both views are
        equal and the true look-ahead is not computed twice.
        """
        cells, boards, belief, tables = self.cells, self.boards, self.belief, self.tables
        belief.outcome = boards.outcome.clone()
        if tables.code_legal is not None:  # one row gather per question, for each board
            code, believed_code = boards.codes[:, 0], belief.codes[:, 0]
            legal = dialogue_mask & tables.code_legal.index_select(0, code)
            true_lookahead = torch.where(legal, tables.code_rewards.index_select(0, code), REWARD_ILLEGAL)
            mask = dialogue_mask & tables.code_empty.index_select(0, believed_code)
            mask[:, :cells] &= (boards.outcome == 0).unsqueeze(1)
            lookahead = torch.where(mask, tables.code_rewards.index_select(0, believed_code), REWARD_ILLEGAL)
            return legal, self._offered(mask, dialogue_mask), lookahead, true_lookahead, None
        moves = dialogue_mask[:, 0]
        can_move = moves & (boards.outcome == 0)
        talk = dialogue_mask[:, cells:]
        legal = torch.cat([self.engine.legal(boards, moves), talk], dim=1)
        mask = torch.cat([self.engine.legal(belief, moves), talk], dim=1)
        lookahead = tables.act_lookahead.index_select(0, context)
        winning = torch.zeros_like(mask)
        if bool(can_move.any()):
            self.engine.write_move_rewards(lookahead, belief, ROBOT, can_move, winning)
        differs = (belief.board != boards.board).any(1)  # a misread is outstanding (else belief == truth)
        true_lookahead = lookahead
        if bool((differs & can_move).any()):
            true_lookahead = torch.where(differs.unsqueeze(1), tables.act_lookahead.index_select(0, context), lookahead)
            self.engine.write_move_rewards(true_lookahead, boards, ROBOT, can_move & differs)
        return legal, self._offered(mask, dialogue_mask), lookahead, true_lookahead, winning

    def _offered(self, mask: torch.Tensor, dialogue_mask: torch.Tensor) -> torch.Tensor:
        """``offered``: the squares known taken too, on the robot's turn (their look-ahead is -5)."""
        if not self.offer_taken:
            return mask
        cells = self.cells
        mask = mask.clone()
        mask[:, :cells] |= (self.belief.board != 0) & dialogue_mask[:, :cells] & (self.boards.outcome == 0).unsqueeze(1)
        return mask

    def believe_robot_moves(self, action: torch.Tensor, robot_moves: torch.Tensor) -> torch.Tensor:
        """The robot's accepted moves on its believed board too; (B,) bool the games to re-read (the square
        was taken on the believed board: only a policy choosing outside ``action_mask`` gets there)."""
        belief = self.belief
        free = belief.board.gather(1, action.clamp(0, self.cells - 1).unsqueeze(1)).squeeze(1) == 0
        self.engine.play(belief, action, ROBOT, robot_moves & free)
        return robot_moves & ~free

    def read_user_moves(self, cells: torch.Tensor, user_moves: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """The user's moves ``cells`` (B,) as the robot reads them, played on its believed board.

        With probability ``misread_rate`` per user move (one draw per game from the env's generator) the robot
        believes the user marked another square, uniform among the squares empty and legal for the user on the
        believed board other than the true one (none: it reads correctly). Returns the squares read (B,), the games
        to re-read (B,) bool (the true square was already marked on the believed board: an earlier misread put a
        mark there, so the read cannot be placed and the robot looks at the sheet again) and the games misread (B,).
        """
        belief = self.belief
        belief.outcome = self.boards.outcome.clone()  # the believed board never ends the game (see refresh)
        slip = user_moves & (torch.rand(user_moves.shape, generator=self.generator) < self.misread_rate)
        column = cells.clamp(0, self.cells - 1).unsqueeze(1)
        if self.tables.code_legal is not None:  # the believed empty squares (a believed line does not stop the game)
            candidates = self.engine.empty_rows_by_code().index_select(0, belief.codes[:, 0])
        else:
            candidates = self.engine.legal(belief)
        candidates = candidates & slip.unsqueeze(1)
        candidates.scatter_(1, column, False)
        slip = slip & candidates.any(1)
        read = torch.where(slip, uniform_choice(candidates, self.generator), cells)
        conflict = user_moves & (belief.board.gather(1, read.clamp(0, self.cells - 1).unsqueeze(1)).squeeze(1) != 0)
        self.engine.play(belief, read, USER, user_moves & ~conflict)
        return read, conflict, slip & ~conflict

    def reread(self, rows: torch.Tensor) -> None:
        """The believed board of the games ``rows`` (B,) bool becomes the true board (every field)."""
        if not bool(rows.any()):
            return
        belief, boards = self.belief, self.boards
        for name in BOARDS_FIELDS:
            true, believed = getattr(boards, name), getattr(belief, name)
            keep = rows.view(-1, *([1] * (true.dim() - 1)))
            setattr(belief, name, torch.where(keep, true, believed))
