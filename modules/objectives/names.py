"""The built-in objectives' short names and where their classes live (light: the config validates names without
importing torch)."""
from __future__ import annotations

BUILT_IN = {
    "competitive_dqn": "ncbot.modules.objectives.competitive_dqn:CompetitiveDQNLoss",
    "recurrent_dqn": "ncbot.modules.objectives.recurrent_dqn:RecurrentDQNLoss",
}
VALUE_ESTIMATOR_NAMES = ("td0", "td1", "td_lambda")  # TorchRL's TD0, TD1, TDLambda (`loss.value_estimator`)


def default_objective(memory: str) -> str:
    """The objective of a run that names none: `recurrent_dqn` for a recurrent network, else `competitive_dqn`."""
    return "competitive_dqn" if memory == "none" else "recurrent_dqn"


def objective_name(name: str) -> str:
    """`loss.objective` as a config keeps it: a built-in name, a module path, or a file path made absolute."""
    from ncbot.fileio.import_path import absolute_import_path, is_import_path

    if name in BUILT_IN:
        return name
    if not is_import_path(name):
        raise ValueError(f"config key 'loss.objective' must be one of {', '.join(BUILT_IN)} or an import path "
                         f"(pkg.module:NameLoss or path/to/file.py:NameLoss), got {name!r}")
    return absolute_import_path(name, "loss.objective")
