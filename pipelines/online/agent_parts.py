"""The training stack's parts the play learner uses, reached in this one module: a saved agent, its learner,
replay buffers, the simulated user's env and its Collector, test games, and the checkpoint format.

Why one module: the play learner learns with exactly the run's own update (loss, target network, optimiser,
symmetries), so it builds them the way training does; keeping those calls here keeps the rest of
`ncbot.pipelines.online` independent of where the training stack keeps them.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import torch


def load_saved_agent(checkpoint: str | Path) -> tuple[Any, dict[str, Any]]:
    """(run config, checkpoint data) of a saved agent (one-line errors for a missing or foreign file)."""
    from ncbot.pipelines.checkpoint import load_agent_checkpoint

    return load_agent_checkpoint(checkpoint)


def build_agent(config: Any, data: dict[str, Any], seed: int) -> tuple[Any, Any, Any]:
    """(Q-network with the saved weights, its policies, its learner) as the run built them."""
    import logging

    from torchrl.data import Categorical

    from ncbot.modules.learner import Learner
    from ncbot.modules.networks.recurrent import make_agent_qnet
    from ncbot.modules.policies.policy import make_policies
    from ncbot.modules.replay.symmetry import make_symmetries
    from ncbot.pipelines.run_env import make_run_env
    from ncbot.pipelines.train.build import make_objective

    logging.getLogger("torchrl").setLevel(logging.WARNING)  # its storage notes go to stdout, which holds the report
    qnet = make_agent_qnet(data["n_features"], data["n_actions"], config.agent, seed)
    qnet.load_state_dict(data["qnet"])
    eps = config.collector.eps_end
    policies = make_policies(qnet, Categorical(data["n_actions"]), config.lookahead, eps_init=eps, eps_end=eps,
                             annealing_frames=1, all_negative=config.agent.all_negative)
    env = make_run_env(config.env, batch_size=1, seed=seed)
    symmetries = make_symmetries(config.buffer.augment, env, seed, torch.device("cpu"))
    env.close()
    objective, symmetries = make_objective(config, qnet, symmetries)
    learner = Learner.build(objective, optim=config.optim, loss=config.loss, symmetries=symmetries)
    return qnet, policies, learner


def replay_buffer(size: int, batch_size: int) -> Any:
    """A uniform replay buffer of transitions (`ncbot.modules.replay.transitions.BUFFER_KEYS`)."""
    from ncbot.modules.replay.buffer import make_replay_buffer

    return make_replay_buffer(size, batch_size)


def buffer_rows(batch: Any, config: Any) -> Any:
    """(rows, T) env steps -> the learner's transitions, as the training loop stores them (its reward, bootstrap)."""
    from ncbot.modules.replay.transitions import BUFFER_KEYS, prepare_transitions

    loss = config.loss
    rows = prepare_transitions(batch, reward=loss.reward, loss_reward=loss.loss_reward, bootstrap=loss.bootstrap,
                               lookahead=config.lookahead)
    return rows.select(*BUFFER_KEYS)


def simulation(config: Any, policy: Any, frames: int, seed: int, opponent: Any = None) -> Any:
    """A Collector of `frames` env steps per batch against `opponent` (an `Opponent`; None: the run's simulated
    user, as in training), endless."""
    from ncbot.pipelines.run_env import make_run_env
    from ncbot.pipelines.train.build import make_collector

    env = make_run_env(config.env, batch_size=min(config.env.batch_size, frames), seed=seed, opponent=opponent)
    return iter(make_collector(env, policy, frames, -1))


def test_games(config: Any, policy: Any, games: int, seed: int, opponent: str = "random") -> Any:
    """Greedy test games from both seats (`ncbot.pipelines.evaluate.games.EvalResult`)."""
    from ncbot.pipelines.evaluate.games import evaluate_agent

    return evaluate_agent(config, policy, games=games, first="alternate", seed=seed, opponent=opponent)


def atomic_torch_save(obj: Any, path: str | Path) -> Path:
    """torch.save, atomically (a crash never leaves half a file)."""
    from ncbot.pipelines.checkpoint import atomic_save

    return atomic_save(obj, path)


def exact_applies(game: str) -> bool:
    """Whether `exact_task_success` can score `game` (a 3x3 board)."""
    from ncbot.pipelines.evaluate.exact import enumerable

    return enumerable(game)


def exact_task_success(config: Any, policy: Any, seed: int) -> float:
    """3x3: task success against the random user over every branch of its moves, mean of both seats."""
    from ncbot.pipelines.evaluate.exact import exact_seat

    return sum(exact_seat(config, policy, first, [seed]).task_success for first in ("robot", "human")) / 2


def save_agent(path: str | Path, config: Any, data: dict[str, Any], qnet: Any, **counters: Any) -> Path:
    """The agent as a final checkpoint (`ncbot robot play CKPT`, `ncbot eval CKPT` load it), written atomically."""
    from ncbot.pipelines.checkpoint import agent_checkpoint, atomic_save

    final = agent_checkpoint(config, data["n_features"], data["n_actions"],
                             {k: v.detach().clone() for k, v in qnet.state_dict().items()}, str(data.get("run_id", "")),
                             frames=int(data.get("frames", 0)), updates=int(data.get("updates", 0)),
                             episodes=int(data.get("episodes", 0)), **counters)
    return atomic_save(final, path)


def check_learnable(config: Any) -> None:
    """The play learner reads one-step transitions of a feed-forward agent: one line for anything else."""
    if config.agent.memory != "none":
        raise ValueError(f"learning from play needs a feed-forward agent; this checkpoint's agent.memory is "
                         f"{config.agent.memory!r}")
    if config.loss.n_step != 1:
        raise ValueError(f"learning from play uses one-step targets; this checkpoint was trained with loss.n_step "
                         f"{config.loss.n_step}")
