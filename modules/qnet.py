"""The Q-network: a plain fully connected ReLU network, as in the paper (3 hidden layers of 100 or 150 units)."""
from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase
from torch import nn
from torch.nn import functional as F

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


def mlp_layers(net: nn.Module) -> list[list] | None:
    """[weight, bias, ReLU after] per Linear of a Sequential of Linear/ReLU (``make_qnet``'s, or the value network
    of ``modules.value_net``), None otherwise.

    The searches read a network once per expansion on one position: at that size ``nn.Module.__call__`` costs as
    much as the matrix products, so they run the same ``F.linear``/``torch.relu`` ops on these tensors with
    ``mlp_forward`` (the same parameters, not copies: the same numbers as calling the network)."""
    if not isinstance(net, nn.Sequential):
        return None
    layers: list[list] = []
    for module in net:
        if isinstance(module, nn.Linear):
            layers.append([module.weight, module.bias, False])
        elif isinstance(module, nn.ReLU) and layers and not layers[-1][2]:
            layers[-1][2] = True
        else:
            return None
    return layers or None


def mlp_forward(layers: list[list], x: torch.Tensor) -> torch.Tensor:
    """The network of ``mlp_layers(net)`` applied to ``x``: its own ops, without ``nn.Module``'s call overhead."""
    for weight, bias, relu in layers:
        x = F.linear(x, weight, bias)
        if relu:
            x = torch.relu(x)
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
    `importlib.util.find_spec("pandas")` on each call: a search of sys.path when pandas is not installed
    (~60-130 us here), more than the whole MLP at the paper's batch of 2, paid twice per update and once per
    collector step.
    """

    def __init__(self, qnet: TensorDictModule | QValues) -> None:
        super().__init__()
        self.module = qnet.module  # `module`, as in TensorDictModule: the parameter paths stay the same
        self.in_keys, self.out_keys = list(qnet.in_keys), list(qnet.out_keys)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        tensordict.set(self.out_keys[0], self.module(*(tensordict.get(key) for key in self.in_keys)))
        return tensordict
