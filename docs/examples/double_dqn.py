"""A user's objective for ncbot, outside the package: masked double DQN, as a TorchRL loss.

    ncbot train default --out runs/double loss.objective=docs/examples/double_dqn.py:MaskedDoubleDQNLoss

Double DQN (van Hasselt et al. 2016) lets the online network pick the next action and the target network score
it, which removes the max operator's over-estimation. Here the pick stays inside the next state's bootstrap mask
(the moves the agent may play there), as in ncbot's own `competitive_dqn`.

What ncbot asks of an objective (docs/learning.md, "Write your own objective"), all TorchRL's public API:
- a `LossModule` whose `__init__` takes the Q-network first (and, by keyword, any of the run's options it names:
  here `loss_function`);
- `_AcceptedKeys` with the keys it reads, which the run wires with `set_keys` (the learning reward, the bootstrap
  mask, the priority for prioritised replay), and `in_keys` listing what `forward` reads;
- target parameters from `convert_to_functional(..., create_target_params=True)` (TorchRL's `HardUpdate` /
  `SoftUpdate` refresh them);
- `make_value_estimator(value_type, gamma=...)`: a TorchRL value estimator (TD(0) here: n-step windows come
  with `steps_to_next_obs`);
- `forward(batch)` -> a TensorDict with `loss`, writing each row's |TD error| under the priority key.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase, TensorDictParams
from tensordict.nn import TensorDictModule
from torchrl.objectives import LossModule, ValueEstimators, default_value_kwargs
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator


class MaskedDoubleDQNLoss(LossModule):
    """Double DQN whose online argmax runs over the next state's bootstrap mask."""

    @dataclass
    class _AcceptedKeys:
        action: str = "action"
        action_value: str = "action_value"
        reward: str = "reward"
        done: str = "done"
        terminated: str = "terminated"
        bootstrap_mask: str = "action_mask"
        steps_to_next_obs: str = "steps_to_next_obs"
        priority: str = "td_error"
        priority_weight: str = "priority_weight"

    default_keys = _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0
    out_keys = ["loss"]
    value_network: TensorDictModule
    value_network_params: TensorDictParams
    target_value_network_params: TensorDictParams

    def __init__(self, value_network: TensorDictModule, *, loss_function: str = "l2") -> None:
        super().__init__()
        self.loss_function = {"huber": "smooth_l1"}.get(loss_function, loss_function)  # TorchRL's distance_loss name
        self.convert_to_functional(value_network, "value_network", create_target_params=True)

    @property
    def in_keys(self) -> list:
        keys, observations = self.tensor_keys, self.value_network.in_keys
        return [*observations, keys.action, *(("next", key) for key in observations), ("next", keys.bootstrap_mask),
                ("next", keys.reward), ("next", keys.done), ("next", keys.terminated)]

    def make_value_estimator(self, value_type: ValueEstimators | None = None, **hyperparams) -> None:
        value_type = value_type or self.default_value_estimator
        if value_type is not ValueEstimators.TD0:
            raise NotImplementedError(f"{type(self).__name__} learns from single transitions: TD(0) only")
        self._value_estimator = TD0Estimator(**{**default_value_kwargs(value_type), **hyperparams},
                                             value_network=None)
        self._forward_value_estimator_keys()

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        keys = self.tensor_keys
        if self._value_estimator is not None:
            self._value_estimator.set_keys(reward=keys.reward, done=keys.done, terminated=keys.terminated,
                                           steps_to_next_obs=keys.steps_to_next_obs)

    def _q(self, state: TensorDictBase, params: TensorDictParams) -> torch.Tensor:
        """Q(s, .) of the value network on `params` (the online or the target ones)."""
        with params.to_module(self.value_network):
            return self.value_network(state.select(*self.value_network.in_keys)).get(self.tensor_keys.action_value)

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        keys = self.tensor_keys
        q_values = self._q(tensordict, self.value_network_params)
        predicted = q_values.gather(-1, tensordict.get(keys.action).unsqueeze(-1))
        with torch.no_grad():
            next_state = tensordict.get("next")
            online = self._q(next_state, self.value_network_params.detach())
            mask = next_state.get(keys.bootstrap_mask)
            best = online.masked_fill(~mask, torch.finfo(online.dtype).min).argmax(-1, keepdim=True)
            next_value = self._q(next_state, self.target_value_network_params).gather(-1, best)
            target = self.value_estimator.value_estimate(tensordict, next_value=next_value)
        error = distance_loss(predicted, target, self.loss_function)
        weight = tensordict.get(keys.priority_weight, None)  # prioritised replay's importance weights
        loss = (error * weight.reshape(error.shape)).mean() if weight is not None else error.mean()
        tensordict.set(keys.priority, (predicted - target).abs().detach(), inplace=True)
        return TensorDict({"loss": loss}, batch_size=[])
