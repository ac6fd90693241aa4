"""The simulated user's half of a dialogue step: what its utterance is heard as, how it replies, which square it takes.

Why a part of its own: the step (``ncbot.envs.dialogue_env.DialogueGameEnv._step``) is the robot's act, the user's
answer and the bookkeeping; the user's answer reads the dialogue model, the step tables, the engine and the env's
seeded generator, all handed to it when the env is built, and the boards it is asked about.
"""
from __future__ import annotations

from typing import Any

import torch

from ncbot.envs.core import USER
from ncbot.envs.dialogue_tables import StepTables, reply_tables
from ncbot.envs.engine.base import Boards


class SimulatedUser:
    """The user of the dialogue env: the replies learnt from the example dialogues, its ears (``hearing``) and its
    move policy (``opponent``: None for uniform among the legal squares).

    ``model`` may be replaced or edited in place while the env runs (``ncbot play`` makes the user say what a
    person typed): the reply tables are rebuilt when its tensors change."""

    def __init__(self, model: Any, tables: StepTables, engine: Any, opponent: Any, opponent_keywords: set[str],
                 hearing: Any, generator: torch.Generator, subgrids: int) -> None:
        self.model, self.tables, self.engine = model, tables, engine
        self.opponent, self.opponent_keywords, self.hearing = opponent, opponent_keywords, hearing
        self.generator, self.subgrids = generator, subgrids
        self._reply_key: tuple | None = None  # what reply_tables last derived its tables from
        self._replies: tuple[torch.Tensor, torch.Tensor] | None = None

    def heard(self, utterance: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """What ``hearing`` makes of the user's utterances (B,): the act understood (B,) (-1 silence), the heard
        words' feature columns (B, H) (the padding column for nothing) and their confidences (B, H)."""
        words, confidence, understood = self.hearing.hear(utterance, self.generator)
        n_words = len(self.model.words)
        if words.dim() != 2 or words.shape != confidence.shape or understood.shape != utterance.shape:
            raise ValueError(f"hearing {self.hearing!r} returned malformed shapes {tuple(words.shape)}, "
                             f"{tuple(confidence.shape)}, {tuple(understood.shape)} for {tuple(utterance.shape)} utterances")
        columns = words.long().clamp(0, n_words) + self.model.template_commands.shape[1]
        understood = torch.where(understood >= 0, understood, self.tables.silence)
        return self.tables.utterance_acts.index_select(0, understood), columns, confidence.float()

    def reply_tables(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The reply tables (``ncbot.envs.dialogue_tables.reply_tables``) of the current ``model``."""
        options, counts = self.model.reply_options, self.model.reply_counts
        key = (options, counts, options._version, counts._version)  # holds the tensors: identity checks stay valid
        last = self._reply_key
        if last is None or last[0] is not options or last[1] is not counts or last[2:] != key[2:]:
            self._reply_key = key
            tables = self.tables
            self._replies = reply_tables(self.model, tables.silence, tables.utterance_is_move, tables.user_turn)
        return self._replies

    def cells(self, boards: Boards, rows: torch.Tensor) -> torch.Tensor:
        """(B,) the user's square in ``rows`` (other rows: meaningless): uniform among legal ones, or the opponent's."""
        if self.opponent is None:
            # picks outside ``rows`` are discarded by the caller; each row draws one number either way, so
            # leaving the other rows unmasked changes neither the moves nor the random stream (one op less)
            return self.engine.random_legal(boards, self.generator)
        legal = self.engine.legal(boards) & rows.unsqueeze(1)
        index = rows.nonzero().squeeze(1)
        kwargs: dict[str, Any] = {"rows": index} if "rows" in self.opponent_keywords else {}
        if "owners" in self.opponent_keywords and self.subgrids:
            kwargs["owners"] = boards.owners[index].to(torch.int8)
        chosen = torch.as_tensor(
            self.opponent.select(boards.board[index], boards.last_move[index], legal[index], USER, self.generator, **kwargs)
        ).reshape(-1).long()
        cells = legal.shape[1]
        if chosen.shape[0] != index.shape[0] or not bool(legal[index].gather(1, chosen.clamp(0, cells - 1).unsqueeze(1)).all()):
            raise ValueError(f"opponent {self.opponent!r} returned an illegal or malformed move {chosen.tolist()}")
        out = torch.zeros(rows.shape[0], dtype=torch.int64)
        out[index] = chosen
        return out
