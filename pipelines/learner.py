"""The learner of a run: replay buffer, competitive DQN loss, target updater and optimiser, built from the config
in one place.

`train.py` and `bench/learner_throughput.py` both step this object, so the benchmark measures exactly the
update the training loop runs. Why each speed choice was made, with figures: docs/learner-speed.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDictBase, is_tensor_collection
from tensordict.nn import TensorDictModule
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from modules.loss import CompetitiveDQNLoss, make_target_updater
from pipelines.config import RunConfig


def scheduled_lr(config: RunConfig, frames: int) -> float:
    """Linear decay from optim.lr to schedule.lr_end over collector.total_frames (constant lr when lr_end is None)."""
    if config.schedule.lr_end is None:
        return config.optim.lr
    progress = min(1.0, max(0.0, frames / max(1, config.collector.total_frames)))
    return config.optim.lr + progress * (config.schedule.lr_end - config.optim.lr)


class GatherStorage(LazyTensorStorage):
    """`LazyTensorStorage` whose batch reads gather each stored tensor with `index_select`.

    Why: TensorDict fancy indexing of the 11 transition keys costs ~1 ms per 1024-sample batch, a sixth of a whole
    gradient update; `index_select` reads the same rows (bit-identical batches, same sampler and RNG) several times
    faster. Anything but a 1-D tensor of indices goes through the parent class unchanged.
    """

    def get(self, index):
        storage = self._storage
        if not (isinstance(index, torch.Tensor) and index.ndim == 1 and index.dtype == torch.long
                and self.initialized and is_tensor_collection(storage)):
            return super().get(index)
        return storage.apply(lambda stored: stored.index_select(0, index), batch_size=index.shape)


def make_replay_buffer(size: int, batch_size: int) -> TensorDictReplayBuffer:
    """The run's uniform replay buffer: TorchRL's TensorDictReplayBuffer + RandomSampler over a GatherStorage."""
    return TensorDictReplayBuffer(storage=GatherStorage(size), batch_size=batch_size)


@dataclass
class Learner:
    loss_module: CompetitiveDQNLoss
    target_updater: object
    optimizer: torch.optim.Optimizer
    max_grad_norm: float

    @classmethod
    def from_config(cls, qnet: TensorDictModule, config: RunConfig) -> "Learner":
        loss_module = CompetitiveDQNLoss(qnet, loss_function=config.loss.loss_function, double_dqn=config.loss.double_dqn,
                                         precision=config.optim.precision)
        loss_module.make_value_estimator(gamma=config.loss.gamma)
        updater = make_target_updater(loss_module, config.loss.target_update, config.loss.target_period, config.loss.tau)
        # fused Adam: one kernel for all parameters instead of a loop of small ops (CPU supports it in torch >= 2.4)
        optimizer = torch.optim.Adam(loss_module.parameters(), lr=config.optim.lr,
                                     weight_decay=config.optim.weight_decay, fused=True)
        return cls(loss_module, updater, optimizer, config.optim.max_grad_norm)

    def set_lr(self, lr: float) -> None:
        """Schedule hook: the train loop decays the step size so Q stops jittering between near-tied moves."""
        for group in self.optimizer.param_groups:
            group["lr"] = lr

    def update(self, batch: TensorDictBase) -> torch.Tensor:
        """One gradient step on a sampled batch, then a target-network step; returns the loss (a 0-d tensor, no sync).

        Calls the loss on plain tensors (`td_loss`): the same computation as `loss_module(batch)`, without building
        the metrics TensorDict and the `td_error` key nobody reads with uniform replay.
        """
        loss, _, _ = self.loss_module.td_loss(*self.loss_module.td_loss_inputs(batch))
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.loss_module.parameters(), self.max_grad_norm, foreach=True)
        self.optimizer.step()
        self.target_updater.step()
        return loss.detach()

    def state_dict(self) -> dict:
        return {"loss": self.loss_module.state_dict(), "optimizer": self.optimizer.state_dict(),
                "target_counter": getattr(self.target_updater, "counter", 0)}

    def load_state_dict(self, state: dict) -> None:
        self.loss_module.load_state_dict(state["loss"])
        self.optimizer.load_state_dict(state["optimizer"])
        if hasattr(self.target_updater, "counter"):
            self.target_updater.counter = state.get("target_counter", 0)
