"""Competitive DQN loss (paper, Algorithm 2) as a TorchRL `LossModule`.

Target: y = r on terminal steps, else r + gamma * max over the AVAILABLE actions a' of s' (the stored next
`action_mask`) of the target network's Q(s', a'); the error is taken on Q(s, a) (the paper's Q(s', a') in the
error term is a typo). Optional double DQN: the online network picks a' among the available actions, the target
network scores it. The target network is a TorchRL target-parameter copy, refreshed by `HardUpdate` (every C
updates, the paper) or `SoftUpdate`.

Speed (docs/learner-speed.md): the update is dominated by the MLP's matrix products, so the loss runs on plain
tensors (`td_loss`) and, when asked (`precision="bf16"`), runs the Q-network's products in bfloat16 under CPU
autocast while weights, gradients and the loss stay float32.
"""
from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass

import torch
from torch import nn
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.objectives import HardUpdate, LossModule, SoftUpdate, ValueEstimators
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator
from torchrl.objectives.value.functional import td0_return_estimate

from modules.argmax import MaskedArgmax
from modules.masks import AVAILABLE_KEY
from modules.qnet import ACTION_VALUE_KEY

MAX_AVAILABLE_VALUE_KEY = "max_available_value"
LOSS_FUNCTIONS = {"l2": "l2", "mse": "l2", "huber": "smooth_l1", "smooth_l1": "smooth_l1"}
PRECISIONS = ("fp32", "bf16")
CACHE_ROW_BLOCK = 64  # the target-value cache runs products of a multiple of this many rows (TargetValueCache)


def _linear_layer_keys(module: nn.Module) -> list[tuple[nn.Module, tuple[str, ...] | None]] | None:
    """(layer, key of its weights in the functional params) for a Sequential of Linear and stateless layers, else
    None: such a network runs on the target weights with one `F.linear` per layer, no module re-parametrisation."""
    if not isinstance(module, nn.Sequential):
        return None
    layers: list[tuple[nn.Module, tuple[str, ...] | None]] = []
    for index, layer in enumerate(module):
        if isinstance(layer, nn.Linear):
            layers.append((layer, ("module", "0", "module", str(index))))
        elif isinstance(layer, (nn.ReLU, nn.Tanh, nn.ELU, nn.LeakyReLU, nn.Identity)):
            layers.append((layer, None))
        else:
            return None
    return layers


class CompetitiveDQNLoss(LossModule):
    """DQN loss whose bootstrap maximises only over the actions available in the next state."""

    @dataclass
    class _AcceptedKeys:
        """Keys read from the sampled transitions."""

        action: str = "action"
        reward: str = "reward"
        done: str = "done"
        terminated: str = "terminated"
        value: str = MAX_AVAILABLE_VALUE_KEY
        action_value: str = ACTION_VALUE_KEY
        action_mask: str = AVAILABLE_KEY
        priority: str = "td_error"

    default_keys = _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0
    tensor_keys: _AcceptedKeys
    value_network: TensorDictModule
    value_network_params: TensorDict
    target_value_network_params: TensorDict

    def __init__(
        self,
        qnet: TensorDictModule,
        *,
        loss_function: str = "l2",
        double_dqn: bool = False,
        delay_value: bool = True,
        precision: str = "fp32",
    ) -> None:
        super().__init__()
        if loss_function not in LOSS_FUNCTIONS:
            raise ValueError(f"unknown loss_function {loss_function!r}; expected one of {sorted(LOSS_FUNCTIONS)}")
        if precision not in PRECISIONS:
            raise ValueError(f"unknown precision {precision!r}; expected one of {list(PRECISIONS)}")
        self.loss_function = LOSS_FUNCTIONS[loss_function]
        self.double_dqn = double_dqn
        self.precision = precision
        self.delay_value = delay_value
        # Q-network followed by a masked max: reading `observation` and `action_mask` of a state, it writes the
        # greedy available action and max_{a available} Q(s, a): the bootstrap value when run on s'.
        value_network = TensorDictSequential(
            qnet,
            MaskedArgmax(ACTION_VALUE_KEY, AVAILABLE_KEY, "action", MAX_AVAILABLE_VALUE_KEY),
        )
        self.convert_to_functional(value_network, "value_network", create_target_params=delay_value)
        self._qnet_tensor_module = qnet.module  # the bare nn.Module inside the TensorDict wrapper
        self._qnet_param_names = [name for name, _ in qnet.module.named_parameters()]
        self._qnet_layers = _linear_layer_keys(qnet.module)

    def make_value_estimator(self, value_type: ValueEstimators | None = None, **hyperparams) -> None:
        """Build the TD(0) estimator (the only one that matches the paper's one-step target), e.g. gamma=0.7."""
        value_type = value_type or self.default_value_estimator
        if value_type is not ValueEstimators.TD0:
            raise ValueError(f"CompetitiveDQNLoss supports only the TD0 value estimator, got {value_type}")
        self._value_estimator = TD0Estimator(**hyperparams, value_network=self.value_network)
        self._value_estimator.set_keys(
            value=self.tensor_keys.value,
            reward=self.tensor_keys.reward,
            done=self.tensor_keys.done,
            terminated=self.tensor_keys.terminated,
        )

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        if self._value_estimator is not None:
            self._value_estimator.set_keys(
                value=self.tensor_keys.value,
                reward=self.tensor_keys.reward,
                done=self.tensor_keys.done,
                terminated=self.tensor_keys.terminated,
            )

    def _matmul_precision(self):
        """bf16: CPU autocast runs the Linear layers' products in bfloat16 (AVX512_BF16 / AMX do them ~2x faster
        than float32); parameters, their gradients and everything after the Q-values stay float32."""
        if self.precision == "bf16":
            return torch.autocast("cpu", dtype=torch.bfloat16)
        return nullcontext()

    def _q_values(self, observation: torch.Tensor, params: TensorDictBase) -> torch.Tensor:
        """Q(s, .) under `params` (online or target), on plain tensors, as float32.

        Why not a full TensorDict module call: its plumbing costs more than the tiny MLP itself, and updates/s is
        what a learner is judged on. The online parameters ARE the Q-network's own (TorchRL's functional
        conversion keeps the same tensors), so the online pass is a plain call; the target pass runs the layers
        with `F.linear` on the target tensors (the same ops as `nn.Linear`), or `torch.func.functional_call` for
        other architectures.
        """
        with self._matmul_precision():
            if params is self.value_network_params:
                q_values = self._qnet_tensor_module(observation)
            elif self._qnet_layers is not None:
                q_values = observation
                for layer, key in self._qnet_layers:
                    if key is None:
                        q_values = layer(q_values)
                    else:
                        q_values = nn.functional.linear(q_values, params.get((*key, "weight")),
                                                        params.get((*key, "bias")))
            else:
                swapped = {name: params.get(("module", "0", "module", *name.split(".")))
                           for name in self._qnet_param_names}
                q_values = torch.func.functional_call(self._qnet_tensor_module, swapped, (observation,))
        return q_values.float()

    def bootstrap_value(self, next_observation: torch.Tensor, available: torch.Tensor) -> torch.Tensor:
        """max over available a' of Q_target(s', a'); with double DQN, Q_target(s', argmax_available Q_online).

        Without double DQN the online network never sees s': one target forward, no extra online forward.
        """
        target_q = self._q_values(next_observation, self.target_value_network_params)
        fill = torch.finfo(target_q.dtype).min
        if not self.double_dqn:
            return target_q.masked_fill(~available, fill).max(-1, keepdim=True).values
        online_q = self._q_values(next_observation, self.value_network_params)
        best = online_q.masked_fill(~available, fill).argmax(-1, keepdim=True)
        return torch.gather(target_q, -1, best)

    def td_loss(
        self,
        observation: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        terminated: torch.Tensor,
        next_observation: torch.Tensor,
        next_available: torch.Tensor,
        next_value: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(loss, Q(s, a), target y) on plain tensors: observation (B, F), action (B,), reward and terminated (B, 1),
        next_observation (B, F), next_available (B, A). The whole loss; `forward` is this plus TensorDict I/O.
        `next_value` (B, 1), when given, replaces `bootstrap_value(next_observation, next_available)` (a cache)."""
        q_values = self._q_values(observation, self.value_network_params)
        predicted = torch.gather(q_values, -1, action.unsqueeze(-1)).squeeze(-1)
        with torch.no_grad():
            if next_value is None:
                next_value = self.bootstrap_value(next_observation, next_available)
            # TorchRL's TD(0) return, with the gamma held by the value estimator: y = r + gamma * (1 - term) * V(s')
            target = td0_return_estimate(gamma=self.value_estimator.gamma, next_state_value=next_value,
                                         reward=reward, terminated=terminated).squeeze(-1)
        loss = distance_loss(predicted, target, self.loss_function).mean()
        return loss, predicted, target

    def td_loss_inputs(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, ...]:
        """The tensors `td_loss` reads, taken from a batch of transitions (the replay buffer's layout)."""
        keys = self.tensor_keys
        return (tensordict.get("observation"), tensordict.get(keys.action), tensordict.get(("next", keys.reward)),
                tensordict.get(("next", keys.terminated)), tensordict.get(("next", "observation")),
                tensordict.get(("next", keys.action_mask)))

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        """Loss on Q(s, a) against the masked one-step target; writes `td_error` for prioritised replay."""
        loss, predicted, target = self.td_loss(*self.td_loss_inputs(tensordict))
        with torch.no_grad():
            tensordict.set(self.tensor_keys.priority, (predicted - target).abs().unsqueeze(-1), inplace=True)
        return TensorDict(
            {"loss": loss, "q_mean": predicted.detach().mean(), "target_mean": target.mean()}, batch_size=[]
        )


class TargetValueCache:
    """Bootstrap values max_a' Q_target(s', a') of replay-buffer slots, kept while the target network is unchanged.

    Why: with hard target updates the target network is frozen for C gradient steps, and C sampled batches revisit
    the same slots (default config: C=100 x 1024 samples over 50K slots, ~2 visits per slot), so each slot's value
    is computed once per target copy instead of at every visit: a quarter of the update's multiply-adds are the
    target pass, and most of them go. A slot is identified by its index and the write stamp the storage gave it,
    so a rewritten slot is recomputed. Missing rows run through the same ops as a full batch; the row results of
    the matrix products do not depend on how many rows share them (MKL checked for 4 to 1500 rows and several layer
    sizes; fewer rows take another path with other bits, so products are padded to a multiple of CACHE_ROW_BLOCK
    rows), so the numbers are unchanged (tested bit for bit).
    The owner must `clear()` it whenever the target weights change.
    """

    def __init__(self, loss: CompetitiveDQNLoss) -> None:
        if loss.double_dqn:
            raise ValueError("TargetValueCache needs double_dqn=False: double DQN's bootstrap follows the online network")
        self.loss = loss
        self.values = torch.empty(0, 1)
        self.stamps = torch.empty(0, dtype=torch.long)
        self.looked_up = 0  # rows asked for since construction
        self.computed = 0  # rows that went through the target network

    def clear(self) -> None:
        self.stamps.fill_(-1)

    def _grow(self, size: int) -> None:
        if size <= len(self.stamps):
            return
        size = max(size, 2 * len(self.stamps))
        values, stamps = torch.zeros(size, 1), torch.full((size,), -1, dtype=torch.long)
        values[: len(self.values)], stamps[: len(self.stamps)] = self.values, self.stamps
        self.values, self.stamps = values, stamps

    def lookup(self, slots: torch.Tensor, stamps: torch.Tensor, next_observation: torch.Tensor,
               available: torch.Tensor) -> torch.Tensor:
        """(B, 1) bootstrap values of the sampled rows; rows whose slot is stale or unseen are computed and kept."""
        self._grow(int(slots.max()) + 1)
        missing = (self.stamps.index_select(0, slots) != stamps).nonzero().squeeze(-1)
        if len(missing):
            # products of a multiple of CACHE_ROW_BLOCK rows, padded with a repeated row: MKL takes another path for
            # 1-3 rows (other bits), and oneDNN (bf16) builds a kernel per new shape, so few distinct shapes
            padded = -(-len(missing) // CACHE_ROW_BLOCK) * CACHE_ROW_BLOCK
            rows = missing if padded == len(missing) else torch.cat(
                (missing, missing[:1].expand(padded - len(missing))))
            with torch.no_grad():
                values = self.loss.bootstrap_value(next_observation.index_select(0, rows),
                                                   available.index_select(0, rows))
            missing_slots = slots.index_select(0, rows)
            self.values.index_copy_(0, missing_slots, values)
            self.stamps.index_copy_(0, missing_slots, stamps.index_select(0, rows))
            self.computed += len(missing)
        self.looked_up += len(slots)
        return self.values.index_select(0, slots)


def make_target_updater(loss: CompetitiveDQNLoss, kind: str = "hard", period: int = 100, tau: float = 0.005):
    """TorchRL target updater: `hard` copies the online weights every `period` calls of `.step()`, `soft` uses tau.

    TorchRL's `HardUpdate(value_network_update_interval=k)` copies on every (k+1)-th call, hence `period - 1`.
    """
    if kind == "hard":
        if period < 1:
            raise ValueError(f"loss.target_period must be >= 1, got {period}")
        return HardUpdate(loss, value_network_update_interval=period - 1)
    if kind == "soft":
        if not 0.0 < tau <= 1.0:
            raise ValueError(f"loss.tau must be in (0, 1], got {tau}")
        return SoftUpdate(loss, tau=tau)
    raise ValueError(f"unknown target update {kind!r}; expected 'hard' or 'soft'")
