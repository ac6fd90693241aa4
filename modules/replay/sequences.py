"""Replayed slices of dialogues for a recurrent Q-network (`agent.memory`), after Kapturowski et al. 2019 (R2D2).

- Sequences, not transitions: TorchRL's `SliceSampler` cuts slices of `buffer.sequence_length` (L) steps out of
  one dialogue each, found by its id (`episode`) and step number (`step`) (`fragmented=True`: a dialogue's
  steps are interleaved with the other games' in the flat storage). Shorter dialogues (and what the circular
  buffer kept of a dialogue) give shorter slices, padded to L and masked (`("collector", "mask")`). A slice never
  crosses a dialogue boundary. A dialogue is drawn uniformly, then a start uniformly inside it.
- Stored state (R2D2's choice, better than zero state in its study): every step keeps the hidden state the
  actor had before it (`recurrent_state`), and the unroll of a slice starts from the stored state of its first
  step. A slice that starts a dialogue starts from the zero state, which is exact.
- Prioritised replay (`buffer.prioritized`): slices drawn by R2D2's sequence priority
  (`ncbot.modules.replay.prioritized_slices`).
- Defaults L = 16, burn-in 4: a 3x3 dialogue is ~10-15 acts, so most slices are whole dialogues; on Ultimate
  (~50-70 acts) the slices start inside dialogues and the burn-in matters (`ncbot.modules.objectives.recurrent_dqn`).

`SequenceRows` adds to the flat transitions what the sampler and the loss read: the dialogue id, the step number,
`is_init` and the hidden state before each step.
"""
from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import LazyTensorStorage, SliceSampler, TensorDictReplayBuffer

from ncbot.modules.networks.recurrent import IS_INIT_KEY, STATE_KEYS, check_memory
from ncbot.modules.objectives.common import PRIORITY_KEY
from ncbot.modules.replay.prioritized_slices import PrioritizedSequenceSampler

EPISODE_KEY = "episode"  # id of the dialogue a step belongs to (the frame index of its first step)
STEP_KEY = "step"  # the step's place in its dialogue (0 = first)
VALID_KEY = ("collector", "mask")  # SliceSampler's pad_output mask: True on real steps, False on padding


def sequence_keys(memory: str) -> tuple:
    """The keys a replayed slice holds besides its transitions' (`SequenceRows` and the sampler write them)."""
    return (IS_INIT_KEY, EPISODE_KEY, STEP_KEY, *STATE_KEYS[check_memory(memory)], VALID_KEY)


def make_sequence_buffer(size: int, batch_size: int, sequence_length: int, device: torch.device | str = "cpu", *,
                         prioritized: bool = False, alpha: float = 0.6, beta: float = 0.4) -> TensorDictReplayBuffer:
    """TorchRL replay buffer whose `SliceSampler` draws `batch_size // sequence_length` slices of one dialogue
    each, padded to `sequence_length` (see module doc); `prioritized`: slices drawn by their R2D2 priority
    (`ncbot.modules.replay.prioritized_slices`)."""
    if batch_size % sequence_length:
        raise ValueError(f"buffer.batch_size ({batch_size}) must be a multiple of buffer.sequence_length "
                         f"({sequence_length}) with agent.memory")
    if prioritized:
        sampler = PrioritizedSequenceSampler(size, sequence_length, alpha, beta, traj_key=EPISODE_KEY, step_key=STEP_KEY)
    else:
        sampler = SliceSampler(slice_len=sequence_length, traj_key=EPISODE_KEY, step_key=STEP_KEY, fragmented=True,
                               strict_length=False, pad_output=True, truncated_key=None)
    return TensorDictReplayBuffer(storage=LazyTensorStorage(size, device=device), sampler=sampler,
                                  priority_key=PRIORITY_KEY, batch_size=batch_size)


class SequenceRows:
    """Collector batch (env rows, T) + its flat transitions -> the rows a sequence buffer stores: the transitions
    plus `is_init`, the hidden state before each step, the dialogue id (`episode`) and its step number (`step`).

    The dialogue id is the global frame index of the dialogue's first step: unique across batches and across a
    resume (the frame counter is restored with the buffer). The id of a dialogue still running at the end of a
    batch is carried to the next batch (this object's state, one number per env row)."""

    def __init__(self, memory: str) -> None:
        self.state_keys = STATE_KEYS[check_memory(memory)] if memory != "none" else ()
        self.current: torch.Tensor | None = None  # per env row: the id of its running dialogue
        self.steps: torch.Tensor | None = None  # per env row: the step number its next step will have

    def __call__(self, batch: TensorDictBase, transitions: TensorDictBase, frames_before: int) -> TensorDictBase:
        rows, steps = batch.shape
        is_init = batch.get(IS_INIT_KEY).reshape(rows, steps)
        frame = frames_before + torch.arange(rows * steps).reshape(rows, steps)
        if self.current is None or self.current.shape[0] != rows:
            self.current = torch.full((rows,), -1, dtype=torch.long)
        starts = torch.where(is_init, frame, torch.full_like(frame, -1))
        episode = torch.cat([self.current.unsqueeze(1), starts], dim=1).cummax(dim=1).values[:, 1:]
        if bool((episode < 0).any()):
            raise ValueError("a collected step belongs to no dialogue (no is_init seen before it): the env must be "
                             "wrapped by modules.networks.recurrent.memory_env")
        self.current = episode[:, -1].clone()
        # the step number counts from each dialogue's first step (also for one that began in an earlier batch)
        first_seen = torch.where(is_init, torch.arange(steps).expand(rows, steps), torch.full_like(frame, -1))
        last_start = first_seen.cummax(dim=1).values
        carried = self.steps if self.steps is not None and self.steps.shape[0] == rows else torch.zeros(rows, dtype=torch.long)
        step = torch.where(last_start >= 0, torch.arange(steps) - last_start,
                           carried.unsqueeze(1) + torch.arange(steps))
        self.steps = step[:, -1] + 1
        flat = transitions.set(IS_INIT_KEY, is_init.reshape(-1, 1))
        flat.set(EPISODE_KEY, episode.reshape(-1))
        flat.set(STEP_KEY, step.reshape(-1))
        for key in self.state_keys:
            flat.set(key, batch.get(key).reshape(rows * steps, *batch.get(key).shape[2:]))
        return flat
