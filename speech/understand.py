"""What the user meant: the example utterance closest to the words heard, weighted by their confidences.

Why: the recogniser (or the channel model) returns words, possibly wrong, missing or extra; the dialogue env
works with the user's utterance ids (each with its act). Closest by a confidence-weighted Jaccard score, so a
confidently heard word counts fully and a doubtful one little; nothing heard (or too little) is silence (-1),
a valid result the robot answers by asking again. Batched: one matrix product for a whole batch of games.
"""
from __future__ import annotations

from collections.abc import Sequence

import torch

MIN_SCORE = 0.25  # below this the best match is no better than a guess: treat as silence


def utterance_table(texts: Sequence[str], words: Sequence[str]) -> torch.Tensor:
    """(U, V) 0/1 float: which of ``words`` each utterance text holds (words outside ``words`` are ignored)."""
    index = {w: i for i, w in enumerate(words)}
    table = torch.zeros(len(texts), len(words))
    for row, text in enumerate(texts):
        for word in text.split():
            if word in index:
                table[row, index[word]] = 1.0
    return table


def closest_utterance(
    heard: torch.Tensor, confidence: torch.Tensor, table: torch.Tensor, min_score: float = MIN_SCORE
) -> torch.Tensor:
    """(B,) utterance id per game (-1 silence) for heard word ids (B, H) (ids >= V mean nothing) with their
    confidences (B, H), over the (U, V) ``table`` of ``utterance_table``."""
    if heard.shape != confidence.shape or heard.dim() != 2:
        raise ValueError(f"heard ids and confidences must both be (B, H), got {tuple(heard.shape)} and {tuple(confidence.shape)}")
    v = table.shape[1]
    bag = torch.zeros(heard.shape[0], v + 1).scatter_reduce_(
        1, heard.clamp(0, v), confidence.float(), "amax"
    )[:, :v]  # each vocabulary word's best confidence (a word heard twice counts once)
    matched = bag @ table.T  # (B, U)
    score = matched / (bag.sum(1, keepdim=True) + table.sum(1) - matched).clamp_min(1e-9)
    best, utterance = score.max(1)
    return torch.where(best >= min_score, utterance, torch.full_like(utterance, -1))


def closest_text(heard_words: Sequence[str], confidences: Sequence[float], texts: Sequence[str]) -> int:
    """One utterance: the index in ``texts`` closest to the heard words (-1 silence). For the robot's game loop."""
    words = sorted({w for text in texts for w in text.split()})
    index = {w: i for i, w in enumerate(words)}
    ids = torch.tensor([[index.get(w, len(words)) for w in heard_words] or [len(words)]])
    conf = torch.tensor([list(confidences) or [0.0]], dtype=torch.float32)
    return int(closest_utterance(ids, conf, utterance_table(texts, words))[0])
