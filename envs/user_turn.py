"""The simulated user's half of a dialogue step, as methods of the dialogue env: what the user's utterance is heard
as, how the user replies, and which square the user takes on its turn.

Why a mixin of its own: the step (``ncbot.envs.dialogue_env.DialogueGameEnv._step``) is the robot's act, the user's
answer and the bookkeeping; the user's answer reads the env's state (``self.model``, ``self.boards``, the seeded
``self._rng``) and options (``hearing``, ``opponent``) and nothing else, so it lives here beside the believed-board
mixin (``ncbot.envs.misread``).
"""
from __future__ import annotations

from typing import Any

import torch

from ncbot.envs.core import USER
from ncbot.envs.dialogue_tables import reply_tables


class SimulatedUserTurn:
    """The simulated user's half of ``DialogueGameEnv``'s step; see the module docstring."""

    def _heard(self, utterance: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """What ``self.hearing`` makes of the user's utterances (B,): the act understood (B,) (-1 silence),
        the heard words' feature columns (B, H) (the padding column for nothing) and their confidences (B, H)."""
        words, confidence, understood = self.hearing.hear(utterance, self._rng)
        n_words = len(self.model.words)
        if words.dim() != 2 or words.shape != confidence.shape or understood.shape != utterance.shape:
            raise ValueError(f"hearing {self.hearing!r} returned malformed shapes {tuple(words.shape)}, "
                             f"{tuple(confidence.shape)}, {tuple(understood.shape)} for {tuple(utterance.shape)} utterances")
        columns = words.long().clamp(0, n_words) + self.model.template_commands.shape[1]
        understood = torch.where(understood >= 0, understood, self._silence)
        return self._utterance_acts.index_select(0, understood), columns, confidence.float()

    def _reply_tables(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The simulated user's reply tables (``ncbot.envs.dialogue_tables.reply_tables``), read each step from
        ``self.model``: ``ncbot play`` swaps in or edits its tables to make the user say what a person typed,
        so they are rebuilt when the model's tensors change."""
        options, counts = self.model.reply_options, self.model.reply_counts
        key = (options, counts, options._version, counts._version)  # holds the tensors: identity checks stay valid
        last = self._reply_key
        if last is None or last[0] is not options or last[1] is not counts or last[2:] != key[2:]:
            self._reply_key = key
            self._replies = reply_tables(self.model, self._silence, self._utterance_is_move, self._user_turn)
        return self._replies

    def _user_cells(self, rows: torch.Tensor) -> torch.Tensor:
        """(B,) the user's square in ``rows`` (other rows: meaningless): uniform among legal ones, or the opponent's choice."""
        if self.opponent is None:
            # picks outside ``rows`` are discarded by the caller; each row draws one number either way, so
            # leaving the other rows unmasked changes neither the moves nor the random stream (one op less)
            return self.engine.random_legal(self.boards, self._rng)
        legal = self.engine.legal(self.boards) & rows.unsqueeze(1)
        index = rows.nonzero().squeeze(1)
        boards = self.boards
        kwargs: dict[str, Any] = {"rows": index} if "rows" in self._opponent_params else {}
        if "owners" in self._opponent_params and self.game == "ultimate":
            kwargs["owners"] = boards.owners[index].to(torch.int8)
        chosen = torch.as_tensor(
            self.opponent.select(boards.board[index], boards.last_move[index], legal[index], USER, self._rng, **kwargs)
        ).reshape(-1).long()
        if chosen.shape[0] != index.shape[0] or not bool(legal[index].gather(1, chosen.clamp(0, self.cells - 1).unsqueeze(1)).all()):
            raise ValueError(f"opponent {self.opponent!r} returned an illegal or malformed move {chosen.tolist()}")
        cells = torch.zeros(rows.shape[0], dtype=torch.int64)
        cells[index] = chosen
        return cells
