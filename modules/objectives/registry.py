"""Objectives by name (`loss.objective`): a built-in short name or a user's `pkg.mod:Name` / `path/to/file.py:Name`.

An objective is a TorchRL `LossModule` class that the training run builds and steps like TorchRL's DQN script does
(docs/learning.md, "Write your own objective"):
- `__init__(value_network, **options)`: the run's Q-network first; then, by keyword, each of `OPTIONS` its
  signature names (a setting the run changed from its default that the objective does not take is an error);
- `_AcceptedKeys` (`set_keys`): the run wires `reward` to the learning reward and, when accepted, `bootstrap_mask`
  to the bootstrap mask; `in_keys` lists what `forward` reads, checked against what the replay buffer holds;
- target parameters made by `convert_to_functional(..., create_target_params=True)`, stepped by TorchRL's
  `HardUpdate` / `SoftUpdate`;
- `make_value_estimator(value_type, gamma=..., [lmbda=...])`, `forward(batch)` returning a TensorDict with `loss`
  (or `loss_*` entries, summed), writing the rows' `priority` key when the buffer is prioritised;
- `replays`: "transitions" (single transitions, the default) or "sequences" (slices of dialogues, a recurrent
  network);
- with search targets: `q_values(batch)`, the online Q-values of a batch of labelled positions.
"""
from __future__ import annotations

import inspect
from collections.abc import Iterable
from typing import Any

from torchrl.objectives import LossModule, ValueEstimators

from ncbot.fileio.import_path import import_object, is_import_path
from ncbot.modules.objectives.common import PRIORITY_KEY
from ncbot.modules.objectives.names import BUILT_IN, VALUE_ESTIMATOR_NAMES, objective_name

REPLAYS = ("transitions", "sequences")
# the keyword arguments the run hands an objective's __init__ when it names them
OPTIONS = ("loss_function", "double_dqn", "precision", "sequence_length", "burn_in", "symmetries")
VALUE_ESTIMATORS = dict(zip(VALUE_ESTIMATOR_NAMES, (ValueEstimators.TD0, ValueEstimators.TD1, ValueEstimators.TDLambda)))
REQUIRED = ("forward", "make_value_estimator")


def objective_class(name: str) -> type[LossModule]:
    """The class `name` names, imported and checked (one-line ValueError naming what is missing)."""
    spec = BUILT_IN.get(name, name)
    if not is_import_path(spec):
        objective_name(spec)  # raises the one line naming the choices
    cls = import_object(spec, "objective")
    check_objective_class(cls, name)
    return cls


def check_objective_class(cls: Any, name: str) -> None:
    """`cls` is a TorchRL LossModule with what the training loop calls (see module doc)."""
    if not inspect.isclass(cls) or not issubclass(cls, LossModule):
        raise ValueError(f"objective {name}: {getattr(cls, '__name__', cls)!r} is not a TorchRL LossModule class "
                         "(subclass torchrl.objectives.LossModule)")
    for method in REQUIRED:
        if inspect.unwrap(getattr(cls, method)) is inspect.unwrap(getattr(LossModule, method)):
            raise ValueError(f"objective {name}: class {cls.__name__} lacks {method}() (docs/learning.md, "
                             "\"Write your own objective\")")
    fields = getattr(getattr(cls, "_AcceptedKeys", None), "__dataclass_fields__", {})
    if "reward" not in fields:
        raise ValueError(f"objective {name}: class {cls.__name__} declares no 'reward' in its _AcceptedKeys "
                         "dataclass (the run wires it to the learning reward with set_keys)")
    replays = getattr(cls, "replays", "transitions")
    if replays not in REPLAYS:
        raise ValueError(f"objective {name}: class {cls.__name__} replays {replays!r}; expected one of "
                         f"{', '.join(REPLAYS)}")


def objective_options(cls: type[LossModule], name: str, options: dict[str, Any], defaults: dict[str, Any]) -> dict:
    """The `options` the class's __init__ takes; a setting changed from its default (`defaults`) that it does not
    take is a ValueError naming it."""
    parameters = inspect.signature(cls.__init__).parameters
    takes_all = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values())
    taken = {key: value for key, value in options.items() if takes_all or key in parameters}
    for key, value in options.items():
        if key not in taken and key in defaults and value != defaults[key]:
            raise ValueError(f"objective {name}: class {cls.__name__} takes no {key!r} argument, so the run's "
                             f"{key}={value!r} cannot apply (leave it at {defaults[key]!r} or pick another objective)")
    return taken


def build_objective(cls: type[LossModule], name: str, value_network: Any, options: dict[str, Any], *,
                    keys: dict[str, str], value_estimator: str = "td0", **hyperparams) -> LossModule:
    """`cls(value_network, **options)`, its keys wired (`keys`, those it accepts) and its value estimator made;
    a constructor or estimator that refuses the run's settings is one line naming the objective."""
    if value_estimator not in VALUE_ESTIMATORS:
        raise ValueError(f"config key 'loss.value_estimator' must be one of {', '.join(VALUE_ESTIMATORS)}, "
                         f"got {value_estimator!r}")
    accepted = cls._AcceptedKeys.__dataclass_fields__
    try:
        objective = cls(value_network, **options)
        objective.set_keys(**{key: value for key, value in keys.items() if key in accepted})
        objective.make_value_estimator(VALUE_ESTIMATORS[value_estimator], **hyperparams)
    except (TypeError, ValueError, NotImplementedError) as error:
        raise ValueError(f"objective {name} ({cls.__name__}): {str(error).splitlines()[0]}") from None
    if not any(key.startswith("target_") and key.endswith("_params") for key, _ in objective.named_children()):
        raise ValueError(f"objective {name} ({cls.__name__}) has no target parameters: call "
                         "self.convert_to_functional(network, name, create_target_params=True) in __init__")
    return objective


def check_objective_keys(objective: LossModule, name: str, stored: Iterable, *, prioritized: bool) -> None:
    """Every key the objective reads (`in_keys`) is one the replayed rows hold (`stored`), and a prioritised buffer
    gets its `priority` key; one-line ValueError otherwise."""
    in_keys = getattr(objective, "in_keys", None)
    if not in_keys:
        raise ValueError(f"objective {name} ({type(objective).__name__}) declares no in_keys (the keys forward "
                         "reads from a replayed batch)")
    have = {_flat(key): key for key in stored}
    missing = [key for key in in_keys if _flat(key) not in have]
    if missing:
        held = ", ".join(repr(key) for key in sorted(have.values(), key=lambda key: _flat(key)))
        raise ValueError(f"objective {name} ({type(objective).__name__}) reads {missing[0]!r}, which the replayed "
                         f"rows do not hold (they hold: {held})")
    if prioritized and getattr(objective.tensor_keys, "priority", None) != PRIORITY_KEY:
        raise ValueError(f"objective {name} ({type(objective).__name__}) writes no {PRIORITY_KEY!r} priority, which "
                         "buffer.prioritized=true needs (declare priority in _AcceptedKeys, or set it false)")


def _flat(key: Any) -> tuple[str, ...]:
    return (key,) if isinstance(key, str) else tuple(key)
