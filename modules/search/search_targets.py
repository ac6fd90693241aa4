"""Targets improved by search: the Q-network is also trained towards the moves its own Q-guided search picks.

Expert iteration (Anthony et al. 2017; AlphaZero) in a DQN: the search (``ncbot.modules.search.guided_mcts``: priors from the
current Q-network, leaves scored by Q plus random playouts or by a value network) is a better player than the greedy
network it starts from, so its choices are labels. Each label is (observation, greedy mask, searched move); the learner adds DQfD's
large-margin loss (Hester et al. 2018) on a batch of labels to the TD loss:

    J_E = max_{a in mask} [Q(s, a) + l(a_E, a)] - Q(s, a_E),   l = margin for a != a_E, 0 for a_E

which is zero once Q ranks the searched move above every other move of the mask by the margin, and leaves the
values themselves to the TD loss. The mask is DQfD's (every move the greedy policy could play, ``gap=None``) or,
by default, only the moves the search valued clearly below the searched one (``gap``): on Ultimate most moves
against the random user are near ties, and the full mask taught the search's tie-breaks and wrecked the agent
(docs/search.md). Labels come from the robot's game moves of the collected batches (optionally
only robot-second games, the weak seat on Ultimate), searched with the network as it is at that point of training.
"""
from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from ncbot.modules.policies.mask_rules import AVAILABLE_KEY, GREEDY_MASK_KEY
from ncbot.modules.replay.buffer import draw_batches
from ncbot.modules.search.guided_mcts import GuidedMCTS, GuidedMCTSPolicy

EXPERT_ACTION_KEY = "expert_action"
LABEL_MASK_KEY = "label_mask"  # the searched move and the moves the label ranks it above
SEARCH_IN_KEYS = ("observation", AVAILABLE_KEY, "board", "lookahead_reward", "winning_actions")


def margin_loss(q_values: torch.Tensor, expert_action: torch.Tensor, mask: torch.Tensor, margin: float) -> torch.Tensor:
    """DQfD's supervised large-margin loss, averaged over rows: (B, A) Q-values, (B,) searched moves, (B, A) masks."""
    q = q_values.masked_fill(~mask, float("-inf"))
    bonus = torch.full_like(q, float(margin))
    bonus.scatter_(-1, expert_action.unsqueeze(-1), 0.0)
    expert_q = q_values.gather(-1, expert_action.unsqueeze(-1)).squeeze(-1)
    return ((q + bonus).amax(-1) - expert_q).mean()


class SearchTeacher:
    """Labels robot game moves of collected batches with the moves the Q-guided search picks (see module doc)."""

    def __init__(self, greedy: torch.nn.Module, search: GuidedMCTS, *, rows_per_batch: int, seat: str = "both",
                 gap: float | None = 0.1, buffer_size: int = 50_000, batch_size: int = 128, seed: int = 0,
                 weight: float = 1.0, margin: float = 1.0, device: torch.device | str = "cpu") -> None:
        if seat not in ("both", "second"):
            raise ValueError(f"seat must be 'both' or 'second', got {seat!r}")
        self.search, self.rows_per_batch, self.seat, self.gap = search, int(rows_per_batch), seat, gap
        self.weight, self.margin, self.device = weight, margin, torch.device(device)  # of the learner's margin term
        self.policy = GuidedMCTSPolicy(greedy, search, seed)  # root: the greedy mask, priors: the real observation
        self.generator = torch.Generator().manual_seed(int(seed) + 17)
        self.labels = TensorDictReplayBuffer(storage=LazyTensorStorage(buffer_size), batch_size=batch_size)
        self.searched = self.kept = 0  # moves searched, labels kept (CPU: the policy's own count)

    @property
    def cpu_seconds(self) -> float:
        return self.policy.cpu_seconds

    def candidates(self, batch: TensorDictBase) -> torch.Tensor:
        """Flat row indices of robot game moves with a choice: at least two moves in the greedy mask."""
        cells = self.search.cells
        choice = batch.get(GREEDY_MASK_KEY)[..., :cells].sum(-1) >= 2
        if self.seat == "second":
            choice = choice & ~batch.get("robot_first").squeeze(-1)
        return choice.reshape(-1).nonzero().flatten()

    @torch.no_grad()
    def label(self, batch: TensorDictBase) -> int:
        """Search up to ``rows_per_batch`` random candidate rows of a collected batch; store their labels."""
        if batch.device is not None and batch.device.type != "cpu":  # a GPU run's batch: the search runs on the CPU
            batch = batch.to("cpu")
        rows = self.candidates(batch)
        if rows.numel() == 0:
            return 0
        pick = rows[torch.randperm(rows.numel(), generator=self.generator)[:self.rows_per_batch]]
        flat = batch.reshape(-1)
        states = flat.select(*SEARCH_IN_KEYS)[pick].clone()
        self.search.refresh()  # the network as it is now
        searched = self.policy(states)
        self.searched += pick.numel()
        expert = searched.get("action")
        mask = searched.get(GREEDY_MASK_KEY).clone()
        if self.gap is not None:
            mask = self.decisive_masks(expert, mask)
        keep = mask.sum(-1) >= 2  # a label must rank the searched move above at least one other move
        if not keep.any():
            return 0
        self.labels.extend(TensorDict({"observation": searched.get("observation")[keep], LABEL_MASK_KEY: mask[keep],
                                       EXPERT_ACTION_KEY: expert[keep]}, batch_size=[int(keep.sum())]))
        self.kept += int(keep.sum())
        return int(keep.sum())

    def decisive_masks(self, expert: torch.Tensor, greedy_mask: torch.Tensor) -> torch.Tensor:
        """Per searched row: the searched move and the moves whose root value is below its value by more than
        ``gap`` (win-probability units). Near-tied moves are left out: most of Ultimate's moves against the random
        user are near ties, and a margin between them would only teach the search's tie-breaks."""
        mask = torch.zeros_like(greedy_mask)
        for row, values in self.policy.root_values.items():
            best = int(expert[row])
            if best not in values:
                continue
            mask[row, best] = True
            for move, value in values.items():
                if value < values[best] - self.gap and greedy_mask[row, move]:
                    mask[row, move] = True
        return mask

    def ready(self) -> bool:
        return len(self.labels) >= self.labels.batch_size

    def draw(self, count: int) -> list[TensorDictBase | None]:
        """Label batches for the learner's next `count` updates, drawn in one call (none until enough are kept)."""
        return draw_batches(self.labels, count) if self.ready() else [None] * count

    def loss(self, objective, labels: TensorDictBase) -> torch.Tensor:
        """`weight` x the margin loss of the objective's online Q-values on a batch of labels (an auxiliary loss of
        ``ncbot.modules.learner.Learner``)."""
        if labels.device != self.device:  # the labels are kept on the CPU
            labels = labels.to(self.device)
        q_values = objective.q_values(labels)
        return self.weight * margin_loss(q_values, labels.get(EXPERT_ACTION_KEY), labels.get(LABEL_MASK_KEY),
                                         self.margin)

    def state_dict(self, keep_labels: bool = True) -> dict:
        """Generators and count (and the labels, unless a run keeps no replay data in its checkpoints)."""
        return {"generator": self.generator.get_state(), "policy_generator": self.policy.generator.get_state(),
                "searched": self.searched, "kept": self.kept, "labels": self.labels.state_dict() if keep_labels else None}

    def load_state_dict(self, state: dict) -> None:
        self.generator.set_state(state["generator"])
        self.policy.generator.set_state(state["policy_generator"])
        self.searched, self.kept = state["searched"], state["kept"]
        if state.get("labels") is not None:
            self.labels.load_state_dict(state["labels"])
