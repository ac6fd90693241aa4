"""A recurrent Q-network (`agent.memory: gru | lstm`) and the sequence replay it learns from (R2D2-style).

Why: the paper adds hand-made "temporal" features (the order of the moves) and names recurrent networks as the
comparison left for future work. With memory the network carries a hidden state through the dialogue and can
learn what the move order (or the dialogue so far) is worth itself; `env.temporal` stays a separate switch.

Network (`make_recurrent_qnet`): observation -> the MLP of `agent.hidden` (ReLU) -> TorchRL `GRUModule` /
`LSTMModule` (`agent.memory_size` units) -> linear head -> `action_value`, the key the look-ahead masks, the
policies and the loss read, so they work unchanged. Acting runs one step at a time: the hidden state lives in
the TensorDict under `recurrent_state` (LSTM: `recurrent_state_h`, `recurrent_state_c`), the module writes the
next one under ("next", ...), and the env, wrapped by `memory_env` in TorchRL's `InitTracker` + the module's
`make_tensordict_primer()`, carries it from step to step and marks `is_init` on every new dialogue (also on
the partial resets of the batched env, where the module zeros the state of the games that restart).

Sequence replay (`make_sequence_buffer`, `SequenceRows`, `SequenceDQNLoss`), choices after Kapturowski et al.
2019 (R2D2):
- Sequences, not transitions: TorchRL's `SliceSampler` cuts slices of `buffer.sequence_length` (L) steps out of
  one dialogue each, found by its id (`episode`) and step number (`step`) (`fragmented=True`: a dialogue's
  steps are interleaved with the other games' in the flat storage). Shorter dialogues (and what the circular
  buffer kept of a dialogue) give shorter slices, padded to L and masked (`("collector", "mask")`). A slice never
  crosses a dialogue boundary. A dialogue is drawn uniformly, then a start uniformly inside it.
- Stored state (R2D2's choice, better than zero state in its study): every step keeps the hidden state the
  actor had before it (`recurrent_state`), and the unroll of a slice starts from the stored state of its first
  step. A slice that starts a dialogue starts from the zero state, which is exact.
- Burn-in (`buffer.burn_in` steps): the stored state was made by older weights; the first steps of a slice that
  starts inside a dialogue only refresh the state and carry no loss. Slices that start a dialogue (most of them
  on 3x3, whose dialogues are shorter than L) need none and train on every step. Unlike R2D2, the burn-in steps
  are unrolled with the rest (one unroll, gradients flow back through them): simpler, same targets.
- Board symmetries (`buffer.augment: d4`): one random symmetry per slice, the same for all its steps. The stored
  state belongs to the unturned game, so a turned slice starts from the zero state (the burn-in rebuilds it).
- Targets: one unroll of the online and one of the target network over the L + 1 observations
  (obs_0, next_obs_0, ..., next_obs_{L-1}) gives Q(s_t) and Q(s_{t+1}) from the same hidden-state history;
  y_t = r_t + gamma * max over the next bootstrap mask of Q_target(s_{t+1}) (r_t alone on terminated steps),
  the target of `ncbot.modules.objectives.competitive_dqn.CompetitiveDQNLoss`; double DQN picks a' with the online unroll.
- Defaults L = 16, burn-in 4, 128 memory units: a 3x3 dialogue is ~10-15 acts, so most slices are whole
  dialogues; on Ultimate (~50-70 acts) the slices start inside dialogues and the burn-in matters.
- Prioritised replay (`buffer.prioritized`): slices drawn by R2D2's sequence priority
  (`ncbot.modules.replay.prioritized_slices`); the loss weights each slice by its importance weight and writes its priority.
Not combined with memory (one-line config errors): n-step returns, bf16, self-play and the search teacher (they
read the network as an MLP or the buffer as transitions).
"""
from __future__ import annotations

from collections.abc import Sequence
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import LazyTensorStorage, SliceSampler, TensorDictReplayBuffer
from torchrl.envs import Compose, EnvBase, InitTracker, TransformedEnv
from torchrl.modules import GRUModule, LSTMModule, set_recurrent_mode
from torchrl.modules.utils import get_primers_from_module
from torchrl.objectives import LossModule
from torchrl.objectives.utils import distance_loss

from ncbot.modules.objectives.competitive_dqn import LOSS_FUNCTIONS, PRIORITY_KEY, CompetitiveDQNLoss
from ncbot.modules.replay.prioritized_slices import PrioritizedSequenceSampler, sequence_priority
from ncbot.modules.networks.qnet import ACTION_VALUE_KEY, OBSERVATION_KEY, make_qnet, seeded_init

MEMORY_CHOICES = ("none", "gru", "lstm")
IS_INIT_KEY = "is_init"  # TorchRL's InitTracker key: True on the first step of a dialogue
EMBEDDING_KEY = "embedding"  # the MLP's output, the recurrent layer's input
MEMORY_KEY = "memory"  # the recurrent layer's output, the head's input
STATE_KEYS = {"gru": ("recurrent_state",), "lstm": ("recurrent_state_h", "recurrent_state_c")}
EPISODE_KEY = "episode"  # id of the dialogue a step belongs to (the frame index of its first step)
STEP_KEY = "step"  # the step's place in its dialogue (0 = first)
VALID_KEY = ("collector", "mask")  # SliceSampler's pad_output mask: True on real steps, False on padding


def check_memory(memory: str) -> str:
    if memory not in MEMORY_CHOICES:
        raise ValueError(f"unknown agent.memory {memory!r}; expected one of {', '.join(MEMORY_CHOICES)}")
    return memory


def make_recurrent_qnet(n_features: int, n_actions: int, hidden: Sequence[int] = (100, 100, 100),
                        memory: str = "gru", memory_size: int = 128) -> TensorDictSequential:
    """observation -> MLP (`hidden`, ReLU) -> GRU/LSTM (`memory_size`) -> linear head -> `action_value`."""
    if check_memory(memory) == "none":
        raise ValueError("make_recurrent_qnet builds agent.memory gru or lstm; use modules.networks.qnet.make_qnet for none")
    trunk = make_qnet(n_features, 1, hidden).module[:-1]  # the same Linear/ReLU stack, without the Q head
    width = int(hidden[-1])
    state = STATE_KEYS[memory]
    rnn_class = GRUModule if memory == "gru" else LSTMModule
    rnn = rnn_class(input_size=width, hidden_size=int(memory_size),
                    in_keys=[EMBEDDING_KEY, *state], out_keys=[MEMORY_KEY, *(("next", key) for key in state)])
    return TensorDictSequential(
        TensorDictModule(trunk, in_keys=[OBSERVATION_KEY], out_keys=[EMBEDDING_KEY]),
        rnn,
        TensorDictModule(nn.Linear(int(memory_size), n_actions), in_keys=[MEMORY_KEY], out_keys=[ACTION_VALUE_KEY]),
    )


def make_agent_qnet(n_features: int, n_actions: int, agent, seed: int | None = None) -> TensorDictModule:
    """The Q-network of an `agent` config section (`ncbot.pipelines.config.AgentConfig`): the paper's MLP for
    memory none (exactly `make_qnet`), else the recurrent network; `seed` re-initialises every weight from it."""
    memory = check_memory(getattr(agent, "memory", "none"))
    if memory == "none":
        qnet = make_qnet(n_features, n_actions, agent.hidden)
        if seed is not None:
            seeded_init(qnet, seed)
        return qnet
    qnet = make_recurrent_qnet(n_features, n_actions, agent.hidden, memory, agent.memory_size)
    if seed is not None:
        seeded_init(qnet, seed)  # the Linear layers, as for the MLP
        generator = torch.Generator().manual_seed(seed + 1)  # the recurrent weights, as PyTorch draws them
        for layer in qnet.modules():
            if isinstance(layer, nn.RNNBase):
                bound = 1.0 / layer.hidden_size ** 0.5
                with torch.no_grad():
                    for weight in layer.parameters():
                        weight.uniform_(-bound, bound, generator=generator)
    return qnet


def recurrent_qnet_shapes(n_features: int, n_actions: int, agent) -> dict[str, tuple[int, ...]]:
    """State-dict shapes of the recurrent network of `agent` (built on the meta device: no memory, no RNG)."""
    with torch.device("meta"):
        qnet = make_recurrent_qnet(n_features, n_actions, agent.hidden, agent.memory, agent.memory_size)
    return {key: tuple(value.shape) for key, value in qnet.state_dict().items()}


def is_recurrent(module) -> bool:
    """True when `module` (a policy or a Q-network) holds a TorchRL recurrent module."""
    return isinstance(module, nn.Module) and any(isinstance(m, (GRUModule, LSTMModule)) for m in module.modules())


def memory_env(env: EnvBase, policy) -> EnvBase:
    """`env` as a recurrent `policy` needs it: TorchRL's InitTracker (`is_init` on every new dialogue, partial
    resets included) and the primer of the policy's hidden state (its keys in the observation spec, so
    `step_mdp` carries ("next", state) to the next step and resets zero it). Unchanged for other policies."""
    if not is_recurrent(policy):
        return env
    return TransformedEnv(env, Compose(InitTracker(init_key=IS_INIT_KEY), get_primers_from_module(policy)))


def require_feedforward(config, what: str) -> None:
    """One-line error for the tools that read the Q-network on positions no dialogue led to (the Q-guided search's
    imagined moves, the `agent:` and `qmcts:` opponents' boards): a recurrent network has no hidden state there."""
    memory = getattr(config.agent, "memory", "none")
    if memory != "none":
        raise ValueError(f"{what} does not support agent.memory={memory} (it reads the Q-network on positions "
                         "without a dialogue history); ncbot eval, ladder without --search, play and robot do")


# --- sequence replay --------------------------------------------------------------------------------------------

def make_sequence_buffer(size: int, batch_size: int, sequence_length: int, device: torch.device | str = "cpu", *,
                         prioritized: bool = False, alpha: float = 0.6, beta: float = 0.4) -> TensorDictReplayBuffer:
    """TorchRL replay buffer whose `SliceSampler` draws `batch_size // sequence_length` slices of one dialogue
    each, padded to `sequence_length` (see module doc); `prioritized`: slices drawn by their R2D2 priority
    (`ncbot.modules.replay.prioritized_slices`)."""
    if batch_size % sequence_length:
        raise ValueError(f"buffer.batch_size ({batch_size}) must be a multiple of buffer.sequence_length "
                         f"({sequence_length}) with agent.memory")
    if prioritized:
        sampler = PrioritizedSequenceSampler(size, sequence_length, alpha, beta, traj_key=EPISODE_KEY, step_key=STEP_KEY)
    else:
        sampler = SliceSampler(slice_len=sequence_length, traj_key=EPISODE_KEY, step_key=STEP_KEY, fragmented=True,
                               strict_length=False, pad_output=True, truncated_key=None)
    return TensorDictReplayBuffer(storage=LazyTensorStorage(size, device=device), sampler=sampler,
                                  priority_key=PRIORITY_KEY, batch_size=batch_size)


class SequenceRows:
    """Collector batch (env rows, T) + its flat transitions -> the rows a sequence buffer stores: the transitions
    plus `is_init`, the hidden state before each step, the dialogue id (`episode`) and its step number (`step`).

    The dialogue id is the global frame index of the dialogue's first step: unique across batches and across a
    resume (the frame counter is restored with the buffer). The id of a dialogue still running at the end of a
    batch is carried to the next batch (this object's state, one number per env row)."""

    def __init__(self, memory: str) -> None:
        self.state_keys = STATE_KEYS[check_memory(memory)] if memory != "none" else ()
        self.current: torch.Tensor | None = None  # per env row: the id of its running dialogue
        self.steps: torch.Tensor | None = None  # per env row: the step number its next step will have

    def __call__(self, batch: TensorDictBase, transitions: TensorDictBase, frames_before: int) -> TensorDictBase:
        rows, steps = batch.shape
        is_init = batch.get(IS_INIT_KEY).reshape(rows, steps)
        frame = frames_before + torch.arange(rows * steps).reshape(rows, steps)
        if self.current is None or self.current.shape[0] != rows:
            self.current = torch.full((rows,), -1, dtype=torch.long)
        starts = torch.where(is_init, frame, torch.full_like(frame, -1))
        episode = torch.cat([self.current.unsqueeze(1), starts], dim=1).cummax(dim=1).values[:, 1:]
        if bool((episode < 0).any()):
            raise ValueError("a collected step belongs to no dialogue (no is_init seen before it): the env must be "
                             "wrapped by modules.networks.recurrent.memory_env")
        self.current = episode[:, -1].clone()
        # the step number counts from each dialogue's first step (also for one that began in an earlier batch)
        first_seen = torch.where(is_init, torch.arange(steps).expand(rows, steps), torch.full_like(frame, -1))
        last_start = first_seen.cummax(dim=1).values
        carried = self.steps if self.steps is not None and self.steps.shape[0] == rows else torch.zeros(rows, dtype=torch.long)
        step = torch.where(last_start >= 0, torch.arange(steps) - last_start,
                           carried.unsqueeze(1) + torch.arange(steps))
        self.steps = step[:, -1] + 1
        flat = transitions.set(IS_INIT_KEY, is_init.reshape(-1, 1))
        flat.set(EPISODE_KEY, episode.reshape(-1))
        flat.set(STEP_KEY, step.reshape(-1))
        for key in self.state_keys:
            flat.set(key, batch.get(key).reshape(rows * steps, *batch.get(key).shape[2:]))
        return flat


def unroll_in_recurrent_mode(qnet: TensorDictSequential, observations: torch.Tensor,
                             states: dict[str, torch.Tensor]) -> torch.Tensor:
    """Q-values (B, T, A) of `qnet` over slices that each start one dialogue from `states` (B, ...), through TorchRL's
    recurrent mode: the reference `SequenceDQNLoss` unrolls against (tests, bench/memory_cost.py)."""
    rows, steps = observations.shape[:2]
    is_init = torch.zeros(rows, steps, 1, dtype=torch.bool)
    is_init[:, 0] = True
    sequence = TensorDict({OBSERVATION_KEY: observations, IS_INIT_KEY: is_init}, batch_size=[rows, steps])
    for key, value in states.items():  # recurrent mode reads the first step's state only
        sequence.set(key, value.unsqueeze(1).expand(rows, steps, *value.shape[1:]))
    with set_recurrent_mode(True):
        return qnet(sequence).get(ACTION_VALUE_KEY).float()


def make_sequence_loss(qnet: TensorDictSequential, settings, symmetries=None) -> "SequenceDQNLoss":
    """The loss of a recurrent learner from `ncbot.modules.learner.LearnerSettings` (memory, sequence_length, burn_in,
    loss_function, double_dqn, gamma), reading the transitions' learning reward and bootstrap mask (`LOSS_KEYS`)."""
    from ncbot.modules.replay.transitions import LOSS_KEYS

    loss = SequenceDQNLoss(qnet, sequence_length=settings.sequence_length, burn_in=settings.burn_in,
                           loss_function=settings.loss_function, double_dqn=settings.double_dqn, symmetries=symmetries)
    loss.set_keys(**LOSS_KEYS)
    loss.make_value_estimator(gamma=settings.gamma)
    return loss


class SequenceDQNLoss(LossModule):
    """The competitive DQN loss (`ncbot.modules.objectives.competitive_dqn.CompetitiveDQNLoss`: same keys, same target) on slices of
    dialogues, unrolling the recurrent network over each slice (see module doc)."""

    _AcceptedKeys = CompetitiveDQNLoss._AcceptedKeys
    default_keys = _AcceptedKeys
    tensor_keys: CompetitiveDQNLoss._AcceptedKeys
    value_network: TensorDictSequential
    value_network_params: TensorDict
    target_value_network_params: TensorDict

    def __init__(self, qnet: TensorDictSequential, *, sequence_length: int, burn_in: int = 0,
                 loss_function: str = "l2", double_dqn: bool = False, symmetries=None) -> None:
        super().__init__()
        if loss_function not in LOSS_FUNCTIONS:
            raise ValueError(f"unknown loss_function {loss_function!r}; expected one of {sorted(LOSS_FUNCTIONS)}")
        if not 0 <= burn_in < sequence_length:
            raise ValueError(f"buffer.burn_in must be >= 0 and < buffer.sequence_length ({sequence_length}), "
                             f"got {burn_in}")
        self.loss_function = LOSS_FUNCTIONS[loss_function]
        self.double_dqn, self.sequence_length, self.burn_in = double_dqn, int(sequence_length), int(burn_in)
        self.symmetries = symmetries  # buffer.augment=d4: one board symmetry per slice
        self.state_keys = [key for key in qnet.in_keys if key not in (OBSERVATION_KEY, IS_INIT_KEY)]
        self.gamma = 0.99
        self.convert_to_functional(qnet, "value_network", create_target_params=True)

    def make_value_estimator(self, value_type=None, *, gamma: float = 0.99) -> None:
        """The TD(0) target's discount (the target is computed in `forward`, over the unrolled slice)."""
        self.gamma = float(gamma)

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        pass

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

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        keys, length = self.tensor_keys, self.sequence_length
        batch = tensordict.reshape(-1, length)  # the sampler's slices, one per row
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
        # obs_0, next_obs_0, ..., next_obs_{L-1}: within a slice next_obs_t is obs_{t+1}, and a padded slice's
        # last real next observation sits right after its last real step
        sequence = torch.cat([observation[:, :1], next_observation], dim=1)
        q_all = self._unroll(sequence, states)
        q_values = q_all[:, :length]
        with torch.no_grad():
            with self.target_value_network_params.to_module(self.value_network):
                q_next = self._unroll(sequence, states)[:, 1:]
            fill = torch.finfo(q_next.dtype).min
            if self.double_dqn:
                best = q_all[:, 1:].detach().masked_fill(~next_mask, fill).argmax(-1, keepdim=True)
                next_value = q_next.gather(-1, best).squeeze(-1)
            else:
                next_value = q_next.masked_fill(~next_mask, fill).max(-1).values
            reward = batch.get(("next", keys.reward)).reshape(rows, length).float()
            terminated = batch.get(("next", keys.terminated)).reshape(rows, length)
            target = reward + self.gamma * next_value * (~terminated).float()
            trained = batch.get(VALID_KEY, torch.ones(rows * length, dtype=torch.bool)).reshape(rows, length).clone()
            if self.burn_in:  # the first steps of a slice starting inside a dialogue only refresh its state
                inside = batch.get(STEP_KEY)[:, 0] > 0
                trained[:, :self.burn_in] &= ~inside.unsqueeze(1)
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

