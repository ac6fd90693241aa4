"""Building a training run from its config, and restoring it from a checkpoint (TorchRL sota-dqn style: env,
Q-network and policies, loss and learner, replay buffer, Collector, each made in one line from its config section).

`build_parts` makes every object in a fixed order: the order of the random numbers each draws is part of what makes
a seed's numbers reproducible. `restore` loads a periodic checkpoint's state into them; `training_state` is what a
periodic checkpoint holds.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch

from ncbot.pipelines.config import RunConfig


@dataclass
class TrainingParts:
    """The objects of one training run, and its counters and evaluation history."""

    env: Any
    qnet: Any
    agent: Any  # modules.policies.policy.AgentPolicies: greedy, explore and its egreedy module
    learner: Any  # modules.learner.Learner
    buffer: Any
    multistep: Any  # TorchRL's MultiStepTransform, or None for one-step targets
    teacher: Any = None  # modules.search.search_targets.SearchTeacher of `search_targets`, or None
    selfplay_pool: Any = None  # pipelines.train.selfplay's snapshot pool of `selfplay`, or None
    sequence_rows: Any = None  # agent.memory: modules.networks.recurrent.SequenceRows (dialogue id, step, hidden state)
    device: torch.device = torch.device("cpu")  # of the networks, loss, optimiser and replay storage (train.device)
    counters: dict[str, Any] = field(default_factory=lambda: {"frames": 0, "updates": 0, "episodes": 0,
                                                              "wall_offset": 0.0, "cpu_offset": 0.0})
    history: list[dict[str, Any]] = field(default_factory=list)


def frames_per_batch(config: RunConfig) -> int:
    """Collector batch rounded to a multiple of the env batch (a batched env steps all its games at once)."""
    batch = config.env.batch_size
    return max(batch, (config.collector.frames_per_batch // batch) * batch)


def env_sizes(config: RunConfig) -> tuple[int, int]:
    """(observation features, actions) of the run's env, read from a one-game env built from `config.env`."""
    from ncbot.pipelines.run_env import make_run_env

    env = make_run_env(config.env, batch_size=1, seed=0)
    try:
        return env.n_features, env.n_actions
    finally:
        env.close()


def checkpoint_bytes(config: RunConfig, features: int, actions: int) -> int:
    """About how large one periodic checkpoint of this run is (networks, Adam moments, replay buffer), for an env of
    `features` observation features and `actions` actions: the free space a run needs before it starts, so a full
    disk is one line at start-up rather than an error hours in."""
    widths = [features, *config.agent.hidden, actions]
    params = sum(a * b + b for a, b in zip(widths, widths[1:]))
    buffer = config.buffer.size * (2 * features * 4 + 2 * actions + 64) if config.checkpoint.save_buffer else 0
    return 4 * 4 * params + buffer + 2**20


def learner_settings(config: RunConfig):
    """The learner's `ncbot.modules.learner.LearnerSettings` from the run's loss and optim sections."""
    from ncbot.modules.learner import LearnerSettings

    loss, optim = config.loss, config.optim
    return LearnerSettings(loss_function=loss.loss_function, double_dqn=loss.double_dqn, precision=optim.precision,
                           gamma=loss.gamma, target_update=loss.target_update, target_period=loss.target_period,
                           tau=loss.tau, lr=optim.lr, weight_decay=optim.weight_decay,
                           max_grad_norm=optim.max_grad_norm, memory=config.agent.memory,
                           sequence_length=config.buffer.sequence_length, burn_in=config.buffer.burn_in)


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


def build_parts(config: RunConfig, seed: int, frames_done: int) -> TrainingParts:
    """Env, Q-network, policies, learner, search teacher and replay buffer of a run (`frames_done`: the frames of
    the checkpoint it resumes from, which also seed the env so a resumed run plays new games)."""
    from ncbot.modules.device import resolve_device
    from ncbot.modules.learner import Learner, make_replay_buffer
    from ncbot.modules.policies.policy import make_policies
    from ncbot.modules.networks.recurrent import SequenceRows, make_agent_qnet, memory_env
    from ncbot.modules.replay.symmetry import make_symmetries
    from ncbot.modules.replay.transitions import make_multistep
    from ncbot.pipelines.run_env import make_run_env

    # --- env and agent -------------------------------------------------------------------------------------------
    selfplay_pool = None
    if config.selfplay.enabled:  # the user's moves come from frozen snapshots of this agent (pipelines/train/selfplay.py)
        from ncbot.pipelines.train.selfplay import make_selfplay_pool

        selfplay_pool = make_selfplay_pool(config.env, config.selfplay, seed)
    env = make_run_env(config.env, batch_size=config.env.batch_size, seed=seed + frames_done, opponent=selfplay_pool)
    qnet = make_agent_qnet(env.n_features, env.n_actions, config.agent, seed)  # the MLP, or agent.memory's network
    # (its starting weights are drawn on the CPU: the same on every device)
    device = resolve_device(config.train.device)
    if device.type != "cpu":
        qnet.to(device)
    agent = make_policies(
        qnet, env.action_spec_unbatched, config.lookahead,
        eps_init=config.collector.eps_init, eps_end=config.collector.eps_end,
        annealing_frames=config.collector.annealing_frames, all_negative=config.agent.all_negative, device=device,
    )
    env = memory_env(env, agent.explore)  # agent.memory: is_init and the hidden state carried by the env

    # --- loss, target network, optimiser, replay buffer ------------------------------------------------------------
    symmetries = make_symmetries(config.buffer.augment, env, seed, device)
    learner = Learner.build(qnet, learner_settings(config), symmetries)
    teacher = make_teacher(config, agent.greedy, seed)  # search_targets: labels of the Q-guided search, or None
    learner.teacher = teacher
    if teacher is not None:
        learner.teacher_weight, learner.teacher_margin = config.search_targets.weight, config.search_targets.margin
    multistep = make_multistep(config.loss.n_step, config.loss.gamma)  # n-step returns when loss.n_step > 1
    buffer = make_replay_buffer(config.buffer.size, config.buffer.batch_size, prioritized=config.buffer.prioritized,
                                alpha=config.buffer.alpha, beta=config.buffer.beta,
                                sequence_length=config.buffer.sequence_length if config.agent.memory != "none" else None,
                                device=device)
    sequence_rows = SequenceRows(config.agent.memory) if config.agent.memory != "none" else None
    return TrainingParts(env, qnet, agent, learner, buffer, multistep, teacher, selfplay_pool, sequence_rows, device)


def restore(parts: TrainingParts, state: dict[str, Any], state_path: Any) -> None:
    """Load a periodic checkpoint's training state into the run's parts (networks, optimiser, epsilon, buffer,
    teacher, RNG, counters, history); a state that does not fit the config is one line naming the checkpoint."""
    try:
        parts.qnet.load_state_dict(state["qnet"])
        parts.learner.load_state_dict(state["learner"])
        parts.agent.egreedy.load_state_dict(state["egreedy"])
        if state.get("buffer") is not None:
            parts.buffer.load_state_dict(state["buffer"])
            _storage_to(parts.buffer, parts.device)
        if parts.teacher is not None and state.get("teacher") is not None:
            parts.teacher.load_state_dict(state["teacher"])
        torch.set_rng_state(state["rng"])
        if state.get("cuda_rng") is not None and parts.device.type == "cuda":
            torch.cuda.set_rng_state(state["cuda_rng"], parts.device)
    except (RuntimeError, KeyError, TypeError, ValueError) as error:  # the checkpoint's parts do not fit this config
        raise ValueError(f"checkpoint {str(state_path)!r} does not fit the run's config "
                         f"({str(error).splitlines()[0][:160]})") from None
    parts.counters.update({k: state[k] for k in ("frames", "updates", "episodes")})
    parts.counters["wall_offset"] = state["wall_time"]
    parts.counters["cpu_offset"] = state.get("cpu_time")  # None: a checkpoint written before CPU time was kept
    parts.history = list(state["history"])


def _storage_to(buffer: Any, device: torch.device) -> None:
    """A replay storage loaded from a (CPU) checkpoint onto the run's device: TorchRL fills an empty storage with
    the checkpoint's own tensors, on the CPU."""
    storage = buffer.storage
    if device.type != "cpu" and getattr(storage, "_storage", None) is not None:
        storage._storage = storage._storage.to(device)


def training_state(config: RunConfig, parts: TrainingParts, run_id: str, wall_time: float,
                   cpu_time: float | None) -> dict[str, Any]:
    """What a periodic checkpoint holds: everything `restore` loads back, every tensor on the CPU (a GPU run's
    checkpoint loads on any machine)."""
    from ncbot.modules.device import to_cpu

    counters, teacher = parts.counters, parts.teacher
    cuda_rng = {"cuda_rng": torch.cuda.get_rng_state(parts.device)} if parts.device.type == "cuda" else {}
    return to_cpu({
        "config": config.to_dict(), "n_features": parts.env.n_features, "n_actions": parts.env.n_actions,
        "qnet": parts.qnet.state_dict(), "learner": parts.learner.state_dict(),
        "egreedy": parts.agent.egreedy.state_dict(),
        "buffer": parts.buffer.state_dict() if config.checkpoint.save_buffer else None,
        "teacher": teacher.state_dict(keep_labels=config.checkpoint.save_buffer) if teacher is not None else None,
        "rng": torch.get_rng_state(), "history": parts.history, "run_id": run_id,
        "frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
        "wall_time": wall_time, "cpu_time": cpu_time, **cuda_rng,
    })


def check_teacher_value(config: RunConfig) -> None:
    """`search_targets.value` names a value network for this run's game and rule (one-line errors otherwise)."""
    settings = config.search_targets
    if not settings.enabled or settings.value is None:
        return
    if config.env.game != "ultimate":
        raise ValueError(f"config key 'search_targets.value' scores Ultimate positions; this run plays "
                         f"{config.env.game} (leave it null)")
    from ncbot.modules.search.value_net import load_value_net

    with torch.random.fork_rng():
        load_value_net(settings.value, config.env.free_move)


def make_teacher(config: RunConfig, greedy: Any, seed: int):
    """The search teacher of `search_targets` (modules/search/search_targets.py) on the run's own Q-network, or None."""
    settings = config.search_targets
    if not settings.enabled:
        return None
    from ncbot.modules.search.search_targets import SearchTeacher
    from ncbot.pipelines.agents import guided_search

    with torch.random.fork_rng():  # building it draws no number from the run's stream: same run up to start_frames
        search = guided_search(config, greedy, settings.simulations, value=settings.value)
        return SearchTeacher(greedy, search, rows_per_batch=settings.rows_per_batch, seat=settings.seat,
                             gap=settings.gap, buffer_size=settings.buffer_size, batch_size=settings.batch_size,
                             seed=seed)
