"""Learner throughput of the default pipeline: gradient updates/s and env frames/s, next to OpenSpiel's PyTorch DQN
on tic_tac_toe measured in the same run (same network, same batch size, one torch thread).

    python bench/learner_throughput.py [--config pipelines/configs/default.yaml] [--seconds 10]

OpenSpiel is a bench-time install only (`pip install open-spiel dm-tree`); without it the script says so and
prints our figures alone. The machine is shared with other jobs: rerun and compare figures from the same run.
"""
from __future__ import annotations

import argparse
import logging
import time

import torch


def _rate(step, seconds: float, warmup: int = 5) -> float:
    """Calls of `step()` per second over about `seconds` (after a warm-up)."""
    for _ in range(warmup):
        step()
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step()
        count += 1
    return count / (time.perf_counter() - start)


def ours(config_path: str, seconds: float) -> dict[str, float]:
    from torchrl.collectors import Collector
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

    from modules.policy import make_policies
    from modules.qnet import make_qnet
    from modules.rewards import learning_rewards
    from pipelines.config import load_config
    from pipelines.learner import Learner
    from pipelines.run_env import make_run_env
    from pipelines.train import TRANSITION_KEYS, frames_per_batch

    config = load_config(config_path)
    env = make_run_env(config.env, batch_size=config.env.batch_size, seed=0)
    qnet = make_qnet(env.n_features, env.n_actions, config.agent.hidden)
    agent = make_policies(qnet, env.action_spec_unbatched, config.lookahead, annealing_frames=10**9)
    learner = Learner.from_config(qnet, config)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(config.buffer.size), batch_size=config.buffer.batch_size)
    collector = Collector(env, agent.explore, frames_per_batch=frames_per_batch(config), total_frames=-1,
                          auto_register_policy_transforms=False)
    batches = iter(collector)

    def collect() -> None:
        batch = next(batches)
        buffer.extend(learning_rewards(batch.select(*TRANSITION_KEYS).reshape(-1), config.loss.reward))

    def update() -> None:
        learner.update(buffer.sample())

    while len(buffer) < config.buffer.batch_size * 4:
        collect()
    frames = _rate(collect, seconds) * frames_per_batch(config)
    updates = _rate(update, seconds)

    def train_iteration() -> None:  # what the training loop does per collected batch
        collect()
        for _ in range(config.optim.updates_per_batch):
            update()

    iterations = _rate(train_iteration, seconds, warmup=1)
    collector.shutdown()
    return {"env_frames_per_s": frames, "updates_per_s": updates,
            "loop_frames_per_s": iterations * frames_per_batch(config),
            "loop_updates_per_s": iterations * config.optim.updates_per_batch,
            "batch_size": config.buffer.batch_size, "hidden": config.agent.hidden}


def openspiel(hidden: list[int], batch_size: int, seconds: float) -> dict[str, float] | None:
    try:
        from open_spiel.python import rl_environment
        from open_spiel.python.pytorch import dqn
    except ImportError as error:
        print(f"OpenSpiel not importable ({error}); install with: pip install open-spiel dm-tree")
        return None
    env = rl_environment.Environment("tic_tac_toe")
    size = env.observation_spec()["info_state"][0]
    actions = env.action_spec()["num_actions"]
    agents = [dqn.DQN(player_id=p, state_representation_size=size, num_actions=actions, hidden_layers_sizes=hidden,
                      batch_size=batch_size, replay_buffer_capacity=50_000, min_buffer_size_to_learn=batch_size,
                      learn_every=10**9, optimizer_str="adam", learning_rate=1e-3) for p in range(2)]
    time_step = env.reset()

    def play_step() -> None:  # one env frame: the player to move acts (its transition is stored)
        nonlocal time_step
        if time_step.last():
            for agent in agents:
                agent.step(time_step)
            time_step = env.reset()
            return
        player = time_step.observations["current_player"]
        output = agents[player].step(time_step)
        time_step = env.step([output.action])

    def stored() -> int:  # OpenSpiel creates the replay buffer on the first transition
        return 0 if agents[0]._replay_buffer is None else len(agents[0]._replay_buffer)

    while stored() < batch_size * 4:
        play_step()
    frames = _rate(play_step, seconds)
    updates = _rate(agents[0].learn, seconds)
    return {"env_frames_per_s": frames, "updates_per_s": updates}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="pipelines/configs/default.yaml")
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring time per figure")
    args = parser.parse_args()
    torch.set_num_threads(1)
    logging.getLogger("torchrl").setLevel(logging.WARNING)
    mine = ours(args.config, args.seconds)
    theirs = openspiel(mine["hidden"], mine["batch_size"], args.seconds)
    print(f"network {mine['hidden']}, batch {mine['batch_size']}, 1 torch thread (shared machine: figures are noisy)")
    print("| learner | env frames/s | gradient updates/s |")
    print("|---|---|---|")
    print(f"| ncbot default pipeline (batched dialogue env, TorchRL Collector) | {mine['env_frames_per_s']:,.0f} | "
          f"{mine['updates_per_s']:,.0f} |")
    print(f"| ncbot full training loop (collect + {mine['loop_updates_per_s'] / mine['loop_frames_per_s'] * 1024:.0f} "
          f"updates per 1024 frames) | {mine['loop_frames_per_s']:,.0f} | {mine['loop_updates_per_s']:,.0f} |")
    if theirs:
        print(f"| OpenSpiel PyTorch DQN, tic_tac_toe (rl_environment, 1 game) | {theirs['env_frames_per_s']:,.0f} | "
              f"{theirs['updates_per_s']:,.0f} |")
        print(f"updates/s ratio ncbot / OpenSpiel: {mine['updates_per_s'] / theirs['updates_per_s']:.2f}x; "
              f"env frames/s ratio: {mine['env_frames_per_s'] / theirs['env_frames_per_s']:.1f}x")


if __name__ == "__main__":
    main()
