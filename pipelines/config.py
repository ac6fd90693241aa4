"""Typed run configuration, grouped by concern like TorchRL's sota configs, loaded from YAML and validated.

Every hyper-parameter is named and documented here, in one place (CleanRL style). `load_config(path, overrides)`
reads a YAML file, applies `section.key=value` overrides and raises `ValueError` with ONE line naming the bad key
and what is allowed; the CLI turns that into exit code 2.
"""
from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from pipelines.selfplay import SelfPlayConfig

GAMES = ("standard", "ultimate")
AGENTS = ("dqn_original", "dqn_variant", "proposed")


@dataclass
class EnvConfig:
    """The dialogue game the robot learns (envs.make_env)."""

    game: Literal["standard", "ultimate"] = "standard"
    temporal: bool = True  # the paper's 9/81 temporal features
    free_move: Literal["anywhere", "open_subgrids"] = "anywhere"  # ultimate rule variant
    batch_size: int = 128  # games played in parallel by one batched env
    first: str = "alternate"  # who starts while training: robot | human | alternate | random
    opponent: str = "random"  # envs.opponents name of the simulated user's move policy
    max_steps: int = 100  # actions per dialogue before truncation (paper: 100)
    options: dict[str, Any] = field(default_factory=dict)  # extra keyword arguments for envs.make_env


@dataclass
class AgentConfig:
    """Which learner: the paper's three agents, each with its own look-ahead masks."""

    name: Literal["dqn_original", "dqn_variant", "proposed"] = "proposed"
    lookahead: str | None = None  # mask rule override (modules.masks); None = the agent's own rule
    hidden: list[int] = field(default_factory=lambda: [100, 100, 100])  # paper: 3 x 100 (or 150 on ultimate)


@dataclass
class CollectorConfig:
    """How experience is gathered (TorchRL Collector) and how exploration anneals."""

    frames_per_batch: int = 1024  # env frames (robot actions) per collected batch
    total_frames: int = 100_000  # training length in frames (paper: 400K steps)
    init_random_frames: int = 1_000  # burn-in: updates start once the buffer holds this many frames
    eps_init: float = 1.0
    eps_end: float = 0.005  # paper: minimum epsilon 0.005
    annealing_frames: int = 20_000  # frames over which epsilon decays linearly


@dataclass
class BufferConfig:
    """Experience replay (TensorDictReplayBuffer over LazyTensorStorage)."""

    size: int = 10_000  # paper: 10,000
    batch_size: int = 128  # sampled transitions per update (paper: 2)
    # each sampled transition seen under a random rotation/reflection of the board (modules/symmetry.py): none | d4
    augment: Literal["none", "d4"] = "none"


@dataclass
class OptimConfig:
    """Adam on the Q-network; the paper does not state these, so they are ours."""

    lr: float = 1e-3
    updates_per_batch: int = 8  # gradient updates per collected batch
    max_grad_norm: float = 10.0
    weight_decay: float = 0.0
    # matrix products of the learner's forward/backward: fp32, or bf16 (CPU autocast, float32 weights, gradients and
    # loss kept); bf16 changes the numbers of a seed, hence off by default (docs/learner-speed.md)
    precision: Literal["fp32", "bf16"] = "fp32"


@dataclass
class ScheduleConfig:
    """Learning-rate schedule over the training frames (optim.lr is the start value)."""

    lr_end: float | None = None  # decay lr linearly to this by collector.total_frames; quiets Q near convergence


@dataclass
class LossConfig:
    """Competitive DQN target and error."""

    gamma: float = 0.7  # paper: 0.7
    reward: Literal["paper", "outcome"] = "paper"  # what the learner trains on (modules.rewards); metrics use paper
    # outcome reward for a lost game (paper scale: -5). Against the random user a -5 loss is worth risking for a
    # likelier fast win (exact expectimax robot-second: 0.9291 wins, 0.0042 losses); <= -15 makes the optimum
    # loss-free (0.9164 wins, zero losses), which is what task success 1.000 asks for.
    loss_reward: float = -5.0  # used with reward: outcome only
    loss_function: Literal["l2", "huber"] = "l2"  # paper: squared error
    double_dqn: bool = False
    target_update: Literal["hard", "soft"] = "hard"  # paper: hard copy every C updates
    target_period: int = 50  # C, in gradient updates (hard)
    tau: float = 0.005  # soft update rate
    # n-step returns (modules/nstep.py): the target sums n discounted rewards before bootstrapping with gamma**n;
    # 1 = the paper's one-step target. Why: Ultimate's outcome reward reaches the opening ~16 decisions back.
    n_step: int = 1
    # which next actions the TD target maximises over (modules/bootstrap.py): every available one (the paper) or
    # only the agent's greedy set, the actions it can actually play; untrained actions outside it inflate targets
    bootstrap: Literal["available", "greedy"] = "available"


@dataclass
class TrainConfig:
    """Run-level settings."""

    seed: int = 0
    episodes: int | None = None  # stop after this many finished training dialogues (paper: 20K games); None = frames
    eval_every_frames: int = 10_000  # periodic greedy evaluation (logged with its wall time)
    num_threads: int = 1  # torch threads: small tensors are fastest on one thread


@dataclass
class EvalConfig:
    """Greedy test games against the simulated user (paper: 3000)."""

    games: int = 3000  # final evaluation
    periodic_games: int = 500  # each periodic evaluation during training
    seat: Literal["first", "second", "alternate"] = "alternate"
    opponent: str = "random"


@dataclass
class LoggerConfig:
    """What a run records besides checkpoints."""

    mcap: bool = True  # every episode to MCAP (logs package)
    progress: bool = True  # tqdm bar


@dataclass
class CheckpointConfig:
    """Periodic checkpoints (atomic write + rename) that `--resume` continues from."""

    every_frames: int = 10_000
    keep: int = 2  # periodic checkpoints kept on disk
    save_buffer: bool = True  # include the replay buffer so a resumed run continues with the same experience


@dataclass
class RunConfig:
    """One training run: every section of the YAML file."""

    env: EnvConfig = field(default_factory=EnvConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    collector: CollectorConfig = field(default_factory=CollectorConfig)
    buffer: BufferConfig = field(default_factory=BufferConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    schedule: ScheduleConfig = field(default_factory=ScheduleConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    checkpoint: CheckpointConfig = field(default_factory=CheckpointConfig)
    selfplay: SelfPlayConfig = field(default_factory=SelfPlayConfig)  # pipelines/selfplay.py

    @property
    def lookahead(self) -> str:
        """The mask rule this run uses: the override, else the agent's own."""
        from modules.masks import AGENT_LOOKAHEAD

        return self.agent.lookahead or AGENT_LOOKAHEAD[self.agent.name]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _type_name(annotation: Any) -> str:
    origin = typing.get_origin(annotation)
    if origin is Literal:
        return "one of " + ", ".join(repr(v) for v in typing.get_args(annotation))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(annotation))
    if annotation is type(None):
        return "null"
    if origin is list:
        return f"a list of {_type_name(typing.get_args(annotation)[0])}"
    if origin is dict:
        return "a mapping"
    return {int: "an integer", float: "a number", bool: "true/false", str: "a string"}.get(annotation, str(annotation))


def _coerce(value: Any, annotation: Any, key: str) -> Any:
    """Check `value` against `annotation`; ints are accepted where floats are expected. One-line error otherwise."""
    origin = typing.get_origin(annotation)
    wrong = ValueError(f"config key '{key}' must be {_type_name(annotation)}, got {value!r}")
    if origin is Literal:
        if value not in typing.get_args(annotation):
            raise wrong
        return value
    if origin in (typing.Union, types.UnionType):
        for option in typing.get_args(annotation):
            try:
                return _coerce(value, option, key)
            except ValueError:
                continue
        raise wrong
    if annotation is type(None):
        if value is not None:
            raise wrong
        return None
    if origin is list:
        if not isinstance(value, list):
            raise wrong
        (item,) = typing.get_args(annotation)
        return [_coerce(v, item, f"{key}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        if not isinstance(value, dict):
            raise wrong
        return dict(value)
    if annotation is bool:
        if not isinstance(value, bool):
            raise wrong
        return value
    if annotation is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise wrong
        return value
    if annotation is float:
        if isinstance(value, str):  # YAML 1.1 reads 5e-4 (no dot) as a string
            try:
                return float(value)
            except ValueError:
                raise wrong from None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise wrong
        return float(value)
    if annotation is str:
        if not isinstance(value, str):
            raise wrong
        return value
    raise wrong


def _build(cls: type, data: Any, prefix: str) -> Any:
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ValueError(f"config section '{prefix or 'root'}' must be a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in data.items():
        full = f"{prefix}.{key}" if prefix else str(key)
        if key not in names:
            raise ValueError(f"unknown config key '{full}'; allowed: {', '.join(names)}")
        annotation = hints[key]
        if dataclasses.is_dataclass(annotation):
            kwargs[key] = _build(annotation, value, full)
        else:
            kwargs[key] = _coerce(value, annotation, full)
    return cls(**kwargs)


def _check_values(config: RunConfig) -> None:
    """Range checks the types cannot express."""
    positive = {
        "env.batch_size": config.env.batch_size,
        "env.max_steps": config.env.max_steps,
        "collector.frames_per_batch": config.collector.frames_per_batch,
        "collector.total_frames": config.collector.total_frames,
        "collector.annealing_frames": config.collector.annealing_frames,
        "buffer.size": config.buffer.size,
        "buffer.batch_size": config.buffer.batch_size,
        "optim.updates_per_batch": config.optim.updates_per_batch,
        "loss.target_period": config.loss.target_period,
        "loss.n_step": config.loss.n_step,
        "train.eval_every_frames": config.train.eval_every_frames,
        "train.num_threads": config.train.num_threads,
        "eval.games": config.eval.games,
        "eval.periodic_games": config.eval.periodic_games,
        "checkpoint.every_frames": config.checkpoint.every_frames,
        "checkpoint.keep": config.checkpoint.keep,
    }
    for key, value in positive.items():
        if value <= 0:
            raise ValueError(f"config key '{key}' must be > 0, got {value}")
    if config.train.episodes is not None and config.train.episodes <= 0:
        raise ValueError(f"config key 'train.episodes' must be > 0 or null, got {config.train.episodes}")
    if config.agent.hidden and any(h <= 0 for h in config.agent.hidden) or not config.agent.hidden:
        raise ValueError(f"config key 'agent.hidden' must be a non-empty list of positive integers, got {config.agent.hidden}")
    for key, value in {"collector.eps_init": config.collector.eps_init, "collector.eps_end": config.collector.eps_end,
                       "loss.gamma": config.loss.gamma, "loss.tau": config.loss.tau}.items():
        if not 0.0 <= value <= 1.0:
            raise ValueError(f"config key '{key}' must be between 0 and 1, got {value}")
    if config.optim.lr <= 0:
        raise ValueError(f"config key 'optim.lr' must be > 0, got {config.optim.lr}")
    if config.loss.loss_reward >= 0:
        raise ValueError(f"config key 'loss.loss_reward' must be < 0, got {config.loss.loss_reward}")
    if config.schedule.lr_end is not None and not 0 < config.schedule.lr_end <= config.optim.lr:
        raise ValueError(f"config key 'schedule.lr_end' must be > 0 and <= optim.lr ({config.optim.lr}), "
                         f"got {config.schedule.lr_end}")
    if config.collector.init_random_frames < 0:
        raise ValueError(f"config key 'collector.init_random_frames' must be >= 0, got {config.collector.init_random_frames}")
    if config.env.first not in ("robot", "human", "alternate", "random"):
        raise ValueError(f"config key 'env.first' must be one of 'robot', 'human', 'alternate', 'random', got {config.env.first!r}")
    config.selfplay.check()
    from modules.masks import LOOKAHEAD_RULES

    if config.agent.lookahead is not None and config.agent.lookahead not in LOOKAHEAD_RULES:
        raise ValueError(f"config key 'agent.lookahead' must be one of {sorted(LOOKAHEAD_RULES)} or null, got {config.agent.lookahead!r}")


def parse_override(text: str) -> tuple[list[str], Any]:
    """`section.key=value` -> (["section", "key"], YAML-parsed value)."""
    if "=" not in text:
        raise ValueError(f"override {text!r} must look like section.key=value (e.g. optim.lr=0.0005)")
    key, raw = text.split("=", 1)
    path = [part for part in key.strip().split(".") if part]
    if not path:
        raise ValueError(f"override {text!r} has no key before '='")
    try:
        value = yaml.safe_load(raw) if raw.strip() else None
    except yaml.YAMLError:
        value = raw
    return path, value


def apply_overrides(data: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Set each `section.key=value` in the nested mapping (validation happens when the config is built)."""
    for text in overrides:
        path, value = parse_override(text)
        node = data
        for part in path[:-1]:
            child = node.get(part)
            if child is None:
                child = node[part] = {}
            if not isinstance(child, dict):
                raise ValueError(f"override {text!r}: '{part}' is not a section")
            node = child
        node[path[-1]] = value
    return data


def config_from_dict(data: dict[str, Any]) -> RunConfig:
    """Validate a nested mapping into a RunConfig (one-line ValueError on any problem)."""
    config = _build(RunConfig, data, "")
    _check_values(config)
    return config


def load_config(path: str | Path, overrides: list[str] | None = None) -> RunConfig:
    """Read a YAML config, apply overrides and validate it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"config file {str(path)!r} not found (expected a YAML file, e.g. pipelines/configs/default.yaml)")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark else ""
        raise ValueError(f"config file {str(path)!r} is not valid YAML{where}") from None
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r} must hold a mapping of sections (env, agent, ...)")
    return config_from_dict(apply_overrides(data, overrides or []))


def dump_config(config: RunConfig) -> str:
    """The resolved config as YAML (written next to every run)."""
    return yaml.safe_dump(config.to_dict(), sort_keys=False)
