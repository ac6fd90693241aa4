"""`recurrent_dqn`: the competitive DQN loss on replayed slices of dialogues, unrolling a recurrent Q-network over
each slice (`agent.memory: gru | lstm`; the slices: `ncbot.modules.replay.sequences`), after Kapturowski et al. 2019
(R2D2).

- Targets: one unroll of the online and one of the target network (TorchRL's target parameters swapped in with
  `to_module`) over the L + 1 observations (obs_0, next_obs_0, ..., next_obs_{L-1}) gives Q(s_t) and Q(s_{t+1})
  from the same hidden-state history; the bootstrap value is the max over the next bootstrap mask of
  Q_target(s_{t+1}) (double DQN: a' picked by the online unroll), the target of `competitive_dqn`. TorchRL's value
  estimator turns the bootstrap values into returns along the slice: TD(0) (default: y_t = r_t + gamma * V(s_{t+1}),
  r_t alone on terminated steps), TD(1) or TD(lambda) (`loss.value_estimator`). The unroll needs the slice's first
  observation, which TorchRL's own next-state pass (`step_mdp`) drops, so the loss hands the estimator the
  bootstrap values (`next_value`), as TorchRL's `DQNLoss` does for double DQN. A slice that ends before L steps
  without its dialogue ending (the newest steps of a running dialogue) is cut there: its last step bootstraps.
- Burn-in (`buffer.burn_in` steps): the stored state was made by older weights; the first steps of a slice that
  starts inside a dialogue only refresh the state and carry no loss. Slices that start a dialogue (most of them
  on 3x3, whose dialogues are shorter than L) need none and train on every step. Unlike R2D2, the burn-in steps
  are unrolled with the rest (one unroll, gradients flow back through them): simpler, same targets.
- Board symmetries (`buffer.augment: d4`): one random symmetry per slice, the same for all its steps. The stored
  state belongs to the unturned game, so a turned slice starts from the zero state (the burn-in rebuilds it).
- Prioritised replay: the loss weights each slice by its importance weight and writes R2D2's sequence priority.
"""
from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictSequential
from torchrl.modules import GRUModule
from torchrl.objectives import LossModule, ValueEstimators, default_value_kwargs
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator, TD1Estimator, TDLambdaEstimator

from ncbot.modules.networks.qnet import OBSERVATION_KEY
from ncbot.modules.networks.recurrent import IS_INIT_KEY
from ncbot.modules.objectives.common import TransitionKeys, check_loss_function
from ncbot.modules.replay.prioritized_slices import sequence_priority
from ncbot.modules.replay.sequences import STEP_KEY, VALID_KEY

ESTIMATORS = {ValueEstimators.TD0: TD0Estimator, ValueEstimators.TD1: TD1Estimator,
              ValueEstimators.TDLambda: TDLambdaEstimator}


class RecurrentDQNLoss(LossModule):
    """The competitive DQN loss (same keys, same target) on slices of dialogues (see module doc)."""

    _AcceptedKeys = TransitionKeys
    default_keys = TransitionKeys
    default_value_estimator = ValueEstimators.TD0
    SUPPORTED_VALUE_ESTIMATORS = tuple(ESTIMATORS)
    replays = "sequences"  # what the run's replay buffer hands this loss: slices of dialogues
    out_keys = ["loss", "q_mean", "target_mean"]
    tensor_keys: TransitionKeys
    value_network: TensorDictSequential
    value_network_params: TensorDict
    target_value_network_params: TensorDict

    def __init__(self, value_network: TensorDictSequential, *, sequence_length: int, burn_in: int = 0,
                 loss_function: str = "l2", double_dqn: bool = False, symmetries=None) -> None:
        super().__init__()
        if not 0 <= burn_in < sequence_length:
            raise ValueError(f"buffer.burn_in must be >= 0 and < buffer.sequence_length ({sequence_length}), "
                             f"got {burn_in}")
        self.loss_function = check_loss_function(loss_function)
        self.double_dqn, self.sequence_length, self.burn_in = double_dqn, int(sequence_length), int(burn_in)
        self.symmetries = symmetries  # buffer.augment=d4: one board symmetry per slice
        self.state_keys = [key for key in value_network.in_keys if key not in (OBSERVATION_KEY, IS_INIT_KEY)]
        self.convert_to_functional(value_network, "value_network", create_target_params=True)

    @property
    def in_keys(self) -> list:
        """What `forward` reads from a replayed slice (with its set keys)."""
        keys = self.tensor_keys
        return [OBSERVATION_KEY, keys.action, *self.state_keys, STEP_KEY, ("next", OBSERVATION_KEY),
                ("next", keys.bootstrap_mask), ("next", keys.reward), ("next", keys.done), ("next", keys.terminated)]

    def make_value_estimator(self, value_type: ValueEstimators | None = None, **hyperparams) -> None:
        """TorchRL's TD(0), TD(1) or TD(lambda) estimator over the slice's time dimension, e.g. `gamma=0.7`
        (TD(lambda): and `lmbda=0.95`)."""
        value_type = value_type or self.default_value_estimator
        if value_type not in ESTIMATORS:
            raise ValueError(f"the recurrent_dqn objective takes the TD(0), TD(1) or TD(lambda) estimator, "
                             f"not {value_type.value}")
        self.value_type = value_type
        self._value_estimator = ESTIMATORS[value_type](**{**default_value_kwargs(value_type), **hyperparams},
                                                       value_network=None)
        self._forward_value_estimator_keys()

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        keys = self.tensor_keys
        if self._value_estimator is not None:
            self._value_estimator.set_keys(reward=keys.reward, done=keys.done, terminated=keys.terminated,
                                           steps_to_next_obs=keys.steps_to_next_obs)

    def _unroll(self, observations: torch.Tensor, states: dict[str, torch.Tensor]) -> torch.Tensor:
        """Q-values (B, T, A) of the network unrolled over `observations` (B, T, F) from `states` (B, ...).

        On the tensors: the MLP, then the torch RNN inside TorchRL's GRUModule / LSTMModule from the stored state,
        then the head: the operations `unroll_in_recurrent_mode` runs (tested bit-identical), without TorchRL's
        TensorDict bookkeeping, which cost as much as the GRU itself at one slice per update."""
        trunk, memory, head = self.value_network
        rnn = memory.gru if isinstance(memory, GRUModule) else memory.lstm
        initial = [states[key].transpose(0, 1).clone(memory_format=torch.contiguous_format) for key in self.state_keys]
        output, _ = rnn(trunk.module(observations), initial[0] if len(initial) == 1 else tuple(initial))
        return head.module(output).float()

    def _slices(self, batch: TensorDictBase) -> tuple[torch.Tensor, ...]:
        """(observations obs_0, next_obs_0, ..., next_obs_{L-1}; actions; next bootstrap masks; start states) of the
        slices, under one random board symmetry per slice with `symmetries`."""
        keys, length = self.tensor_keys, self.sequence_length
        rows = batch.shape[0]
        observation, next_observation = batch.get(OBSERVATION_KEY), batch.get(("next", OBSERVATION_KEY))
        action, next_mask = batch.get(keys.action), batch.get(("next", keys.bootstrap_mask))
        states = {key: batch.get(key)[:, 0] for key in self.state_keys}
        if self.symmetries is not None:  # one symmetry per slice; a turned slice starts from the zero state
            which = self.symmetries.draw(rows)
            steps_which = which.repeat_interleave(length)
            flat = rows * length
            observation = self.symmetries.observations(observation.reshape(flat, -1), steps_which).reshape(observation.shape)
            next_observation = self.symmetries.observations(next_observation.reshape(flat, -1),
                                                            steps_which).reshape(next_observation.shape)
            action = self.symmetries.actions(action.reshape(flat), steps_which).reshape(action.shape)
            next_mask = self.symmetries.masks(next_mask.reshape(flat, -1), steps_which).reshape(next_mask.shape)
            unturned = which == 0
            states = {key: value * unturned.reshape(-1, *([1] * (value.dim() - 1))) for key, value in states.items()}
        # within a slice next_obs_t is obs_{t+1}, and a padded slice's last real next observation sits right after
        # its last real step
        return torch.cat([observation[:, :1], next_observation], dim=1), action, next_mask, states

    def _bootstrap_values(self, q_all: torch.Tensor, sequence: torch.Tensor, next_mask: torch.Tensor,
                          states: dict[str, torch.Tensor]) -> torch.Tensor:
        """(B, L) max over the next bootstrap mask of the target unroll's Q(s_{t+1}) (double DQN: at the online
        unroll's best a')."""
        with self.target_value_network_params.to_module(self.value_network):
            q_next = self._unroll(sequence, states)[:, 1:]
        fill = torch.finfo(q_next.dtype).min
        if self.double_dqn:
            best = q_all[:, 1:].detach().masked_fill(~next_mask, fill).argmax(-1, keepdim=True)
            return q_next.gather(-1, best).squeeze(-1)
        return q_next.masked_fill(~next_mask, fill).max(-1).values

    def _trained_steps(self, batch: TensorDictBase) -> torch.Tensor:
        """(B, L) True on the steps that carry loss: real (not padding) and past the burn-in of a slice that starts
        inside its dialogue."""
        rows, length = batch.shape
        trained = batch.get(VALID_KEY, torch.ones(rows * length, dtype=torch.bool)).reshape(rows, length).clone()
        if self.burn_in:  # the first steps of a slice starting inside a dialogue only refresh its state
            inside = batch.get(STEP_KEY)[:, 0] > 0
            trained[:, :self.burn_in] &= ~inside.unsqueeze(1)
        return trained

    def _returns(self, batch: TensorDictBase, next_value: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        """(B, L) returns of the value estimator along each slice; a slice's last real step that neither ends its
        dialogue nor the slice is marked done there (a cut), so TD(1) and TD(lambda) bootstrap at it."""
        keys = self.tensor_keys
        if self.value_type is ValueEstimators.TD0:  # one step at a time: the slice's ends change nothing
            rows = batch.select(("next", keys.reward), ("next", keys.done), ("next", keys.terminated))
        else:
            last_real = valid & ~torch.cat([valid[:, 1:], torch.zeros_like(valid[:, :1])], dim=1)
            done = batch.get(("next", keys.done)).reshape(valid.shape) | last_real
            rows = batch.select(("next", keys.reward), ("next", keys.terminated)).set(("next", keys.done),
                                                                                      done.unsqueeze(-1))
        rows.set(("next", keys.reward), rows.get(("next", keys.reward)).float().reshape(*valid.shape, 1))
        return self.value_estimator.value_estimate(rows, next_value=next_value.unsqueeze(-1)).squeeze(-1)

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        keys, length = self.tensor_keys, self.sequence_length
        batch = tensordict.reshape(-1, length)  # the sampler's slices, one per row
        rows = batch.shape[0]
        sequence, action, next_mask, states = self._slices(batch)
        q_all = self._unroll(sequence, states)
        q_values = q_all[:, :length]
        with torch.no_grad():
            next_value = self._bootstrap_values(q_all, sequence, next_mask, states)
            valid = batch.get(VALID_KEY, torch.ones(rows * length, dtype=torch.bool)).reshape(rows, length)
            target = self._returns(batch, next_value, valid)
            trained = self._trained_steps(batch)
        predicted = q_values.gather(-1, action.unsqueeze(-1)).squeeze(-1)
        error = distance_loss(predicted, target, self.loss_function)
        weight = trained.float()
        count = weight.sum().clamp(min=1.0)
        importance = batch.get(keys.priority_weight, None)  # prioritised replay: one weight per slice, on its steps
        scaled = weight * importance.reshape(rows, length) if importance is not None else weight
        loss = (error * scaled).sum() / count
        with torch.no_grad():  # R2D2's sequence priority, written on every step of its slice
            priority = sequence_priority((predicted - target).detach(), trained)
            tensordict.set(keys.priority, priority.repeat_interleave(length).reshape(tensordict.shape).unsqueeze(-1),
                           inplace=True)
        return TensorDict({"loss": loss, "q_mean": (predicted.detach() * weight).sum() / count,
                           "target_mean": (target * weight).sum() / count}, batch_size=[])
