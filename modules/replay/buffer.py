"""The run's replay buffer: TorchRL's `TensorDictReplayBuffer` over a `LazyTensorStorage`, of transitions or of
slices of dialogues, whichever the objective replays (`replays`)."""
from __future__ import annotations

import warnings

import torch
from tensordict import TensorDictBase
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from ncbot.modules.objectives.common import PRIORITY_KEY
from ncbot.modules.replay.prioritized_sampler import ProportionalSampler
from ncbot.modules.replay.sequences import make_sequence_buffer


def make_replay_buffer(size: int, batch_size: int, *, prioritized: bool = False, alpha: float = 0.6,
                       beta: float = 0.4, sequence_length: int | None = None,
                       device: torch.device | str = "cpu") -> TensorDictReplayBuffer:
    """Uniform RandomSampler or, `prioritized`, a proportional one (`ncbot.modules.replay.prioritized_sampler`: rows
    drawn by the loss's |TD error|, each with its importance weight `priority_weight`); with a `sequence_length`,
    slices of dialogues (`ncbot.modules.replay.sequences`; `prioritized`: by R2D2's sequence priority). The storage
    lives on `device` (the learner's: sampled batches need no copy; the uniform sampler draws its indices there)."""
    if sequence_length is not None:
        return make_sequence_buffer(size, batch_size, sequence_length, device, prioritized=prioritized, alpha=alpha,
                                    beta=beta)
    sampler = ProportionalSampler(size, alpha, beta) if prioritized else None
    return TensorDictReplayBuffer(storage=LazyTensorStorage(size, device=device), sampler=sampler,
                                  priority_key=PRIORITY_KEY, batch_size=batch_size)


def draw_batches(buffer: TensorDictReplayBuffer, count: int) -> list[TensorDictBase]:
    """`count` batches of the buffer's batch size, drawn in one sampling call (`Learner.update_many` says why)."""
    size = buffer.batch_size
    with warnings.catch_warnings():  # TorchRL warns that the call's size overrides the constructor's: intended
        warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
        return list(buffer.sample(size * count).split(size))
