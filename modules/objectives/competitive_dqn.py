"""`competitive_dqn`: the paper's competitive DQN loss (Algorithm 2) as a TorchRL `LossModule`, learnt from replayed
transitions, called as `loss_td = objective(td)`.

Target: y = r on terminated steps, else r + gamma^k * max over the next state's BOOTSTRAP MASK a' of the target
network's Q(s', a'), where k is the transition's `steps_to_next_obs` (1 unless n-step returns wrote it). The mask
is read from ("next", tensor_keys.bootstrap_mask): by default the env's ("next", "action_mask"), i.e. every
available action (the paper); training wires it with `set_keys` to ("next", "bootstrap_mask"), which
`ncbot.modules.replay.transitions` fills with the available or the greedy set (`loss.bootstrap`). The reward is read
from ("next", tensor_keys.reward), wired in training to ("next", "learning_reward"). The error is taken on Q(s, a)
(the paper's Q(s', a') in the error term is a typo). Optional double DQN: the online network picks a' inside the
mask, the target network scores it (handed to the estimator as `next_value`, as TorchRL's `DQNLoss` does).

The target network is the value network (Q-network + masked max) on TorchRL's target parameters
(`convert_to_functional(..., create_target_params=True)`), refreshed in place by `HardUpdate` (every C updates, the
paper) or `SoftUpdate`. TorchRL's TD(0) estimator runs it on the next states (`step_mdp`); n-step returns are TD(0)
over the window (`steps_to_next_obs`). TD(1) and TD(lambda) need whole sequences (`recurrent_dqn`). The estimator
runs a copy of the value network bound to the target parameters (`TargetNetwork`) rather than swapping them into
the value network at every update as `value_estimate(td, target_params=...)` does: the same bits, and at the
paper's batch of 2 the swap costs more than the target pass itself (bench/target_network.py, docs/learner-speed.md).

`precision="bf16"` runs the Q-network's products in bfloat16 under autocast on the network's device while weights,
gradients and the loss stay float32 (docs/learner-speed.md).
"""
from __future__ import annotations

import copy
from contextlib import nullcontext

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase, TensorDictSequential
from torchrl.objectives import LossModule, ValueEstimators, default_value_kwargs
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator

from ncbot.modules.networks.argmax import MaskedArgmax
from ncbot.modules.networks.qnet import ACTION_VALUE_KEY, QValues
from ncbot.modules.objectives.common import TransitionKeys, check_loss_function

PRECISIONS = ("fp32", "bf16")


class TargetNetwork(TensorDictModuleBase):
    """The value network on the target parameters, as the value estimator runs it: a copy of the Q-network whose
    parameters are the target tensors (TorchRL's `TensorDictBase.to_module`, kept bound: the target updater and
    `load_state_dict` write those tensors in place), then the masked max over the bootstrap mask, in one module.

    Kept out of the loss's module tree (TorchRL's estimator holds it, as it holds a value network): the loss's
    parameters and state_dict are unchanged. `follow` binds it again when the target tensors were replaced (the loss
    moved to another device or dtype)."""

    def __init__(self, value_network: TensorDictSequential, target_params: TensorDictBase, value_key: str) -> None:
        super().__init__()
        self._skeleton = [copy.deepcopy(value_network)]  # the copy the target tensors are bound to (a list: no submodule)
        self.qnet, self.masked_max = self._skeleton[0][0], value_network[1]
        self.in_keys, self.out_keys = [*self.qnet.in_keys, self.masked_max.mask_key], [value_key]
        self._first_key = next(iter(target_params.keys(True, True)))
        self.follow(target_params, force=True)

    def follow(self, target_params: TensorDictBase, force: bool = False) -> None:
        """Bind the copy to `target_params` unless it already runs on those very tensors."""
        if force or target_params.get(self._first_key).data_ptr() != self._bound.data_ptr():
            target_params.to_module(self._skeleton[0])
            self._skeleton[0].requires_grad_(False)
            self._bound = self._skeleton[0].get_parameter(".".join(self._first_key))

    def q_values(self, tensordict: TensorDictBase) -> torch.Tensor:
        return self.qnet.module(*(tensordict.get(key) for key in self.qnet.in_keys))

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        values = self.q_values(tensordict)
        masked = values.masked_fill(~tensordict.get(self.masked_max.mask_key), torch.finfo(values.dtype).min)
        tensordict.set(self.out_keys[0], masked.max(-1)[0].unsqueeze(-1))
        return tensordict


class CompetitiveDQNLoss(LossModule):
    """DQN loss whose bootstrap maximises only over the next state's bootstrap mask (see module doc)."""

    _AcceptedKeys = TransitionKeys
    default_keys = TransitionKeys
    default_value_estimator = ValueEstimators.TD0
    SUPPORTED_VALUE_ESTIMATORS = (ValueEstimators.TD0,)
    replays = "transitions"  # what the run's replay buffer hands this loss: single transitions
    out_keys = ["loss", "q_mean", "target_mean"]
    tensor_keys: TransitionKeys
    value_network: TensorDictSequential
    value_network_params: TensorDict
    target_value_network_params: TensorDict

    def __init__(self, value_network: TensorDictModule, *, loss_function: str = "l2", double_dqn: bool = False,
                 delay_value: bool = True, precision: str = "fp32") -> None:
        super().__init__()
        if precision not in PRECISIONS:
            raise ValueError(f"unknown precision {precision!r}; expected one of {list(PRECISIONS)}")
        if double_dqn and not delay_value:
            raise ValueError("double DQN needs a delayed target network (delay_value=True)")
        self.loss_function = check_loss_function(loss_function)
        self.double_dqn, self.precision, self.delay_value = double_dqn, precision, delay_value
        # Q-network followed by a masked max: run on a next state (observation + bootstrap mask) it writes the
        # greedy action inside the mask and max_{a' in mask} Q(s', a'): the bootstrap value
        network = TensorDictSequential(
            QValues(value_network),
            MaskedArgmax(ACTION_VALUE_KEY, self.tensor_keys.bootstrap_mask, "action", self.tensor_keys.value),
        )
        self.convert_to_functional(network, "value_network", create_target_params=delay_value)

    @property
    def in_keys(self) -> list:
        """What `forward` reads from a replayed batch (with its set keys)."""
        keys = self.tensor_keys
        observations = self.value_network[0].in_keys
        return [*observations, keys.action, *(("next", key) for key in observations),
                ("next", keys.bootstrap_mask), ("next", keys.reward), ("next", keys.done), ("next", keys.terminated)]

    def make_value_estimator(self, value_type: ValueEstimators | None = None, **hyperparams) -> None:
        """TorchRL's TD(0) estimator on the value network, e.g. `gamma=0.7` (n-step windows: gamma^k)."""
        value_type = value_type or self.default_value_estimator
        if value_type not in self.SUPPORTED_VALUE_ESTIMATORS:
            raise ValueError(f"learns from single replayed transitions: the TD(0) estimator only (n-step returns: "
                             f"loss.n_step), not {value_type.value}; TD(1) and TD(lambda) need whole sequences "
                             "(loss.objective=recurrent_dqn)")
        self.value_type = value_type
        # (read as a child module: the attribute would warn that no target updater exists yet, made right after)
        target_params = dict(self.named_children())["target_value_network_params"] if self.delay_value else \
            self.value_network_params.data
        target = TargetNetwork(self.value_network, target_params, self.tensor_keys.value)
        self._value_estimator = TD0Estimator(**{**default_value_kwargs(value_type), **hyperparams},
                                             value_network=target)
        self._forward_value_estimator_keys()

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        keys = self.tensor_keys
        masked_max = self.value_network[1]  # the max follows the bootstrap-mask key
        masked_max.mask_key = keys.bootstrap_mask
        masked_max.in_keys = [masked_max.value_key, keys.bootstrap_mask]
        self.value_network.in_keys = [*self.value_network[0].in_keys, keys.bootstrap_mask]
        if self._value_estimator is not None:
            target = self._value_estimator.value_network
            target.in_keys, target.out_keys = [*target.qnet.in_keys, keys.bootstrap_mask], [keys.value]
            self._value_estimator.set_keys(value=keys.value, reward=keys.reward, done=keys.done,
                                           terminated=keys.terminated, steps_to_next_obs=keys.steps_to_next_obs)

    def _matmul_precision(self):
        """bf16: autocast on the parameters' device runs the Linear layers' products in bfloat16 (on the CPU with
        AVX512_BF16 / AMX, faster than float32: docs/learner-speed.md); parameters, their gradients and everything
        after the Q-values stay float32."""
        if self.precision == "bf16":
            return torch.autocast(next(self.value_network.parameters()).device.type, dtype=torch.bfloat16)
        return nullcontext()

    def q_values(self, tensordict: TensorDictBase) -> torch.Tensor:
        """Q(s, .) of the online network on the rows' observations (float32, with gradients; other losses on the
        same network, e.g. the search teacher's margin loss, read it here)."""
        with self._matmul_precision():
            return self._online_q(tensordict).float()

    def _online_q(self, tensordict: TensorDictBase) -> torch.Tensor:
        """The online Q-network on the rows' observations: its module on the tensors of its in_keys, as `QValues`
        runs it, without a selected copy of the batch (the online parameters are the network's own)."""
        qnet = self.value_network[0]
        return qnet.module(*(tensordict.get(key) for key in qnet.in_keys))

    def _double_dqn_next_value(self, tensordict: TensorDictBase) -> torch.Tensor:
        """Double DQN's bootstrap value Q_target(s', argmax_{a' in mask} Q_online(s', a'))."""
        next_state = tensordict.get("next").select(*self.value_network.in_keys)
        online = self.value_network(next_state.copy())
        target = self.value_estimator.value_network.q_values(next_state)
        return torch.gather(target.float(), -1, online.get("action").unsqueeze(-1))

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        """Loss on Q(s, a) against the masked TD target; writes `td_error` (|Q - y|) for prioritised replay and,
        when the batch carries the sampler's `priority_weight`, weights each row's error by it (importance
        sampling, as TorchRL's DQNLoss does)."""
        estimator = self.value_estimator
        estimator.value_network.follow(self.target_value_network_params)
        with self._matmul_precision():
            q_values = self._online_q(tensordict).float()
            with torch.no_grad():  # TD(0) runs the target network on the next states (double DQN: handed its value)
                next_value = self._double_dqn_next_value(tensordict) if self.double_dqn else None
                target = estimator.value_estimate(tensordict, next_value=next_value).squeeze(-1)
        return self._td_loss(tensordict, q_values, target)

    def _td_loss(self, tensordict: TensorDictBase, q_values: torch.Tensor, target: torch.Tensor) -> TensorDict:
        """The error of Q(s, a) against the targets, each row weighted by its importance weight when prioritised;
        writes the rows' |TD error|."""
        keys = self.tensor_keys
        predicted = torch.gather(q_values, -1, tensordict.get(keys.action).unsqueeze(-1)).squeeze(-1)
        error = distance_loss(predicted, target.float(), self.loss_function)
        weight = tensordict.get(keys.priority_weight, None)
        loss = (error * weight.reshape(error.shape)).mean() if weight is not None else error.mean()
        with torch.no_grad():
            tensordict.set(keys.priority, (predicted - target).abs().unsqueeze(-1), inplace=True)
        return TensorDict({"loss": loss, "q_mean": predicted.detach().mean(), "target_mean": target.mean()},
                          batch_size=[])
