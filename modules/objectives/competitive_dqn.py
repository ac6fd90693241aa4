"""Competitive DQN loss (paper, Algorithm 2) as a TorchRL `LossModule`, called as `loss_td = loss_module(td)`.

Target: y = r on terminated steps, else r + gamma^k * max over the next state's BOOTSTRAP MASK a' of the target
network's Q(s', a'), where k is the transition's `steps_to_next_obs` (1 unless n-step returns wrote it). The mask
is read from ("next", tensor_keys.bootstrap_mask): by default the env's ("next", "action_mask"), i.e. every
available action (the paper); training wires it with `set_keys` to ("next", "bootstrap_mask"), which
`modules/replay/transitions.py` fills with the available or the greedy set (`loss.bootstrap`). The reward is read from
("next", tensor_keys.reward), wired in training to ("next", "learning_reward"). The error is taken on Q(s, a) (the
paper's Q(s', a') in the error term is a typo). Optional double DQN: the online network picks a' inside the mask,
the target network scores it. The target network is `value_network` on TorchRL's target parameters (bound once
to a copy of it, `target_value_network`), run by the TD(0) value estimator, refreshed in place by `HardUpdate` (every
C updates, the paper) or `SoftUpdate`.

`precision="bf16"` runs the Q-network's products in bfloat16 under autocast on the network's device while weights, gradients and the
loss stay float32 (docs/learner-speed.md).
"""
from __future__ import annotations

import copy
from contextlib import nullcontext
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.objectives import HardUpdate, LossModule, SoftUpdate, ValueEstimators
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator

from ncbot.modules.networks.argmax import MaskedArgmax
from ncbot.modules.policies.masks import AVAILABLE_KEY
from ncbot.modules.networks.qnet import ACTION_VALUE_KEY, QValues

BOOTSTRAP_VALUE_KEY = "bootstrap_value"  # max of Q over the bootstrap mask, written by `value_network`
PRIORITY_KEY = "td_error"  # |Q(s, a) - y| per row, written by the loss for a prioritised replay buffer
LOSS_FUNCTIONS = {"l2": "l2", "mse": "l2", "huber": "smooth_l1", "smooth_l1": "smooth_l1"}
PRECISIONS = ("fp32", "bf16")


class CompetitiveDQNLoss(LossModule):
    """DQN loss whose bootstrap maximises only over the next state's bootstrap mask (see module doc)."""

    @dataclass
    class _AcceptedKeys:
        """Keys read from the sampled transitions (reward, done, terminated and bootstrap_mask under "next")."""

        action: str = "action"
        reward: str = "reward"
        done: str = "done"
        terminated: str = "terminated"
        bootstrap_mask: str = AVAILABLE_KEY
        steps_to_next_obs: str = "steps_to_next_obs"
        value: str = BOOTSTRAP_VALUE_KEY
        action_value: str = ACTION_VALUE_KEY
        priority: str = PRIORITY_KEY
        priority_weight: str = "priority_weight"

    default_keys = _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0
    tensor_keys: _AcceptedKeys
    value_network: TensorDictSequential
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
        # Q-network followed by a masked max: run on a next state (observation + bootstrap mask) it writes the
        # greedy action inside the mask and max_{a' in mask} Q(s', a'): the bootstrap value.
        value_network = TensorDictSequential(
            QValues(qnet),
            MaskedArgmax(ACTION_VALUE_KEY, self.tensor_keys.bootstrap_mask, "action", BOOTSTRAP_VALUE_KEY),
        )
        self.convert_to_functional(value_network, "value_network", create_target_params=delay_value)
        self._bind_target_network()

    def _bind_target_network(self) -> None:
        """`target_value_network`: a copy of `value_network` whose parameters ARE the target parameters (the same
        tensors, which the target updater and `load_state_dict` write in place); the value estimator runs it.

        Why: given `target_params`, TorchRL's estimator swaps them into `value_network` (`to_module`) and back at
        every update, ~60 us: more than the target pass itself at the paper's batch of 2. Same modules, same
        tensors, same ops, so the same bits. Kept out of the module tree (as TorchRL keeps `value_network`): the
        state_dict and the optimised parameters are unchanged. Without a delayed target it is `value_network`."""
        if self.delay_value:
            target = copy.deepcopy(self.value_network)
            # read from _modules: the attribute warns while no target updater is associated yet (the Learner makes
            # it after the loss); to_module not as a context: the target tensors stay bound
            self._modules["target_value_network_params"].to_module(target)
            target.requires_grad_(False)  # (to_module wraps them as Parameters sharing their storage)
        else:
            target = self.value_network
        self.__dict__["target_value_network"] = target
        # autocast follows the parameters' device (bf16 products on the CPU's AVX512_BF16/AMX or a GPU's tensor cores)
        first = next(iter(self.value_network.parameters()), None)
        self.__dict__["autocast_type"] = first.device.type if first is not None else "cpu"
        if self._value_estimator is not None:
            self._value_estimator.__dict__["value_network"] = target  # as TorchRL stores it: not a submodule

    def _apply(self, fn, *args, **kwargs):
        """`.to(...)`, `.double()`, ... give the target parameters new tensors: bind the target network to them."""
        module = super()._apply(fn, *args, **kwargs)
        if "target_value_network" in self.__dict__:  # (not while the loss is being built)
            self._bind_target_network()
        return module

    @property
    def _qnet(self) -> QValues:
        return self.value_network[0]

    def make_value_estimator(self, value_type: ValueEstimators | None = None, **hyperparams) -> None:
        """Build the TD(0) estimator (the only one that matches the paper's one-step target), e.g. gamma=0.7."""
        value_type = value_type or self.default_value_estimator
        if value_type is not ValueEstimators.TD0:
            raise ValueError(f"CompetitiveDQNLoss supports only the TD0 value estimator, got {value_type}")
        self._value_estimator = TD0Estimator(**hyperparams, value_network=self.target_value_network)
        self._forward_value_estimator_keys()

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        keys = self.tensor_keys
        target = self.__dict__.get("target_value_network")
        networks = [self.value_network] + ([target] if target is not None and target is not self.value_network else [])
        for network in networks:
            masked_max = network[1]  # the target's max follows the bootstrap-mask key
            masked_max.mask_key = keys.bootstrap_mask
            masked_max.in_keys = [masked_max.value_key, keys.bootstrap_mask]
            network.in_keys = [*network[0].in_keys, keys.bootstrap_mask]
        if self._value_estimator is not None:
            self._value_estimator.set_keys(value=keys.value, reward=keys.reward, done=keys.done,
                                           terminated=keys.terminated, steps_to_next_obs=keys.steps_to_next_obs)

    def _matmul_precision(self):
        """bf16: autocast on the parameters' device runs the Linear layers' products in bfloat16 (on the CPU,
        AVX512_BF16 / AMX do them ~2x faster than float32); parameters, their gradients and everything after the
        Q-values stay float32."""
        if self.precision == "bf16":
            return torch.autocast(self.autocast_type, dtype=torch.bfloat16)
        return nullcontext()

    def _double_dqn_next_value(self, tensordict: TensorDictBase) -> torch.Tensor | None:
        """Double DQN's bootstrap value Q_target(s', argmax_{a' in mask} Q_online(s', a')); None otherwise, and the
        value estimator runs `target_value_network` (max over the mask)."""
        if not self.double_dqn:
            return None
        next_state = tensordict.get("next").select(*self.value_network.in_keys)
        online = self.value_network(next_state.copy())  # the online parameters are the Q-network's own
        target = self.target_value_network[0](next_state.copy())
        return torch.gather(target.get(ACTION_VALUE_KEY).float(), -1, online.get("action").unsqueeze(-1))

    def q_values(self, tensordict: TensorDictBase) -> torch.Tensor:
        """Q(s, .) of the online network on the rows' observations (float32, with gradients; other losses on the
        same network, e.g. the search teacher's margin loss, read it here)."""
        with self._matmul_precision():
            return self._online_q(tensordict).float()

    def _online_q(self, tensordict: TensorDictBase) -> torch.Tensor:
        """The online Q-network on the rows' observations: its module on the tensors of its in_keys, as `QValues`
        runs it, without a selected copy of the batch (same module, same inputs, same bits)."""
        qnet = self._qnet
        return qnet.module(*(tensordict.get(key) for key in qnet.in_keys))

    def _bootstrap_value(self, tensordict: TensorDictBase) -> torch.Tensor:
        """max over the next state's bootstrap mask of the target network's Q(s', a'), shape [..., 1].

        What TD(0)'s `_next_value` computes by running `target_value_network` on `step_mdp(tensordict)`, done on the
        tensors: the same modules, inputs and ops (QValues' module, then MaskedArgmax's fill and max), so the same
        bits, without the step_mdp copy and two TensorDict passes, which cost more than the products themselves
        at the paper's batch of 2. The estimator still computes the return from it."""
        qnet, best = self.target_value_network[0], self.target_value_network[1]
        next_state = tensordict.get("next")
        values = qnet.module(*(next_state.get(key) for key in qnet.in_keys))
        masked = values.masked_fill(~next_state.get(best.mask_key), torch.finfo(values.dtype).min)
        return masked.max(-1)[0].unsqueeze(-1)

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        """Loss on Q(s, a) against the masked TD(0) target; writes `td_error` (|Q - y|) for prioritised replay and,
        when the batch carries the sampler's `priority_weight`, weights each row's error by it (importance
        sampling, as TorchRL's DQNLoss does)."""
        keys = self.tensor_keys
        with self._matmul_precision():
            q_values = self._online_q(tensordict).float()
            with torch.no_grad():
                next_value = self._double_dqn_next_value(tensordict)
                if next_value is None:
                    next_value = self._bootstrap_value(tensordict)
                target = self.value_estimator.value_estimate(tensordict, next_value=next_value).squeeze(-1)
        predicted = torch.gather(q_values, -1, tensordict.get(keys.action).unsqueeze(-1)).squeeze(-1)
        error = distance_loss(predicted, target.float(), self.loss_function)
        weight = tensordict.get(keys.priority_weight, None)
        loss = (error * weight.reshape(error.shape)).mean() if weight is not None else error.mean()
        with torch.no_grad():
            tensordict.set(keys.priority, (predicted - target).abs().unsqueeze(-1), inplace=True)
        return TensorDict({"loss": loss, "q_mean": predicted.detach().mean(), "target_mean": target.mean()},
                          batch_size=[])


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
