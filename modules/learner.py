"""The learner of a run: its objective (a TorchRL loss), target updater and optimiser, stepped as TorchRL's DQN
script does: sample, `loss_td = objective(td)`, backward, clip, step, `target_updater.step()`.

The training loop (`ncbot.pipelines.train`) and `bench/learner_throughput.py` both step this object, so the benchmark
measures exactly the update the training loop runs. Speed figures: docs/learner-speed.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import reduce
from typing import Any, Protocol

import torch
from tensordict import TensorDictBase
from torchrl.data import TensorDictReplayBuffer
from torchrl.objectives import LossModule

from ncbot.modules.objectives.common import PRIORITY_KEY, make_target_updater
from ncbot.modules.replay.buffer import draw_batches
from ncbot.modules.replay.prioritized_sampler import ProportionalSampler
from ncbot.modules.replay.prioritized_slices import PrioritizedSequenceSampler
from ncbot.modules.replay.symmetry import BoardSymmetries
from ncbot.modules.replay.transitions import BOOTSTRAP_MASK_KEY


class AuxiliaryLoss(Protocol):
    """A loss term added to the objective's at every update, on batches of its own (the search targets' margin
    loss on the search's labels, `ncbot.modules.search.search_targets.SearchTeacher`)."""

    def draw(self, count: int) -> list[TensorDictBase | None]:
        """Its batches for the next `count` updates, drawn in one call (None: no term at that update)."""

    def loss(self, objective: LossModule, batch: TensorDictBase) -> torch.Tensor:
        """The term, computed with the objective's online network."""


def scheduled_lr(frames: int, lr: float, lr_end: float | None, total_frames: int) -> float:
    """Linear decay from `lr` to `lr_end` over `total_frames` (constant `lr` when `lr_end` is None)."""
    if lr_end is None:
        return lr
    progress = min(1.0, max(0.0, frames / max(1, total_frames)))
    return lr + progress * (lr_end - lr)


def total_loss(loss_td: TensorDictBase) -> torch.Tensor:
    """The objective's `loss`, or, as TorchRL's trainers read a loss's output, the sum of its `loss_*` entries."""
    if "loss" in loss_td.keys():
        return loss_td.get("loss")
    return reduce(torch.add, [loss_td.get(key) for key in loss_td.keys() if key.startswith("loss_")])


@dataclass
class Learner:
    """The update of TorchRL's DQN script: sample, `loss_td = objective(td)`, backward/step, target updater step."""

    objective: LossModule
    target_updater: Any
    optimizer: torch.optim.Optimizer
    max_grad_norm: float
    symmetries: BoardSymmetries | None = None  # buffer.augment=d4 on transitions: each row under a random symmetry
    auxiliary: list[AuxiliaryLoss] = field(default_factory=list)

    def __post_init__(self) -> None:
        # the online parameters, listed once: LossModule.parameters() walks its modules at every call, a sizeable part
        # of a whole update at the paper's batch of 2
        self._parameters = list(self.objective.parameters())

    @classmethod
    def build(cls, objective: LossModule, *, optim: Any, loss: Any,
              symmetries: BoardSymmetries | None = None) -> "Learner":
        """From the run config's `optim` (lr, weight_decay, max_grad_norm) and `loss` (target_update,
        target_period, tau) sections."""
        updater = make_target_updater(objective, loss.target_update, loss.target_period, loss.tau)
        # fused Adam: one kernel for all parameters instead of a loop of small ops (CPU supports it in torch >= 2.4)
        optimizer = torch.optim.Adam(objective.parameters(), lr=optim.lr, weight_decay=optim.weight_decay,
                                     fused=True)
        return cls(objective, updater, optimizer, optim.max_grad_norm, symmetries)

    def set_lr(self, lr: float) -> None:
        """Schedule hook: the train loop decays the step size so Q stops jittering between near-tied moves."""
        for group in self.optimizer.param_groups:
            group["lr"] = lr

    def augmented(self, batch: TensorDictBase) -> TensorDictBase:
        """The batch under one random board symmetry per row: state, action, next state and bootstrap mask turn
        together (the keys a transition's loss reads; the rest of the batch is left out)."""
        observation, action, next_observation, next_mask = self.symmetries.transitions(
            batch.get("observation"), batch.get("action"), batch.get(("next", "observation")),
            batch.get(BOOTSTRAP_MASK_KEY))
        turned = batch.exclude("observation", "action", ("next", "observation"), BOOTSTRAP_MASK_KEY)
        turned.set("observation", observation)
        turned.set("action", action)
        turned.set(("next", "observation"), next_observation)
        turned.set(BOOTSTRAP_MASK_KEY, next_mask)
        return turned

    def update(self, batch: TensorDictBase, extras: list[TensorDictBase | None] | None = None) -> torch.Tensor:
        """One gradient step on a sampled batch (and each auxiliary loss on its batch in `extras`), then a
        target-network step; returns the loss (0-d tensor, no sync)."""
        sampled = batch
        if self.symmetries is not None:
            batch = self.augmented(batch)
        loss_td = self.objective(batch)  # writes the rows' |TD error| into `batch` (prioritised replay reads it)
        if batch is not sampled and PRIORITY_KEY in batch.keys():
            sampled.set(PRIORITY_KEY, batch.get(PRIORITY_KEY))
        loss = total_loss(loss_td)
        for term, extra in zip(self.auxiliary, extras or ()):
            if extra is not None:
                loss = loss + term.loss(self.objective, extra)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self._parameters, self.max_grad_norm, foreach=True)
        self.optimizer.step()
        self.target_updater.step()
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
        parts = draw_batches(buffer, count)
        extras = list(zip(*(term.draw(count) for term in self.auxiliary))) or [()] * count
        if not isinstance(buffer.sampler, (ProportionalSampler, PrioritizedSequenceSampler)):
            return [self.update(part, list(extra)) for part, extra in zip(parts, extras)]
        # prioritised: the draw is one sample of the priorities (as Ape-X's learner takes a few batches per fetch);
        # each part's new |TD error| (a recurrent loss: its slices' priorities) goes back to the sampler after its update
        losses = []
        for part, extra in zip(parts, extras):
            losses.append(self.update(part, list(extra)))
            buffer.update_priority(part.get("index"), part.get(PRIORITY_KEY))
        return losses

    def state_dict(self) -> dict:
        state = {"loss": self.objective.state_dict(), "optimizer": self.optimizer.state_dict(),
                 "target_counter": getattr(self.target_updater, "counter", 0)}
        if self.symmetries is not None:
            state["symmetries"] = self.symmetries.state_dict()
        return state

    def load_state_dict(self, state: dict) -> None:
        self.objective.load_state_dict(state["loss"])
        self.optimizer.load_state_dict(state["optimizer"])
        if hasattr(self.target_updater, "counter"):
            self.target_updater.counter = state.get("target_counter", 0)
        if self.symmetries is not None and "symmetries" in state:
            self.symmetries.load_state_dict(state["symmetries"])
