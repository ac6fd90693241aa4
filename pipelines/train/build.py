"""The assembly of a training run, in one place (TorchRL sota-dqn style): env, Q-network and policies, objective and
learner, replay buffer, hooks and Collector, each made from its config section.

`check_run` resolves and validates what a run needs before its folder is touched (the device, the objective's
class, the search teacher's value network, the scalar backend); `assemble` then builds every part in a fixed order
(the order of the random numbers each draws is part of what makes a seed's numbers reproducible) and loads a
resumed run's state into them (`ncbot.pipelines.checkpoint.restore`). The Collector is made when the loop starts
(`TrainingParts.collector`): its first reset already plays against what the hooks set up (self-play's snapshot).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch

from ncbot.pipelines.config import RunConfig


@dataclass(frozen=True)
class RunSetup:
    """What `check_run` resolved once for the whole run."""

    device: torch.device  # of the networks, objective, optimiser and replay storage (train.device)
    objective: type  # the objective's class (loss.objective)


@dataclass
class TrainingParts:
    """The objects of one training run, and its counters and evaluation history."""

    config: RunConfig
    env: Any
    qnet: Any
    agent: Any  # modules.policies.policy.AgentPolicies: greedy, explore and its egreedy module
    learner: Any  # modules.learner.Learner (its objective, target updater, optimiser)
    buffer: Any
    multistep: Any  # TorchRL's MultiStepTransform, or None for one-step targets
    hooks: list[Any]  # pipelines.train.hooks.TrainingHook, called by the loop in this order
    device: torch.device = torch.device("cpu")
    counters: dict[str, Any] = field(default_factory=lambda: {"frames": 0, "updates": 0, "episodes": 0,
                                                              "wall_offset": 0.0, "cpu_offset": 0.0})
    history: list[dict[str, Any]] = field(default_factory=list)

    def transitions(self, batch: Any) -> Any:
        """A collected batch as the replay buffer stores it (`ncbot.modules.replay.transitions`)."""
        from ncbot.modules.replay.transitions import prepare_transitions

        loss = self.config.loss
        return prepare_transitions(batch, reward=loss.reward, loss_reward=loss.loss_reward, bootstrap=loss.bootstrap,
                                   lookahead=self.config.lookahead, multistep=self.multistep)

    def collector(self) -> Any:
        """TorchRL's Collector for the frames the run has left (open-ended when it stops on games), or None."""
        config = self.config
        batch_frames = frames_per_batch(config)
        remaining = -1 if config.train.episodes is not None else \
            max(0, config.collector.total_frames - self.counters["frames"])
        if remaining == 0:
            return None
        if remaining > 0:  # whole collector batches (TorchRL would round up anyway, with a warning)
            remaining = -(-remaining // batch_frames) * batch_frames
        return make_collector(self.env, self.agent.explore, batch_frames, remaining,
                              keeps_views=self.multistep is not None, device=self.device)


def frames_per_batch(config: RunConfig) -> int:
    """Collector batch rounded to a multiple of the env batch (a batched env steps all its games at once)."""
    batch = config.env.batch_size
    return max(batch, (config.collector.frames_per_batch // batch) * batch)


def checkpoint_bytes(config: RunConfig, features: int, actions: int) -> int:
    """About how large one periodic checkpoint of this run is (networks, Adam moments, replay buffer), for an env of
    `features` observation features and `actions` actions: the free space a run needs before it claims its folder,
    so a full disk is one line at start-up rather than an error hours in."""
    widths = [features, *config.agent.hidden, actions]
    params = sum(a * b + b for a, b in zip(widths, widths[1:]))
    buffer = config.buffer.size * (2 * features * 4 + 2 * actions + 64) if config.checkpoint.save_buffer else 0
    return 4 * 4 * params + buffer + 2**20


def check_run(config: RunConfig) -> RunSetup:
    """Everything about the run that can be refused before its folder is touched, each a one-line ValueError."""
    from ncbot.modules.device import resolve_device
    from ncbot.modules.objectives.registry import objective_class
    from ncbot.pipelines.scalars import check_backend

    device = resolve_device(config.train.device)  # no GPU here: one line, nothing written
    objective = objective_class(config.objective)
    replays = getattr(objective, "replays", "transitions")
    if (replays == "sequences") != (config.agent.memory != "none"):
        wanted = "a recurrent network (agent.memory: gru or lstm)" if replays == "sequences" else \
            "the feed-forward network (agent.memory: none)"
        raise ValueError(f"config key 'loss.objective' {config.objective} replays {replays} and needs {wanted}; "
                         f"this run has agent.memory={config.agent.memory}")
    check_teacher_value(config)
    check_backend(config.logger.backend)
    return RunSetup(device, objective)


def make_collector(env: Any, policy: Any, frames_per_batch: int, total_frames: int, *, keeps_views: bool = False,
                   device: torch.device | str = "cpu"):
    """TorchRL's Collector as the training loop uses it (and bench/learner_throughput.py measures it).

    Per-step overhead is most of a frame at the paper's 8-frame batches (docs/learner-speed.md): with device "cpu"
    named, the Collector keeps its TensorDicts there instead of casting every step to the env's device; each batch
    is used up before the next is collected (the buffer copies it, the MCAP log packs it into rows of its own), so
    it may hand out its own storage instead of a clone, unless the consumer `keeps_views` (n-step's
    MultiStepTransform keeps views of the last steps); nothing reads ("collector", "traj_ids").

    On a GPU `device`, the env stays on the CPU (a table-driven simulator) while the policy runs on the GPU and the
    batches are stored there, next to the replay storage: env_device cpu, policy_device and storing_device `device`.
    """
    from torchrl.collectors import Collector

    device = torch.device(device)
    where = {"device": "cpu"} if device.type == "cpu" else \
        {"env_device": "cpu", "policy_device": device, "storing_device": device}
    return Collector(env, policy, frames_per_batch=frames_per_batch, total_frames=total_frames, **where,
                     auto_register_policy_transforms=False, return_same_td=not keeps_views, track_traj_ids=False)


def make_objective(config: RunConfig, qnet: Any, symmetries: Any = None, cls: type | None = None) -> tuple[Any, Any]:
    """(objective, the symmetries the learner turns rows with) of the run: `cls` (default: `config.objective`'s
    class, modules/objectives/registry.py) built on `qnet` with the options its constructor takes, its keys wired
    to the replayed transitions' and its TorchRL value estimator made. An objective that turns board symmetries
    itself (a `symmetries` argument: whole slices) leaves the learner none."""
    from ncbot.modules.objectives.common import PRIORITY_KEY
    from ncbot.modules.objectives.registry import (build_objective, check_objective_keys, objective_class,
                                                   objective_options)
    from ncbot.modules.replay.sequences import sequence_keys
    from ncbot.modules.replay.transitions import LOSS_KEYS, stored_keys

    name, loss = config.objective, config.loss
    cls = cls or objective_class(name)
    replays = getattr(cls, "replays", "transitions")
    options = {"loss_function": loss.loss_function, "double_dqn": loss.double_dqn, "precision": config.optim.precision,
               "symmetries": symmetries}
    if replays == "sequences":
        options.update(sequence_length=config.buffer.sequence_length, burn_in=config.buffer.burn_in)
    taken = objective_options(cls, name, options, {"loss_function": "l2", "double_dqn": False, "precision": "fp32"})
    if symmetries is not None and "symmetries" not in taken and replays == "sequences":
        raise ValueError(f"objective {name}: class {cls.__name__} takes no 'symmetries' argument, so "
                         "buffer.augment=d4 cannot turn its slices (set buffer.augment: none)")
    estimator = {"gamma": loss.gamma, **({"lmbda": loss.lmbda} if loss.value_estimator == "td_lambda" else {})}
    objective = build_objective(cls, name, qnet, taken, keys={**LOSS_KEYS, "priority": PRIORITY_KEY},
                                value_estimator=loss.value_estimator, **estimator)
    stored = [*stored_keys(loss.n_step), *(sequence_keys(config.agent.memory) if replays == "sequences" else ())]
    check_objective_keys(objective, name, stored, prioritized=config.buffer.prioritized)
    return objective, None if "symmetries" in taken else symmetries


def assemble(config: RunConfig, setup: RunSetup, seed: int, state: dict[str, Any] | None = None,
             state_path: Any = None) -> TrainingParts:
    """Env, Q-network, policies, objective, learner, replay buffer and hooks of a run, with a resumed run's `state`
    loaded (its frames also seed the env, so a resumed run plays new games)."""
    from ncbot.modules.learner import Learner
    from ncbot.modules.networks.recurrent import make_agent_qnet, memory_env
    from ncbot.modules.policies.policy import make_policies
    from ncbot.modules.replay.buffer import make_replay_buffer
    from ncbot.modules.replay.symmetry import make_symmetries
    from ncbot.modules.replay.transitions import make_multistep
    from ncbot.pipelines.checkpoint import restore
    from ncbot.pipelines.run_env import make_run_env

    device = setup.device
    pool = make_selfplay_pool(config, seed)  # self-play: the user's moves by snapshots of this agent, or None
    env = make_run_env(config.env, batch_size=config.env.batch_size, seed=seed + (state["frames"] if state else 0),
                       opponent=pool)
    qnet = make_agent_qnet(env.n_features, env.n_actions, config.agent, seed)  # the MLP, or agent.memory's network
    if device.type != "cpu":  # (its starting weights are drawn on the CPU: the same on every device)
        qnet.to(device)
    agent = make_policies(
        qnet, env.action_spec_unbatched, config.lookahead,
        eps_init=config.collector.eps_init, eps_end=config.collector.eps_end,
        annealing_frames=config.collector.annealing_frames, all_negative=config.agent.all_negative, device=device,
    )
    env = memory_env(env, agent.explore)  # agent.memory: is_init and the hidden state carried by the env

    objective, symmetries = make_objective(config, qnet, make_symmetries(config.buffer.augment, env, seed, device),
                                           setup.objective)
    learner = Learner.build(objective, optim=config.optim, loss=config.loss, symmetries=symmetries)
    hooks = make_hooks(config, objective, learner, agent, pool, seed, device)
    multistep = make_multistep(config.loss.n_step, config.loss.gamma)  # n-step returns when loss.n_step > 1
    buffer = make_replay_buffer(config.buffer.size, config.buffer.batch_size, prioritized=config.buffer.prioritized,
                                alpha=config.buffer.alpha, beta=config.buffer.beta, device=device,
                                sequence_length=config.buffer.sequence_length if replays_sequences(objective) else None)
    parts = TrainingParts(config, env, qnet, agent, learner, buffer, multistep, hooks, device)
    if state is not None:
        restore(parts, state, state_path)
    return parts


def replays_sequences(objective: Any) -> bool:
    return getattr(objective, "replays", "transitions") == "sequences"


def make_hooks(config: RunConfig, objective: Any, learner: Any, agent: Any, pool: Any, seed: int,
               device: torch.device) -> list[Any]:
    """The run's hooks, in the order the loop calls them: recurrent replay, search targets (also the learner's
    margin loss), self-play, periodic evaluation, periodic checkpoints."""
    from ncbot.pipelines.train.hooks import PeriodicCheckpoint, PeriodicEvaluation, RecurrentReplay, SearchTargets

    hooks: list[Any] = []
    if replays_sequences(objective):
        hooks.append(RecurrentReplay(config.agent.memory))
    teacher = make_teacher(config, agent.greedy, seed, device)
    if teacher is not None:
        learner.auxiliary.append(teacher)
        hooks.append(SearchTargets(teacher, config.search_targets.start_frames, config.checkpoint.save_buffer))
    if pool is not None:
        from ncbot.pipelines.train.selfplay import SelfPlay

        hooks.append(SelfPlay(pool))
    return [*hooks, PeriodicEvaluation(), PeriodicCheckpoint()]


def make_selfplay_pool(config: RunConfig, seed: int) -> Any:
    """The snapshot pool the env's user plays in self-play (pipelines/train/selfplay.py), or None. Built before the
    Q-network because the network's sizes come from the env, which needs its opponent."""
    if not config.selfplay.enabled:
        return None
    from ncbot.pipelines.train.selfplay import SnapshotPool

    env = config.env
    return SnapshotPool(env.game, env.free_move, env.temporal, config.selfplay, seed=seed, threats=env.threats)


def check_teacher_value(config: RunConfig) -> None:
    """`search_targets.value` names a value network for this run's game and rule (one-line errors otherwise)."""
    settings = config.search_targets
    if not settings.enabled or settings.value is None:
        return
    from ncbot.modules.search.value_net import VALUE_GAME, load_value_net

    if config.env.game != VALUE_GAME:
        raise ValueError(f"config key 'search_targets.value' scores Ultimate positions; this run plays "
                         f"{config.env.game} (leave it null)")

    with torch.random.fork_rng():
        load_value_net(settings.value, config.env.free_move)


def make_teacher(config: RunConfig, greedy: Any, seed: int, device: torch.device):
    """The search teacher of `search_targets` (modules/search/search_targets.py) on the run's own Q-network, or None."""
    settings = config.search_targets
    if not settings.enabled:
        return None
    from ncbot.modules.search.guided_mcts import policy_search
    from ncbot.modules.search.search_targets import SearchTeacher

    with torch.random.fork_rng():  # building it draws no number from the run's stream: same run up to start_frames
        search = policy_search(greedy, config.env, settings.simulations, value=settings.value)
        return SearchTeacher(greedy, search, rows_per_batch=settings.rows_per_batch, seat=settings.seat,
                             gap=settings.gap, buffer_size=settings.buffer_size, batch_size=settings.batch_size,
                             seed=seed, weight=settings.weight, margin=settings.margin, device=device)
