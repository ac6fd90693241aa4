"""How the competitive DQN objective runs its target network, measured on a config's own learner: updates per CPU
second of the bare update (loss, backward, clip, Adam, target update) and of the training loop (collect a batch,
store it, its updates), for three ways to the same target bits.

    python bench/target_network.py [--config pipelines/configs/paper/standard_proposed.yaml] [--seconds 2] [--rounds 5]

- `swap` (TorchRL's default use of an estimator): the TD(0) estimator runs the loss's value network on `step_mdp`
  of the batch with the target parameters swapped in and out at every update (`value_estimate(td,
  target_params=...)`);
- `bound` (what `competitive_dqn` ships): the estimator runs `TargetNetwork`, a copy of the value network bound once
  to the target parameters (TorchRL's public `TensorDictBase.to_module`; the target updater writes those tensors in
  place), as one module: no swap;
- `tensors`: the bootstrap value computed by the loss on the tensors of that copy and handed to the estimator as
  `next_value`: no swap, no `step_mdp`, no TensorDict pass, but the estimator no longer runs the target network.
The three give the same losses bit for bit (checked first, on the same batches), and each variant's loop draws its
own copy of one random stream, so all three play the same games and replay the same rows; the variants take turns over
`--rounds` rounds and the median is reported, with ratios against `swap` from the same run (a shared machine's load
moves every figure; compare ratios, not rates across runs). Results: docs/learner-speed.md.
"""
from __future__ import annotations

import argparse
import logging
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree's objective, not an installed copy

from ncbot.modules.objectives.competitive_dqn import CompetitiveDQNLoss  # noqa: E402


class Swap(CompetitiveDQNLoss):
    """TorchRL's default: the estimator swaps the target parameters into the loss's value network per update."""

    def make_value_estimator(self, value_type=None, **hyperparams) -> None:
        super().make_value_estimator(value_type, **hyperparams)
        self._value_estimator = type(self._value_estimator)(**hyperparams, value_network=self.value_network)
        self._forward_value_estimator_keys()

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        keys = self.tensor_keys
        masked_max = self.value_network[1]
        masked_max.mask_key, masked_max.in_keys = keys.bootstrap_mask, [masked_max.value_key, keys.bootstrap_mask]
        self.value_network.in_keys = [*self.value_network[0].in_keys, keys.bootstrap_mask]
        if self._value_estimator is not None:
            self._value_estimator.set_keys(value=keys.value, reward=keys.reward, done=keys.done,
                                           terminated=keys.terminated, steps_to_next_obs=keys.steps_to_next_obs)

    def forward(self, tensordict):
        q_values = self._online_q(tensordict).float()
        with torch.no_grad():
            target = self.value_estimator.value_estimate(tensordict, target_params=self.target_value_network_params)
        return self._td_loss(tensordict, q_values, target.squeeze(-1))


class TensorBootstrap(CompetitiveDQNLoss):
    """The bound copy's masked max computed by the loss on the tensors and handed to the estimator as `next_value`."""

    def forward(self, tensordict):
        network = self.value_estimator.value_network
        q_values = self._online_q(tensordict).float()
        with torch.no_grad():
            values = network.q_values(tensordict.get("next"))
            masked = values.masked_fill(~tensordict.get(("next", network.masked_max.mask_key)),
                                        torch.finfo(values.dtype).min)
            target = self.value_estimator.value_estimate(tensordict, next_value=masked.max(-1)[0].unsqueeze(-1))
        return self._td_loss(tensordict, q_values, target.squeeze(-1))


VARIANTS = {"swap": Swap, "bound": CompetitiveDQNLoss, "tensors": TensorBootstrap}


def build(config_path: str, cls: type):
    """The config's training parts (`ncbot.pipelines.train.build.assemble`) with the objective of class `cls`."""
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.build import RunSetup, assemble, check_run

    config = load_config(config_path, ["logger.mcap=false", "selfplay.enabled=false", "search_targets.enabled=false"])
    torch.manual_seed(0)
    setup = check_run(config)
    return config, assemble(config, RunSetup(setup.device, cls), config.train.seed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="pipelines/configs/paper/standard_proposed.yaml")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    logging.getLogger("torchrl").setLevel(logging.WARNING)
    torch.set_num_threads(1)
    runs = {name: build(args.config, cls) for name, cls in VARIANTS.items()}
    collectors = {name: iter(parts.collector()) for name, (_, parts) in runs.items()}

    def collect(name: str) -> None:
        _, parts = runs[name]
        parts.buffer.extend(parts.transitions(next(collectors[name])))

    for name, (config, parts) in runs.items():  # a full replay buffer, as for most of a run: the same in each
        torch.manual_seed(0)
        while len(parts.buffer) < config.buffer.size:
            collect(name)
    config = runs["swap"][0]
    torch.manual_seed(1)
    batches = [runs["swap"][1].buffer.sample() for _ in range(32)]
    losses = {name: [parts.learner.update(batch.clone()) for batch in batches] for name, (_, parts) in runs.items()}
    assert all(torch.equal(a, b) for name in runs for a, b in zip(losses[name], losses["swap"])), "bits differ"

    def updates(name: str) -> float:
        learner, count, start = runs[name][1].learner, 0, time.process_time()
        while time.process_time() - start < args.seconds:
            learner.update(batches[count % len(batches)].clone())
            count += 1
        return count / (time.process_time() - start)

    streams = {name: torch.get_rng_state() for name in runs}  # each variant's own draws: the same games and rows

    def loop(name: str) -> float:
        parts, count = runs[name][1], 0
        torch.set_rng_state(streams[name])
        start = time.process_time()
        while time.process_time() - start < args.seconds:
            collect(name)
            count += len(parts.learner.update_many(parts.buffer, config.optim.updates_per_batch))
        seconds = time.process_time() - start
        streams[name] = torch.get_rng_state()
        return count / seconds

    rates: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.rounds):
        for name in runs:
            rates.setdefault((name, "update"), []).append(updates(name))
            rates.setdefault((name, "loop"), []).append(loop(name))
    print(f"{args.config}: batch {config.buffer.batch_size}, hidden {config.agent.hidden}, "
          f"{config.optim.updates_per_batch} updates per {config.collector.frames_per_batch}-frame batch; "
          f"median of {args.rounds} rounds, updates per CPU second")
    print("| target pass | bare update | vs swap | training loop | vs swap |")
    print("|---|---|---|---|---|")
    base = {kind: statistics.median(rates["swap", kind]) for kind in ("update", "loop")}
    for name in runs:
        update, whole = statistics.median(rates[name, "update"]), statistics.median(rates[name, "loop"])
        print(f"| {name} | {update:.0f} | {update / base['update']:.2f}x | {whole:.0f} | {whole / base['loop']:.2f}x |")


if __name__ == "__main__":
    main()
