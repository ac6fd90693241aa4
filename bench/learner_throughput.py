"""Learner throughput of the default pipeline: gradient updates/s and env frames/s, next to OpenSpiel's PyTorch DQN
on tic_tac_toe measured in the same run (same network, same batch size, same single torch thread).

    python bench/learner_throughput.py [--config pipelines/configs/default.yaml] [--seconds 3] [--rounds 3]
    python bench/learner_throughput.py --levers [--compile]    # speed levers tried on a bare update, one at a time
    python bench/learner_throughput.py --ops                   # aten ops one Learner.update issues, per precision

Every figure is measured per CPU second of this process (`time.process_time`), which survives a machine shared
with other jobs far better than wall time; the learners take turns over `--rounds` rounds and the median round is
reported, so a burst of load hits both sides alike. Updates are timed on a full replay buffer that takes a fresh
collected batch every `optim.updates_per_batch` updates (untimed), as in training. Rows for ncbot: the update the
training loop runs (`Learner.update`: `objective(td)`, backward, Adam, target updater) at the config's precision,
the same update at the other precision (`optim.precision`), and the whole loop (collect + updates).
To compare with another commit, run this script from each tree in turn (docs/learner-speed.md gives the command).
OpenSpiel is a bench-time install only (`pip install open-spiel dm-tree`); without it the script says so and
prints our figures alone.
"""
from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree's learner, not an installed copy


def _rate(step: Callable[[], object], seconds: float, warmup: int = 5) -> float:
    """Calls of `step()` per CPU second of this process over about `seconds` of CPU time (after a warm-up)."""
    for _ in range(warmup):
        step()
    count, start = 0, time.process_time()
    while time.process_time() - start < seconds:
        step()
        count += 1
    return count / (time.process_time() - start)


def _update_rate(update: Callable[[], object], refresh: Callable[[], object], every: int, seconds: float) -> float:
    """Calls of `update()` per CPU second spent in them, with an untimed `refresh()` (new experience) before every
    `every` updates: the replay buffer turns over as in training."""
    count, spent = 0, 0.0
    while spent < seconds:
        if count % every == 0:
            refresh()
        start = time.process_time()
        update()
        spent += time.process_time() - start
        count += 1
    return count / spent


class Ours:
    """The default pipeline's env, Collector, replay buffer and learners (one per precision, same start weights)."""

    def __init__(self, config_path: str) -> None:
        from ncbot.modules.policies.policy import make_policies
        from ncbot.modules.networks.qnet import make_qnet, seeded_init
        from ncbot.modules.replay.symmetry import make_symmetries
        from ncbot.modules.replay.transitions import make_multistep, prepare_transitions
        from ncbot.pipelines.config import load_config
        from ncbot.modules.learner import Learner
        from ncbot.modules.replay.buffer import make_replay_buffer
        from ncbot.pipelines.run_env import make_run_env
        from ncbot.pipelines.train.build import frames_per_batch, make_collector, make_objective

        config = self.config = load_config(config_path)
        self.env = make_run_env(config.env, batch_size=config.env.batch_size, seed=0)
        self.batch_frames = frames_per_batch(config)

        self.learners: dict[str, Learner] = {}
        for precision in ("fp32", "bf16"):
            qnet = make_qnet(self.env.n_features, self.env.n_actions, config.agent.hidden)
            seeded_init(qnet, 0)
            learner_config = load_config(config_path, [f"optim.precision={precision}"])
            symmetries = make_symmetries(config.buffer.augment, self.env, 0)  # buffer.augment: as training runs it
            objective, symmetries = make_objective(learner_config, qnet, symmetries)
            self.learners[precision] = Learner.build(objective, optim=learner_config.optim, loss=learner_config.loss,
                                                     symmetries=symmetries)
            if precision == config.optim.precision:  # the collecting policy acts with the default learner's network
                agent = make_policies(qnet, self.env.action_spec_unbatched, config.lookahead, annealing_frames=10**9)
        self.buffer = make_replay_buffer(config.buffer.size, config.buffer.batch_size)
        multistep = make_multistep(config.loss.n_step, config.loss.gamma)
        self.collector = make_collector(self.env, agent.explore, self.batch_frames, -1, keeps_views=multistep is not None)
        batches = iter(self.collector)

        def collect() -> None:  # what the training loop does with a collected batch before the updates
            self.buffer.extend(prepare_transitions(next(batches), reward=config.loss.reward,
                                                   loss_reward=config.loss.loss_reward,
                                                   bootstrap=config.loss.bootstrap, lookahead=config.lookahead,
                                                   multistep=multistep))

        self.collect = collect
        while len(self.buffer) < config.buffer.size:  # a full buffer, as for most of a training run
            collect()

    def measure(self, seconds: float) -> dict[str, float]:
        config, buffer = self.config, self.buffer
        default = self.learners[config.optim.precision]

        def train_iteration() -> None:  # what the training loop does per collected batch
            self.collect()
            default.update_many(buffer, config.optim.updates_per_batch)

        def rate(update: Callable[[], object]) -> float:
            return _update_rate(update, self.collect, config.optim.updates_per_batch, seconds)

        iterations = _rate(train_iteration, seconds, warmup=1)
        other = "bf16" if config.optim.precision == "fp32" else "fp32"
        return {
            "updates_per_s": rate(lambda: default.update(buffer.sample())),
            "env_frames_per_s": _rate(self.collect, seconds) * self.batch_frames,
            "other_updates_per_s": rate(lambda: self.learners[other].update(buffer.sample())),
            "sample_per_s": _rate(buffer.sample, seconds),
            "loop_frames_per_s": iterations * self.batch_frames,
            "loop_updates_per_s": iterations * config.optim.updates_per_batch,
        }

    def close(self) -> None:
        self.collector.shutdown()


class OpenSpiel:
    """OpenSpiel's PyTorch DQN on tic_tac_toe (rl_environment, one game), network and batch set to ours."""

    def __init__(self, hidden: list[int], batch_size: int) -> None:
        from open_spiel.python import rl_environment
        from open_spiel.python.pytorch import dqn

        self.env = rl_environment.Environment("tic_tac_toe")
        size = self.env.observation_spec()["info_state"][0]
        actions = self.env.action_spec()["num_actions"]
        self.agents = [dqn.DQN(player_id=p, state_representation_size=size, num_actions=actions,
                               hidden_layers_sizes=hidden, batch_size=batch_size, replay_buffer_capacity=50_000,
                               min_buffer_size_to_learn=batch_size, learn_every=10**9, optimizer_str="adam",
                               learning_rate=1e-3) for p in range(2)]
        self.time_step = self.env.reset()
        while self.stored() < batch_size * 4:
            self.play_step()

    def play_step(self) -> None:
        """One env frame: the player to move acts (its transition is stored)."""
        if self.time_step.last():
            for agent in self.agents:
                agent.step(self.time_step)
            self.time_step = self.env.reset()
            return
        player = self.time_step.observations["current_player"]
        output = self.agents[player].step(self.time_step)
        self.time_step = self.env.step([output.action])

    def stored(self) -> int:  # OpenSpiel creates the replay buffer on the first transition
        buffer = self.agents[0]._replay_buffer
        return 0 if buffer is None else len(buffer)

    def measure(self, seconds: float) -> dict[str, float]:
        return {"env_frames_per_s": _rate(self.play_step, seconds), "updates_per_s": _rate(self.agents[0].learn, seconds)}


def levers(config_path: str, seconds: float, rounds: int, compile_too: bool) -> None:
    """Per-update CPU time of a bare DQN update (our MLP, batch, masked max target, MSE, clipping, fused Adam) on
    random tensors, for each speed lever we measured: the evidence behind docs/learner-speed.md's lever table."""
    import copy

    from torch import nn

    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.run_env import make_run_env

    config = load_config(config_path)
    env = make_run_env(config.env, batch_size=1, seed=0)  # the config's env: its observation features and actions
    features, actions = env.n_features, env.n_actions
    env.close()
    batch, hidden = config.buffer.batch_size, config.agent.hidden
    torch.manual_seed(0)
    widths = [features, *hidden]
    layers: list[nn.Module] = []
    for width_in, width_out in zip(widths, widths[1:]):
        layers += [nn.Linear(width_in, width_out), nn.ReLU()]
    net = nn.Sequential(*layers, nn.Linear(widths[-1], actions))
    target = copy.deepcopy(net).requires_grad_(False)
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3, fused=True)
    observation, next_observation = torch.rand(batch, features), torch.rand(batch, features)
    action, reward = torch.randint(0, actions, (batch,)), torch.randn(batch)
    available, terminated = torch.rand(batch, actions) < 0.5, torch.rand(batch) < 0.2
    available[:, 0] = True

    def update(bf16: bool = False, chunks: int = 1) -> None:
        optimizer.zero_grad(set_to_none=True)
        size = batch // chunks
        for chunk in range(chunks):
            rows = slice(chunk * size, (chunk + 1) * size)
            with torch.no_grad(), torch.autocast("cpu", torch.bfloat16, enabled=bf16):
                next_q = target(next_observation[rows]).float().masked_fill(~available[rows], -1e30)
                y = reward[rows] + config.loss.gamma * (~terminated[rows]) * next_q.max(-1).values
            with torch.autocast("cpu", torch.bfloat16, enabled=bf16):
                q = net(observation[rows]).float()
            predicted = q.gather(-1, action[rows, None]).squeeze(-1)
            (nn.functional.mse_loss(predicted, y, reduction="sum") / batch).backward()
        nn.utils.clip_grad_norm_(net.parameters(), config.optim.max_grad_norm, foreach=True)
        optimizer.step()

    def bf32() -> None:
        torch.backends.mkldnn.matmul.fp32_precision = "bf16"
        try:
            update()
        finally:
            torch.backends.mkldnn.matmul.fp32_precision = "none"

    cases: dict[str, Callable[[], object]] = {
        "reference fp32": update, "reference bf16 (autocast)": lambda: update(bf16=True),
        "mkldnn fp32_precision=bf16": bf32,
        "4 chunks of batch/4, fp32": lambda: update(chunks=4), "4 chunks of batch/4, bf16": lambda: update(True, 4),
    }
    if compile_too:
        for name, bf16 in (("torch.compile, fp32", False), ("torch.compile, bf16", True)):
            compiled = torch.compile(lambda bf16=bf16: update(bf16))
            start = time.perf_counter()
            compiled()
            print(f"{name}: compiled in {time.perf_counter() - start:.0f} s (wall)")
            cases[name] = compiled
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(rounds):
        for name, step in cases.items():
            times[name].append(1e3 / _rate(step, seconds))
    print(f"bare update, batch {batch}, network {features}-{hidden}-{actions}, 1 torch thread; CPU ms per update, "
          f"median of {rounds} rounds; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    reference = statistics.median(times["reference fp32"])
    for name, values in times.items():
        print(f"| {name} | {statistics.median(values):.2f} ms | {reference / statistics.median(values):.2f}x |")


def op_counts(config_path: str) -> None:
    """How many aten ops one `Learner.update` issues at each precision (torch.profiler): what bf16 adds besides
    faster products (the dtype casts)."""
    from torch.profiler import ProfilerActivity, profile

    ours = Ours(config_path)
    batch = ours.buffer.sample()
    for precision, learner in ours.learners.items():
        for _ in range(3):
            learner.update(batch)
        with profile(activities=[ProfilerActivity.CPU]) as profiler:
            learner.update(batch)
        counts = {event.key: event.count for event in profiler.key_averages() if event.key.startswith("aten::")}
        casts = counts.get("aten::_to_copy", 0)
        products = sum(counts.get(name, 0) for name in ("aten::addmm", "aten::mm"))
        print(f"{precision}: {sum(counts.values())} aten ops per update, {products} matrix products, {casts} dtype "
              f"casts (aten::_to_copy)")
    ours.close()


def _median(rounds: list[dict[str, float]]) -> dict[str, float]:
    return {key: statistics.median(r[key] for r in rounds) for key in rounds[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="pipelines/configs/default.yaml")
    parser.add_argument("--seconds", type=float, default=3.0, help="CPU seconds per figure and round")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds; the median is reported")
    parser.add_argument("--levers", action="store_true", help="time the speed levers on a bare update instead")
    parser.add_argument("--compile", action="store_true", help="with --levers: also torch.compile (slow to compile)")
    parser.add_argument("--ops", action="store_true", help="count the aten ops of one update per precision instead")
    args = parser.parse_args()
    torch.set_num_threads(1)
    logging.getLogger("torchrl").setLevel(logging.WARNING)
    if args.levers:
        levers(args.config, args.seconds, args.rounds, args.compile)
        return
    if args.ops:
        op_counts(args.config)
        return
    ours = Ours(args.config)
    hidden, batch = ours.config.agent.hidden, ours.config.buffer.batch_size
    try:
        theirs: OpenSpiel | None = OpenSpiel(hidden, batch)
    except ImportError as error:
        print(f"OpenSpiel not importable ({error}); install with: pip install open-spiel dm-tree")
        theirs = None
    mine_rounds, their_rounds = [], []
    for _ in range(args.rounds):
        mine_rounds.append(ours.measure(args.seconds))
        if theirs is not None:
            their_rounds.append(theirs.measure(args.seconds))
    ours.close()
    mine = _median(mine_rounds)
    precision = ours.config.optim.precision
    print(f"network {hidden}, batch {batch}, 1 torch thread, config precision {precision}; per CPU second, median of "
          f"{args.rounds} alternating rounds; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print("| learner | env frames/s | gradient updates/s |")
    print("|---|---|---|")
    print(f"| ncbot default pipeline, {precision} (batched dialogue env, TorchRL Collector) | "
          f"{mine['env_frames_per_s']:,.0f} | {mine['updates_per_s']:,.0f} |")
    other = "bf16" if precision == "fp32" else "fp32"
    print(f"| ncbot same update, optim.precision={other} | | {mine['other_updates_per_s']:,.0f} |")
    print(f"| ncbot full training loop (collect + {ours.config.optim.updates_per_batch} updates per "
          f"{ours.batch_frames} frames) | {mine['loop_frames_per_s']:,.0f} | {mine['loop_updates_per_s']:,.0f} |")
    print(f"replay sampling: {1e6 / mine['sample_per_s']:,.0f} us per batch of {batch}")
    if theirs is not None:
        their = _median(their_rounds)
        print(f"| OpenSpiel PyTorch DQN, tic_tac_toe (rl_environment, 1 game) | {their['env_frames_per_s']:,.0f} | "
              f"{their['updates_per_s']:,.0f} |")
        print(f"updates/s ratio ncbot / OpenSpiel: {mine['updates_per_s'] / their['updates_per_s']:.2f}x at "
              f"{precision}, {mine['other_updates_per_s'] / their['updates_per_s']:.2f}x at {other} "
              f"(OpenSpiel float32); env frames/s ratio: {mine['env_frames_per_s'] / their['env_frames_per_s']:.1f}x")


if __name__ == "__main__":
    main()
