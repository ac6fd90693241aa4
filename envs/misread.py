"""``taken_squares="misread"``: the robot's knowledge of the board can be wrong (the paper's "not taken yet (to the
robot's knowledge)"), as the methods of the dialogue env that keep its believed board beside the true one;
``"offered"``: the same, and every square the robot knows is taken is offered too (refused at -5 with a re-read).

Why a mixin of its own: the reading is one option of ``ncbot.envs.dialogue_env.DialogueGameEnv``, used only by the paper
configs; its four steps (offer from the belief, play the robot's accepted moves on it, read the user's moves with
seeded misreads, re-read the sheet after a refusal) read and write the env's state (``self.boards``,
``self.belief``, ``self.d``) and are called from its ``_refresh`` and ``_step``. docs/env.md "Readings" says what
is believed and what is true.
"""
from __future__ import annotations

import torch

from ncbot.envs.core import REWARD_ILLEGAL, ROBOT, USER
from ncbot.envs.dialogue_tables import N_STAGES
from ncbot.envs.engine import uniform_choice


class MisreadBoard:
    """The believed-board half of ``DialogueGameEnv`` (``taken_squares="misread"``); see the module docstring."""

    def _refresh_misread(self) -> None:
        """``taken_squares="misread"``: what the step accepts and pays from the true board, what the robot is
        offered and observes (``action_mask``, ``lookahead_reward``, ``winning_actions``) from its believed board.

        ``d.legal`` / ``d.true_lookahead``: the true board's legal acts and one-step rewards (the reward of an
        accepted act, -5 for a refused one); ``d.mask`` / ``d.lookahead``: the same read off ``self.belief``. The
        believed board never decides the game (its ``outcome`` is the true one), so its offered squares are its
        empty (Ultimate: and reachable) squares while the true game goes on. Where the belief is the truth (no
        misread outstanding) both views are equal and the true look-ahead is not computed twice.
        """
        cells, boards, belief = self.cells, self.boards, self.belief
        belief.outcome = boards.outcome.clone()
        context = self.d.talk * N_STAGES + self._stage(self.d.flags)
        dialogue_mask = self._filter_table.index_select(0, context)
        if self._code_legal is not None:  # 3x3: one row gather per question, for each board
            code, believed_code = boards.codes[:, 0], belief.codes[:, 0]
            legal = dialogue_mask & self._code_legal.index_select(0, code)
            true_lookahead = torch.where(legal, self._code_rewards.index_select(0, code), REWARD_ILLEGAL)
            mask = dialogue_mask & self._code_empty.index_select(0, believed_code)
            mask[:, :cells] &= (boards.outcome == 0).unsqueeze(1)
            lookahead = torch.where(mask, self._code_rewards.index_select(0, believed_code), REWARD_ILLEGAL)
        else:
            moves = dialogue_mask[:, 0]
            can_move = moves & (boards.outcome == 0)
            talk = dialogue_mask[:, cells:]
            legal = torch.cat([self.engine.legal(boards, moves), talk], dim=1)
            mask = torch.cat([self.engine.legal(belief, moves), talk], dim=1)
            lookahead = self._act_lookahead.index_select(0, context)
            winning = torch.zeros_like(mask)
            if bool(can_move.any()):
                self.engine.write_move_rewards(lookahead, belief, ROBOT, can_move, winning)
            self.d.winning_moves = winning
            differs = (belief.board != boards.board).any(1)  # a misread is outstanding (else belief == truth)
            true_lookahead = lookahead
            if bool((differs & can_move).any()):
                true_lookahead = torch.where(differs.unsqueeze(1), self._act_lookahead.index_select(0, context), lookahead)
                self.engine.write_move_rewards(true_lookahead, boards, ROBOT, can_move & differs)
        if self._offer_taken:  # "offered": the squares known taken too, on the robot's turn (their look-ahead is -5)
            mask = mask.clone()
            mask[:, :cells] |= (belief.board != 0) & dialogue_mask[:, :cells] & (boards.outcome == 0).unsqueeze(1)
        self.d.legal, self.d.dialogue_mask, self.d.lookahead, self.d.mask = legal, dialogue_mask, lookahead, mask
        self.d.true_lookahead = true_lookahead

    # ------------------------------------------------------------------ taken_squares="misread"
    def _believe_robot_moves(self, action: torch.Tensor, robot_moves: torch.Tensor) -> torch.Tensor:
        """The robot's accepted moves on its believed board too; (B,) bool the games to re-read (the square
        was taken on the believed board: only a policy choosing outside ``action_mask`` gets there)."""
        belief = self.belief
        free = belief.board.gather(1, action.clamp(0, self.cells - 1).unsqueeze(1)).squeeze(1) == 0
        self.engine.play(belief, action, ROBOT, robot_moves & free)
        return robot_moves & ~free

    def _read_user_moves(self, cells: torch.Tensor, user_moves: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The user's moves ``cells`` (B,) as the robot reads them, played on its believed board.

        With probability ``misread_rate`` per user move (one draw per game from the env's generator) the robot
        believes the user marked another square, uniform among the squares empty and legal for the user on the
        believed board other than the true one (none: it reads correctly). Returns the squares read (B,) and the
        games to re-read (B,) bool: the true square was already marked on the believed board (an earlier misread
        put a mark there), so the read cannot be placed and the robot looks at the sheet again.
        """
        belief = self.belief
        belief.outcome = self.boards.outcome.clone()  # the believed board never ends the game (see _refresh_misread)
        slip = user_moves & (torch.rand(user_moves.shape, generator=self._rng) < self.misread_rate)
        column = cells.clamp(0, self.cells - 1).unsqueeze(1)
        if self._code_legal is not None:  # 3x3: the believed empty squares (a believed line does not stop the game)
            candidates = self.engine.empty_rows_by_code().index_select(0, belief.codes[:, 0])
        else:
            candidates = self.engine.legal(belief)
        candidates = candidates & slip.unsqueeze(1)
        candidates.scatter_(1, column, False)
        slip = slip & candidates.any(1)
        read = torch.where(slip, uniform_choice(candidates, self._rng), cells)
        conflict = user_moves & (belief.board.gather(1, read.clamp(0, self.cells - 1).unsqueeze(1)).squeeze(1) != 0)
        self.engine.play(belief, read, USER, user_moves & ~conflict)
        self.d.misread = slip & ~conflict
        return read, conflict

    def _reread(self, rows: torch.Tensor) -> None:
        """The believed board of the games ``rows`` (B,) bool becomes the true board (every field)."""
        if not bool(rows.any()):
            return
        belief, boards = self.belief, self.boards
        for name in ("board", "codes", "owners", "last_move", "n_marks", "move_order", "outcome"):
            true, believed = getattr(boards, name), getattr(belief, name)
            keep = rows.view(-1, *([1] * (true.dim() - 1)))
            setattr(belief, name, torch.where(keep, true, believed))
