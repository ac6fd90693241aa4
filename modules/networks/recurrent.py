"""A recurrent Q-network (`agent.memory: gru | lstm`) and how the env carries its hidden state.

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

It learns from replayed slices of dialogues (`ncbot.modules.replay.sequences`) through the `recurrent_dqn`
objective (`ncbot.modules.objectives.recurrent_dqn`), after Kapturowski et al. 2019 (R2D2). Not combined with
memory (one-line config errors): n-step returns, bf16, self-play and the search teacher (they read the network as
an MLP or the buffer as transitions).
"""
from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.envs import Compose, EnvBase, InitTracker, TransformedEnv
from torchrl.modules import GRUModule, LSTMModule, set_recurrent_mode
from torchrl.modules.utils import get_primers_from_module

from ncbot.modules.networks.qnet import ACTION_VALUE_KEY, OBSERVATION_KEY, make_qnet, seeded_init

MEMORY_CHOICES = ("none", "gru", "lstm")
IS_INIT_KEY = "is_init"  # TorchRL's InitTracker key: True on the first step of a dialogue
EMBEDDING_KEY = "embedding"  # the MLP's output, the recurrent layer's input
MEMORY_KEY = "memory"  # the recurrent layer's output, the head's input
STATE_KEYS = {"gru": ("recurrent_state",), "lstm": ("recurrent_state_h", "recurrent_state_c")}


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


def unroll_in_recurrent_mode(qnet: TensorDictSequential, observations: torch.Tensor,
                             states: dict[str, torch.Tensor]) -> torch.Tensor:
    """Q-values (B, T, A) of `qnet` over slices that each start one dialogue from `states` (B, ...), through TorchRL's
    recurrent mode: the reference `RecurrentDQNLoss` unrolls against (tests, bench/memory_cost.py)."""
    rows, steps = observations.shape[:2]
    is_init = torch.zeros(rows, steps, 1, dtype=torch.bool)
    is_init[:, 0] = True
    sequence = TensorDict({OBSERVATION_KEY: observations, IS_INIT_KEY: is_init}, batch_size=[rows, steps])
    for key, value in states.items():  # recurrent mode reads the first step's state only
        sequence.set(key, value.unsqueeze(1).expand(rows, steps, *value.shape[1:]))
    with set_recurrent_mode(True):
        return qnet(sequence).get(ACTION_VALUE_KEY).float()
