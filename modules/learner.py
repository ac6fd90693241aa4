"""The learner of a run: replay buffer, competitive DQN loss, target updater and optimiser, built in one place
from `LearnerSettings` (plain values; the pipelines fill them from the run's config).

The training loop (`ncbot.pipelines.train`) and `bench/learner_throughput.py` both step this object, so the benchmark
measures exactly the update the training loop runs. Speed figures: docs/learner-speed.md.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from ncbot.modules.objectives.competitive_dqn import PRIORITY_KEY, CompetitiveDQNLoss, make_target_updater
from ncbot.modules.search.search_targets import EXPERT_ACTION_KEY, LABEL_MASK_KEY, SearchTeacher, margin_loss
from ncbot.modules.replay.symmetry import BoardSymmetries
from ncbot.modules.replay.prioritized_sampler import ProportionalSampler
from ncbot.modules.replay.prioritized_slices import PrioritizedSequenceSampler
from ncbot.modules.replay.transitions import LOSS_KEYS


@dataclass(frozen=True)
class LearnerSettings:
    """What the learner is built from (the run config's loss and optim sections)."""

    loss_function: str
    double_dqn: bool
    precision: str
    gamma: float
    target_update: str
    target_period: int
    tau: float
    lr: float
    weight_decay: float
    max_grad_norm: float
    # agent.memory (modules/networks/recurrent.py): a recurrent network learnt from slices of dialogues
    memory: str = "none"
    sequence_length: int = 16
    burn_in: int = 0


def scheduled_lr(frames: int, lr: float, lr_end: float | None, total_frames: int) -> float:
    """Linear decay from `lr` to `lr_end` over `total_frames` (constant `lr` when `lr_end` is None)."""
    if lr_end is None:
        return lr
    progress = min(1.0, max(0.0, frames / max(1, total_frames)))
    return lr + progress * (lr_end - lr)


def make_loss(qnet: TensorDictModule, *, loss_function: str = "l2", double_dqn: bool = False,
              precision: str = "fp32", gamma: float = 0.99) -> CompetitiveDQNLoss:
    """The competitive DQN loss reading the transitions `ncbot.modules.replay.transitions.prepare_transitions` stores (its
    learning reward and bootstrap mask: `LOSS_KEYS`), with its TD(0) value estimator."""
    loss_module = CompetitiveDQNLoss(qnet, loss_function=loss_function, double_dqn=double_dqn, precision=precision)
    loss_module.set_keys(**LOSS_KEYS)
    loss_module.make_value_estimator(gamma=gamma)
    return loss_module


def make_replay_buffer(size: int, batch_size: int, *, prioritized: bool = False, alpha: float = 0.6,
                       beta: float = 0.4, sequence_length: int | None = None,
                       device: torch.device | str = "cpu") -> TensorDictReplayBuffer:
    """The run's replay buffer: TorchRL's TensorDictReplayBuffer over a LazyTensorStorage, with its uniform
    RandomSampler or, `prioritized`, a proportional one (`ncbot.modules.replay.prioritized_sampler`: rows drawn by the loss's
    |TD error|, each with its importance weight `priority_weight`); with a `sequence_length` (agent.memory), slices
    of dialogues (`ncbot.modules.networks.recurrent.make_sequence_buffer`; `prioritized`: by R2D2's sequence priority). The storage lives on `device` (the learner's: sampled
    batches need no copy; the uniform sampler draws its indices there)."""
    if sequence_length is not None:
        from ncbot.modules.networks.recurrent import make_sequence_buffer

        return make_sequence_buffer(size, batch_size, sequence_length, device, prioritized=prioritized, alpha=alpha,
                                    beta=beta)
    sampler = ProportionalSampler(size, alpha, beta) if prioritized else None
    return TensorDictReplayBuffer(storage=LazyTensorStorage(size, device=device), sampler=sampler, priority_key=PRIORITY_KEY,
                                  batch_size=batch_size)


def _draw(buffer: TensorDictReplayBuffer, count: int) -> list[TensorDictBase]:
    """`count` batches of the buffer's batch size, drawn in one sampling call (see `Learner.update_many`)."""
    size = buffer.batch_size
    with warnings.catch_warnings():  # TorchRL warns that the call's size overrides the constructor's: intended
        warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
        return list(buffer.sample(size * count).split(size))


@dataclass
class Learner:
    """The update of TorchRL's DQN script: sample, `loss_td = loss_module(td)`, backward/step, target updater step."""

    loss_module: CompetitiveDQNLoss
    target_updater: object
    optimizer: torch.optim.Optimizer
    max_grad_norm: float
    symmetries: BoardSymmetries | None = None  # buffer.augment=d4: each sample seen under a random board symmetry
    teacher: SearchTeacher | None = None  # search_targets: labels of the Q-guided search, a margin loss beside TD
    teacher_weight: float = 1.0
    teacher_margin: float = 1.0

    def __post_init__(self) -> None:
        # the online parameters, listed once: LossModule.parameters() walks its modules at every call (~80 us, which
        # is a third of a whole update at the paper's batch of 2)
        self._parameters = list(self.loss_module.parameters())

    @classmethod
    def build(cls, qnet: TensorDictModule, settings: LearnerSettings,
              symmetries: BoardSymmetries | None = None) -> "Learner":
        if settings.memory != "none":  # slices of dialogues through the recurrent network (modules/networks/recurrent.py)
            from ncbot.modules.networks.recurrent import make_sequence_loss

            loss_module = make_sequence_loss(qnet, settings, symmetries)
            symmetries = None  # the loss turns whole slices
        else:
            loss_module = make_loss(qnet, loss_function=settings.loss_function, double_dqn=settings.double_dqn,
                                    precision=settings.precision, gamma=settings.gamma)
        updater = make_target_updater(loss_module, settings.target_update, settings.target_period, settings.tau)
        # fused Adam: one kernel for all parameters instead of a loop of small ops (CPU supports it in torch >= 2.4)
        optimizer = torch.optim.Adam(loss_module.parameters(), lr=settings.lr, weight_decay=settings.weight_decay,
                                     fused=True)
        return cls(loss_module, updater, optimizer, settings.max_grad_norm, symmetries)

    def set_lr(self, lr: float) -> None:
        """Schedule hook: the train loop decays the step size so Q stops jittering between near-tied moves."""
        for group in self.optimizer.param_groups:
            group["lr"] = lr

    def augmented(self, batch: TensorDictBase) -> TensorDictBase:
        """The batch under one random board symmetry per row: state, action, next state and bootstrap mask turn
        together (the keys the loss reads; the rest of the batch is left out)."""
        keys = self.loss_module.tensor_keys
        mask_key = ("next", keys.bootstrap_mask)
        observation, action, next_observation, next_mask = self.symmetries.transitions(
            batch.get("observation"), batch.get(keys.action), batch.get(("next", "observation")), batch.get(mask_key))
        turned = batch.exclude("observation", keys.action, ("next", "observation"), mask_key)
        turned.set("observation", observation)
        turned.set(keys.action, action)
        turned.set(("next", "observation"), next_observation)
        turned.set(mask_key, next_mask)
        return turned

    def update(self, batch: TensorDictBase, labels: TensorDictBase | None = None) -> torch.Tensor:
        """One gradient step on a sampled batch (and, with `labels` of the search teacher, its margin loss), then a
        target-network step; returns the loss (0-d tensor, no sync)."""
        sampled = batch
        if self.symmetries is not None:
            batch = self.augmented(batch)
        loss_td = self.loss_module(batch)  # writes the rows' |TD error| into `batch` (prioritised replay reads it)
        if batch is not sampled:
            sampled.set(PRIORITY_KEY, batch.get(PRIORITY_KEY))
        loss = loss_td["loss"]
        if labels is not None:
            if batch.device is not None and labels.device != batch.device:  # the teacher's labels stay on the CPU
                labels = labels.to(batch.device)
            q_values = self.loss_module.q_values(labels)
            loss = loss + self.teacher_weight * margin_loss(q_values, labels.get(EXPERT_ACTION_KEY),
                                                            labels.get(LABEL_MASK_KEY), self.teacher_margin)
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
        parts = _draw(buffer, count)
        labels = _draw(self.teacher.labels, count) if self.teacher is not None and self.teacher.ready() \
            else [None] * count
        if not isinstance(buffer.sampler, (ProportionalSampler, PrioritizedSequenceSampler)):
            return [self.update(part, label) for part, label in zip(parts, labels)]
        # prioritised: the draw is one sample of the priorities (as Ape-X's learner takes a few batches per fetch);
        # each part's new |TD error| (a recurrent loss: its slices' priorities) goes back to the sampler after its update
        losses = []
        for part, label in zip(parts, labels):
            losses.append(self.update(part, label))
            buffer.update_priority(part.get("index"), part.get(PRIORITY_KEY))
        return losses

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
        if self.symmetries is not None and "symmetries" in state:
            self.symmetries.load_state_dict(state["symmetries"])
