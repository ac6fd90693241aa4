"""Masked argmax over Q-values, leaving the raw Q-values untouched.

TorchRL's `QValueModule` overwrites `action_value` with the masked values; we keep the raw ones for the logger and
write the masked argmax and its value under separate keys.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase


class MaskedArgmax(TensorDictModuleBase):
    """Writes `action` = argmax of `value_key` over `mask_key`, and that maximum under `max_value_key`."""

    def __init__(self, value_key: str, mask_key: str, action_key: str = "action", max_value_key: str = "chosen_action_value") -> None:
        super().__init__()
        self.value_key, self.mask_key = value_key, mask_key
        self.action_key, self.max_value_key = action_key, max_value_key
        self.in_keys = [value_key, mask_key]
        self.out_keys = [action_key, max_value_key]

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        values = tensordict.get(self.value_key)
        masked = values.masked_fill(~tensordict.get(self.mask_key), torch.finfo(values.dtype).min)
        best, action = masked.max(-1)
        tensordict.set(self.action_key, action)
        tensordict.set(self.max_value_key, best.unsqueeze(-1))
        return tensordict
