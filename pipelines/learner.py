"""The learner of a run: competitive DQN loss + target updater + optimiser, built from the config in one place.

`train.py` and `bench/learner_throughput.py` both step this object, so the benchmark measures exactly the
update the training loop runs.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule

from modules.loss import CompetitiveDQNLoss, make_target_updater
from pipelines.config import RunConfig


def scheduled_lr(config: RunConfig, frames: int) -> float:
    """Linear decay from optim.lr to schedule.lr_end over collector.total_frames (constant lr when lr_end is None)."""
    if config.schedule.lr_end is None:
        return config.optim.lr
    progress = min(1.0, max(0.0, frames / max(1, config.collector.total_frames)))
    return config.optim.lr + progress * (config.schedule.lr_end - config.optim.lr)


@dataclass
class Learner:
    loss_module: CompetitiveDQNLoss
    target_updater: object
    optimizer: torch.optim.Optimizer
    max_grad_norm: float

    @classmethod
    def from_config(cls, qnet: TensorDictModule, config: RunConfig) -> "Learner":
        loss_module = CompetitiveDQNLoss(qnet, loss_function=config.loss.loss_function, double_dqn=config.loss.double_dqn)
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

    def update(self, batch) -> float:
        """One gradient step on a sampled batch, then a target-network step; returns the loss."""
        loss = self.loss_module(batch)["loss"]
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
