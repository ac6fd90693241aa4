"""A position-value network for Ultimate: the leaf evaluator that lets the Q-guided search drop random playouts.

Why: the Q-guided search (``ncbot.modules.search.guided_mcts``) scores a leaf by a mix of the Q-network's value and
one random playout. The Q-values were learnt against a random user, and one playout is a coin toss, so that search
is weak against strong searchers (``mcts:10000``, docs/search.md "The value network"). This network is trained
(``ncbot.pipelines.train.value_training``) to predict the root value a plain UCT search finds from a position, so one
forward pass gives a leaf what a few hundred playouts would, without their noise (expert iteration's "search
as the target", with plain UCT as the expert).

Positions are those of the bitboard engine (``ncbot.envs.opponents.bitboards.UltimateBits``); features are seen from
the side to move: its marks and the other side's (81 + 81, subgrid-major: index 9 * subgrid + square), the
subgrids each side owns and the drawn ones (3 x 9), the subgrid the mover must play in (9, one-hot), a free-move
flag, the open subgrids where each side could complete a line with one mark (2 x 9) and whether that would
complete a line of subgrids (2): ``N_FEATURES`` = 219. The threats are what an MLP finds hard to compute from
marks: with them the error on held-out games is lower (docs/search.md, "The value network"). The network's output
is a logit; its sigmoid is the mover's expected score (win 1, draw 0.5, loss 0). The eight symmetries of the
square act on subgrids and squares alike (``ncbot.modules.replay.symmetry.square_symmetries``), so training sees every
position in eight orientations.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from ncbot.envs.opponents.bitboards import COMPLETING, ONGOING
from ncbot.envs.opponents.search import Node, Rand, RandomRollout, result_value
from ncbot.modules.networks.qnet import MLPReader
from ncbot.modules.replay.symmetry import square_symmetries

VALUE_FORMAT = "ncbot-value-v1"
VALUE_GAME = "ultimate"  # the game whose positions the networks score (features of its bitboards)
N_FEATURES = 219
DEFAULT_HIDDEN = (256, 256)
DEFAULT_PLAYOUT_WEIGHT = 0.0  # the network alone: docs/search.md "The value network" measures the mix

_BITS = tuple(tuple(float(mask >> p & 1) for p in range(9)) for mask in range(512))
_TARGET = tuple(tuple(1.0 if k == t else 0.0 for k in range(9)) + (0.0,) for t in range(9))
_FREE = (0.0,) * 9 + (1.0,)


def position_features(pos: tuple) -> list[float]:
    """The 219 features of an Ultimate bitboard position, seen from the side to move (see the module docstring)."""
    subs0, subs1, decided, macro0, macro1, target, turn, _, _ = pos
    if turn:
        subs0, subs1, macro0, macro1 = subs1, subs0, macro1, macro0
    bits = _BITS
    features: list[float] = []
    for mask in subs0:
        features += bits[mask]
    for mask in subs1:
        features += bits[mask]
    features += bits[macro0]
    features += bits[macro1]
    features += bits[decided & ~(macro0 | macro1)]
    features += _TARGET[target] if target >= 0 else _FREE
    completers = COMPLETING  # a threat where one of them is still empty
    threats0 = threats1 = 0
    for k in range(9):
        if not decided >> k & 1:
            free = ~(subs0[k] | subs1[k])
            if completers[subs0[k]] & free:
                threats0 |= 1 << k
            if completers[subs1[k]] & free:
                threats1 |= 1 << k
    features += bits[threats0]
    features += bits[threats1]
    features.append(1.0 if completers[macro0] & threats0 else 0.0)
    features.append(1.0 if completers[macro1] & threats1 else 0.0)
    return features


def feature_symmetries() -> torch.Tensor:
    """(8, 219) int64 gather maps: ``features[:, maps[g]]`` is the features of the position turned by symmetry g.

    A symmetry moves subgrid k to s[k] and square p to s[p] in every subgrid (row 0 is the identity)."""
    maps = []
    for image in square_symmetries(3).tolist():
        index = list(range(N_FEATURES))
        for k in range(9):
            for p in range(9):
                for plane in (0, 81):
                    index[plane + 9 * image[k] + image[p]] = plane + 9 * k + p
            for plane in (162, 171, 180, 189, 199, 208):  # owned by each side, drawn, the target, threats of each side
                index[plane + image[k]] = plane + k
        maps.append(index)
    return torch.tensor(maps)


def make_value_net(hidden: tuple[int, ...] | list[int] = DEFAULT_HIDDEN) -> nn.Sequential:
    """An MLP from the 219 features to one logit (the mover's expected score after a sigmoid)."""
    layers: list[nn.Module] = []
    width = N_FEATURES
    for size in hidden:
        layers += [nn.Linear(width, int(size)), nn.ReLU()]
        width = int(size)
    layers.append(nn.Linear(width, 1))
    return nn.Sequential(*layers)


def value_checkpoint(net: nn.Sequential, hidden: list[int], free_move: str, meta: dict[str, Any]) -> dict[str, Any]:
    """What ``ncbot train-value`` saves: tensors and plain values only (``torch.load(weights_only=True)``)."""
    return {"format": VALUE_FORMAT, "state_dict": net.state_dict(), "hidden": list(hidden), "free_move": free_move,
            "meta": meta}


def load_value_net(path: str, free_move: str) -> nn.Sequential:
    """The value network saved at ``path`` for the ``free_move`` rule; one-line errors for anything else."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"value network {path!r} not found (expected a value.pt written by ncbot train-value)")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # noqa: BLE001 - torch's unpickler raises anything on a foreign or truncated file
        raise ValueError(f"value network {path!r} is corrupt or not ncbot's (expected a value.pt written by "
                         "ncbot train-value)") from None
    if not isinstance(data, dict) or data.get("format") != VALUE_FORMAT or not {"state_dict", "hidden", "free_move"} <= set(data):
        raise ValueError(f"{path!r} is not an ncbot value network (expected format {VALUE_FORMAT}, written by "
                         "ncbot train-value)")
    if data["free_move"] != free_move:
        raise ValueError(f"value network {path!r} was trained on the {data['free_move']!r} free-move rule, the agent "
                         f"plays {free_move!r} (train one with ncbot train-value --free-move {free_move})")
    net = make_value_net(data["hidden"])
    try:
        net.load_state_dict(data["state_dict"])
    except (RuntimeError, KeyError) as error:
        raise ValueError(f"value network {path!r} does not fit its own hidden sizes {data['hidden']} "
                         f"({str(error).splitlines()[0][:80]})") from None
    return net.eval()


class ValueNetEvaluator:
    """Scores a leaf by the value network (``playout_weight`` > 0 mixes in one random playout); a finished game
    scores its result. Values are for ``node.mover``. It does not expand the leaf: the search's ``PUCT`` does
    that when it first descends from it (``GuidedMCTS.expand_visited``)."""

    def __init__(self, search: Any, net: nn.Sequential, playout_weight: float = DEFAULT_PLAYOUT_WEIGHT) -> None:
        if not 0.0 <= playout_weight <= 1.0:
            raise ValueError(f"playout_weight must be in [0, 1], got {playout_weight}")
        self.search, self.playout_weight = search, float(playout_weight)
        self.rollout = RandomRollout(search.engine)
        self.net, self._reader = net, MLPReader.of(net)  # torch's per-op cost exceeds the products at one position

    def value(self, pos: tuple) -> float:
        """The side to move's expected score in [0, 1]."""
        x = np.array(position_features(pos), dtype=np.float32)
        if self._reader is not None:
            logit = float(self._reader(x)[0])
        else:
            with torch.no_grad():
                logit = self.net(torch.from_numpy(x)).item()
        return 1.0 / (1.0 + math.exp(-logit))

    def evaluate(self, node: Node, rand: Rand) -> float:
        result = self.search.engine.result(node.pos)
        if result != ONGOING:
            return result_value(result, node.mover)
        value = 1.0 - self.value(node.pos)  # the network scores the side to move; the node belongs to its mover
        if self.playout_weight == 0.0:
            return value
        return (1.0 - self.playout_weight) * value + self.playout_weight * self.rollout.evaluate(node, rand)
