"""The decision maker when no trained checkpoint is given: the paper's look-ahead filter alone.

Same masks as the trained agent (`modules.masks`, rule "one_step": win if you can, never pick an action with a
negative one-step reward), then a seeded uniform choice inside them. A trained agent replaces the uniform
choice by the argmax of its Q-network (`pipelines.evaluate.load_agent`).
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase

from modules.masks import GREEDY_MASK_KEY, LookaheadMasks


class LookaheadOnlyPolicy:
    """Callable on an env TensorDict: writes `action` chosen uniformly among the look-ahead's greedy set."""

    def __init__(self, seed: int = 0, lookahead: str = "one_step") -> None:
        self.masks = LookaheadMasks(lookahead)
        self.generator = torch.Generator().manual_seed(int(seed))

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        self.masks(td)
        mask = td.get(GREEDY_MASK_KEY)
        scores = torch.rand(mask.shape, generator=self.generator) + mask.float()
        td.set("action", scores.argmax(-1))
        return td
