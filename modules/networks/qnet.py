"""The Q-network: a plain fully connected ReLU network, as in the paper (3 hidden layers of 100 or 150 units)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase
from torch import nn

OBSERVATION_KEY = "observation"
ACTION_VALUE_KEY = "action_value"


def make_qnet(n_features: int, n_actions: int, hidden: Sequence[int] = (100, 100, 100)) -> TensorDictModule:
    """Build the Q-network as a TensorDict module reading `observation` and writing raw `action_value`.

    Raw (unmasked) Q-values are kept under `action_value` so the logger can record what the network thinks of
    every action; the masks are applied later by the policy and the loss.
    """
    if n_features <= 0 or n_actions <= 0:
        raise ValueError(f"make_qnet needs positive sizes, got n_features={n_features}, n_actions={n_actions}")
    hidden = [int(h) for h in hidden]
    if not hidden or any(h <= 0 for h in hidden):
        raise ValueError(f"agent.hidden must be a non-empty list of positive layer sizes, got {hidden}")
    layers: list[nn.Module] = []
    width = n_features
    for units in hidden:
        layers += [nn.Linear(width, units), nn.ReLU()]
        width = units
    layers.append(nn.Linear(width, n_actions))
    return TensorDictModule(nn.Sequential(*layers), in_keys=[OBSERVATION_KEY], out_keys=[ACTION_VALUE_KEY])


class MLPReader:
    """One-position reads of a Linear/ReLU ``nn.Sequential`` in numpy (``make_qnet``'s network, the value network
    of ``ncbot.modules.search.value_net``): ``reader(x)`` for a (F,) float32 array is the network's output as a float32 array.

    Why: the searches read a network once per simulation on one position. At that size torch's per-op dispatch
    (``nn.Module.__call__``, autograd's no-grad guard, ``F.linear``) costs more than the products; numpy's
    matrix-vector products on the same float32 weights are faster (docs/search.md, "MCTS guided by the Q-network").
    The weights are copied when the reader is made: build it after the network is loaded or trained. Outputs
    agree with the network's to float32 rounding (the sums run in another order), not bit for bit."""

    def __init__(self, layers: list[tuple[np.ndarray, np.ndarray, bool]]) -> None:
        self.layers = layers

    @classmethod
    def of(cls, net: nn.Module) -> "MLPReader | None":
        """The reader of ``net`` if it is a Sequential of Linear layers each followed by at most one ReLU, else None."""
        if not isinstance(net, nn.Sequential):
            return None
        layers: list[list] = []
        for module in net:
            if isinstance(module, nn.Linear):
                # .cpu(): a network on a GPU is read from a CPU copy of its weights (a no-op on the CPU)
                weight = module.weight.detach().cpu().numpy().T.astype(np.float32, copy=True)
                layers.append([weight, module.bias.detach().cpu().numpy().astype(np.float32, copy=True), False])
            elif isinstance(module, nn.ReLU) and layers and not layers[-1][2]:
                layers[-1][2] = True
            else:
                return None
        return cls([tuple(layer) for layer in layers]) if layers else None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        for weight, bias, relu in self.layers:
            x = x @ weight
            x += bias
            if relu:
                np.maximum(x, 0.0, out=x)
        return x


def seeded_init(module: nn.Module, seed: int) -> None:
    """Re-initialise every Linear layer from one seed so a run's starting weights depend only on the seed."""
    generator = torch.Generator().manual_seed(seed)
    for layer in module.modules():
        if isinstance(layer, nn.Linear):
            bound = 1.0 / layer.in_features**0.5
            with torch.no_grad():
                layer.weight.uniform_(-bound, bound, generator=generator)
                layer.bias.uniform_(-bound, bound, generator=generator)


class QValues(TensorDictModuleBase):
    """The Q-network as the loss and the policies run it: reads and writes the same keys as its `TensorDictModule`,
    on the same `nn.Module` (same parameters, same ops, same state_dict keys), but sets its output directly.

    Why: tensordict 0.14's `TensorDictModule` passes every output through `TensorDict.from_any`, which runs
    `importlib.util.find_spec("pandas")` on each call: a search of sys.path when pandas is not installed, which
    costs more than the whole MLP at the paper's batch of 2, paid twice per update and once per collector step
    (docs/learner-speed.md).
    """

    def __init__(self, qnet: TensorDictModule | QValues) -> None:
        super().__init__()
        self.module = qnet.module  # `module`, as in TensorDictModule: the parameter paths stay the same
        self.in_keys, self.out_keys = list(qnet.in_keys), list(qnet.out_keys)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        tensordict.set(self.out_keys[0], self.module(*(tensordict.get(key) for key in self.in_keys)))
        return tensordict
