"""The dialogue env's ears, batched: which of the env's words the robot hears for each game's user utterance,
with what confidence, and which example utterance it understands them as.

Why here and not in ``envs``: ``speech`` sits above ``envs`` (it reads the example dialogues), so the env takes a
hearing object from the caller (pipelines builds it from the config), as it takes an opponent object.
``ChannelHearing`` samples the fitted channel model (training); the robot's game loop hears with the real
recogniser instead and turns its words into the same three tensors with ``heard_tensors``.
"""
from __future__ import annotations

from collections.abc import Sequence

import torch

from speech.asr import Heard
from speech.channel import ChannelModel
from speech.understand import closest_utterance, utterance_table


class ChannelHearing:
    """Hears a batch of the env's utterance ids through ``model`` at an SNR drawn per utterance, uniformly in
    ``snr_db`` (low, high) dB (None = clean), in ``kind`` noise."""

    def __init__(
        self, model: ChannelModel, utterance_texts: Sequence[str], env_words: Sequence[str],
        snr_db: tuple[float, float] | None = (10.0, 30.0), kind: str = "babble",
    ) -> None:
        from envs.dialogue import tokenize

        if kind not in model.kinds:
            raise ValueError(f"noise kind {kind!r} is not in the channel model; kinds: {', '.join(model.kinds)}")
        if snr_db is not None and not (len(snr_db) == 2 and snr_db[0] <= snr_db[1]):
            raise ValueError(f"snr_db must be (low, high) with low <= high, or None for clean; got {snr_db!r}")
        self.model, self.kind, self.snr_db = model, kind, snr_db
        texts = [" ".join(tokenize(t)) for t in utterance_texts]
        # said word ids per env utterance; one more row (all padding) for silence, the env's utterance id U
        if not texts:
            raise ValueError("the env has no user utterances to hear")
        said = model.encode(texts)
        self._said = torch.cat([said, torch.full((1, said.shape[1]), len(model.words))])
        column = {w: i for i, w in enumerate(env_words)}
        # channel word id -> env word column (len(env_words) = not an env word, or nothing heard)
        self._column = torch.tensor([column.get(w, len(env_words)) for w in model.words] + [len(env_words)])
        self._table = utterance_table(texts, env_words)
        self.n_env_words = len(env_words)

    def hear(
        self, utterance: torch.Tensor, generator: torch.Generator | None = None, snr_db: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """For utterance ids (B,) (U = silence): env word columns (B, H) (``n_env_words`` = nothing), their
        confidences (B, H) float32 (0 for nothing) and the utterance understood (B,) (-1 = heard as silence)."""
        said = self._said.index_select(0, utterance)
        if snr_db is None:
            if self.snr_db is None:
                snr_db = torch.full(utterance.shape, float("inf"))
            else:
                low, high = self.snr_db
                snr_db = low + (high - low) * torch.rand(utterance.shape, generator=generator)
        heard, confidence = self.model.sample(said, snr_db, self.kind, generator)
        columns = self._column.index_select(0, heard.reshape(-1)).reshape(heard.shape)
        confidence = torch.where(columns < self.n_env_words, confidence, torch.zeros(()))
        return columns, confidence, closest_utterance(columns, confidence, self._table)


def heard_tensors(heard: Heard, utterance_texts: Sequence[str], env_words: Sequence[str]) -> tuple[
        torch.Tensor, torch.Tensor, torch.Tensor]:
    """The real recogniser's result for one game as ``ChannelHearing.hear``'s (1, H), (1, H), (1,) tensors."""
    from envs.dialogue import tokenize

    column = {w: i for i, w in enumerate(env_words)}
    columns = torch.tensor([[column.get(w, len(env_words)) for w in heard.words] or [len(env_words)]])
    confidence = torch.tensor([list(heard.confidences) or [0.0]], dtype=torch.float32)
    confidence = torch.where(columns < len(env_words), confidence, torch.zeros(()))
    table = utterance_table([" ".join(tokenize(t)) for t in utterance_texts], env_words)
    return columns, confidence, closest_utterance(columns, confidence, table)
