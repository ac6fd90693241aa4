"""The learner of a run: replay buffer, competitive DQN loss, target updater and optimiser, built from the config
in one place.

`train.py` and `bench/learner_throughput.py` both step this object, so the benchmark measures exactly the
update the training loop runs. Why each speed choice was made, with figures: docs/learner-speed.md.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase, is_tensor_collection
from tensordict.nn import TensorDictModule
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.objectives import HardUpdate

from modules.loss import CACHE_ROW_BLOCK, CompetitiveDQNLoss, TargetValueCache, make_target_updater
from modules.symmetry import BoardSymmetries
from pipelines.config import RunConfig


def scheduled_lr(config: RunConfig, frames: int) -> float:
    """Linear decay from optim.lr to schedule.lr_end over collector.total_frames (constant lr when lr_end is None)."""
    if config.schedule.lr_end is None:
        return config.optim.lr
    progress = min(1.0, max(0.0, frames / max(1, config.collector.total_frames)))
    return config.optim.lr + progress * (config.schedule.lr_end - config.optim.lr)


WRITE_STAMP_KEY = "write_stamp"


class GatherStorage(LazyTensorStorage):
    """`LazyTensorStorage` whose batch reads gather each stored tensor with `index_select`, and which stamps every
    write so a cache of per-slot values (`TargetValueCache`) can tell a rewritten slot from a revisited one.

    Why: TensorDict fancy indexing of the 11 transition keys costs ~1.2 ms per 1024-sample batch, a sixth of a
    whole gradient update; `index_select` reads the same rows (bit-identical batches, same sampler and RNG) 2.4x
    faster. Sampled batches carry one extra key, `write_stamp` (B,): the stamp of the write that filled each row's
    slot. Anything but a 1-D tensor of indices goes through the parent class unchanged.
    """

    def __init__(self, max_size: int, **kwargs) -> None:
        super().__init__(max_size, **kwargs)
        self._write_stamps = torch.full((max_size,), -1, dtype=torch.long)
        self._next_stamp = 0

    def _stamp(self, cursor) -> None:
        if isinstance(cursor, (list, tuple)):
            cursor = torch.as_tensor(cursor, dtype=torch.long)
        self._write_stamps[cursor] = self._next_stamp
        self._next_stamp += 1

    def set(self, cursor, data, *, set_cursor: bool = True):
        result = super().set(cursor, data, set_cursor=set_cursor)
        self._stamp(cursor)
        return result

    def load_state_dict(self, state_dict) -> None:
        super().load_state_dict(state_dict)
        self._stamp(slice(None))  # every slot holds new data now

    def get(self, index):
        storage = self._storage
        if not (isinstance(index, torch.Tensor) and index.ndim == 1 and index.dtype == torch.long
                and self.initialized and is_tensor_collection(storage)):
            return super().get(index)
        batch = storage.apply(lambda stored: stored.index_select(0, index), batch_size=index.shape)
        batch.set(WRITE_STAMP_KEY, self._write_stamps.index_select(0, index))
        return batch


def make_replay_buffer(size: int, batch_size: int) -> TensorDictReplayBuffer:
    """The run's uniform replay buffer: TorchRL's TensorDictReplayBuffer + RandomSampler over a GatherStorage."""
    return TensorDictReplayBuffer(storage=GatherStorage(size), batch_size=batch_size)


@dataclass
class Learner:
    loss_module: CompetitiveDQNLoss
    target_updater: object
    optimizer: torch.optim.Optimizer
    max_grad_norm: float
    target_cache: TargetValueCache | None = None  # hard target updates without double DQN: bootstrap values per slot
    symmetries: BoardSymmetries | None = None  # buffer.augment=d4: each sample seen under a random board symmetry

    def __post_init__(self) -> None:
        # the online parameters, listed once: LossModule.parameters() walks its modules at every call (~80 us, which
        # is a third of a whole update at the paper's batch of 2)
        self._parameters = list(self.loss_module.parameters())

    @classmethod
    def from_config(cls, qnet: TensorDictModule, config: RunConfig,
                    symmetries: BoardSymmetries | None = None) -> "Learner":
        loss_module = CompetitiveDQNLoss(qnet, loss_function=config.loss.loss_function, double_dqn=config.loss.double_dqn,
                                         precision=config.optim.precision)
        loss_module.make_value_estimator(gamma=config.loss.gamma)
        updater = make_target_updater(loss_module, config.loss.target_update, config.loss.target_period, config.loss.tau)
        # fused Adam: one kernel for all parameters instead of a loop of small ops (CPU supports it in torch >= 2.4)
        optimizer = torch.optim.Adam(loss_module.parameters(), lr=config.optim.lr,
                                     weight_decay=config.optim.weight_decay, fused=True)
        cache = None
        # the cache keys a slot's bootstrap value by slot, so it cannot hold one value per orientation (augment); it
        # pads its products to CACHE_ROW_BLOCK rows, so for small batches (the paper's 2) it costs more than it saves
        if isinstance(updater, HardUpdate) and not config.loss.double_dqn and symmetries is None \
                and config.buffer.batch_size >= CACHE_ROW_BLOCK:
            cache = TargetValueCache(loss_module)
        return cls(loss_module, updater, optimizer, config.optim.max_grad_norm, cache, symmetries)

    def set_lr(self, lr: float) -> None:
        """Schedule hook: the train loop decays the step size so Q stops jittering between near-tied moves."""
        for group in self.optimizer.param_groups:
            group["lr"] = lr

    def update(self, batch: TensorDictBase) -> torch.Tensor:
        """One gradient step on a sampled batch, then a target-network step; returns the loss (a 0-d tensor, no sync).

        Calls the loss on plain tensors (`td_loss`): the same computation as `loss_module(batch)`, without building
        the metrics TensorDict and the `td_error` key nobody reads with uniform replay. Batches from a GatherStorage
        (slot index + write stamp) take their bootstrap values from the target cache when it has them.
        """
        inputs = self.loss_module.td_loss_inputs(batch)
        if self.symmetries is not None:
            observation, action, reward, terminated, next_observation, next_mask = inputs
            observation, action, next_observation, next_mask = self.symmetries.transitions(
                observation, action, next_observation, next_mask)
            inputs = (observation, action, reward, terminated, next_observation, next_mask)
        next_value = None
        if self.target_cache is not None:
            slots, stamps = batch.get("index", None), batch.get(WRITE_STAMP_KEY, None)
            if slots is not None and stamps is not None:
                next_value = self.target_cache.lookup(slots, stamps, inputs[4], inputs[5])
        loss, _, _ = self.loss_module.td_loss(*inputs, next_value=next_value)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self._parameters, self.max_grad_norm, foreach=True)
        self.optimizer.step()
        self.target_updater.step()
        if self.target_cache is not None and self.target_updater.counter == 0:  # HardUpdate just copied the weights
            self.target_cache.clear()
        return loss.detach()

    def update_many(self, buffer: TensorDictReplayBuffer, count: int) -> list[torch.Tensor]:
        """`count` gradient steps on `count` batches drawn from `buffer` in one sampling call; returns their losses.

        Why: the buffer does not change between the updates of one collected batch, and the sampler draws rows
        i.i.d. uniformly, so one draw of count x batch_size rows split in order is the same sample as `count` draws
        (the same rows, bit for bit: the sampler's index draw consumes the generator row by row), but pays the
        sampler's fixed cost once. That cost is most of an update at small batches (the paper's batch of 2).
        """
        if count <= 0:
            return []
        size = buffer.batch_size
        with warnings.catch_warnings():  # TorchRL warns that the call's size overrides the constructor's: intended
            warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
            draw = buffer.sample(size * count)
        return [self.update(part) for part in draw.split(size)]

    def state_dict(self) -> dict:
        state = {"loss": self.loss_module.state_dict(), "optimizer": self.optimizer.state_dict(),
                 "target_counter": getattr(self.target_updater, "counter", 0)}
        if self.symmetries is not None:
            state["symmetries"] = self.symmetries.state_dict()
        return state

    def load_state_dict(self, state: dict) -> None:
        self.loss_module.load_state_dict(state["loss"])
        self.optimizer.load_state_dict(state["optimizer"])
        if hasattr(self.target_updater, "counter"):
            self.target_updater.counter = state.get("target_counter", 0)
        if self.target_cache is not None:
            self.target_cache.clear()
        if self.symmetries is not None and "symmetries" in state:
            self.symmetries.load_state_dict(state["symmetries"])
