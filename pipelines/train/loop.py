"""The training loop of one run, as in TorchRL's DQN script: for every Collector batch, extend the replay buffer
with its transitions, anneal epsilon, and once past the burn-in run N updates (sample, loss, backward, step, target
update); then the hooks (`ncbot.pipelines.train.hooks`: periodic evaluation, checkpoints, self-play, search targets,
recurrent replay) and the log. At the end: the final agent (`ncbot.pipelines.checkpoint`) and its evaluation from
both seats.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import torch

from ncbot.pipelines.config import RunConfig
from ncbot.pipelines.errors import raise_if_terminated

SUCCESS_THRESHOLD = 0.995
EVAL_SEED_OFFSET = 1_000_003  # periodic evaluations play games that training never sees


def time_to_success(history: list[dict[str, Any]], threshold: float = SUCCESS_THRESHOLD) -> float | None:
    """Wall time of the first periodic evaluation whose task success reached `threshold`."""
    for record in history:
        if record["task_success"] >= threshold:
            return record["wall_time"]
    return None


def run_cpu_time(offset: float | None, started: float) -> float | None:
    """CPU seconds of this process (every thread) since `started`, plus those of the run's earlier parts
    (`offset`, from its checkpoint): unlike the wall time it leaves out time the process waited or was stopped, so
    it compares runs on a shared machine. None when the run resumed from a checkpoint that did not keep it: a
    partial sum would understate the run's cost."""
    return None if offset is None else offset + time.process_time() - started


def _rounded(seconds: float | None) -> float | None:
    return None if seconds is None else round(seconds, 2)


def anneal_epsilon(egreedy: Any, frames: int) -> None:
    """TorchRL's `EGreedyModule.step(frames)`, skipped once annealing down has reached eps_end: from there a step
    leaves eps as it is (max(eps_end, eps_end - delta) = eps_end), and it runs a loop of tensor ops per frame."""
    if egreedy.eps_init >= egreedy.eps_end and bool(egreedy.eps <= egreedy.eps_end):
        return
    egreedy.step(frames)


class TrainingLoop:
    """One run's loop over its Collector (`run`), then its final checkpoint and evaluation (`finish`)."""

    def __init__(self, config: RunConfig, parts: Any, *, seed: int, run_id: str, out_dir: Path, started: float,
                 cpu_started: float, scalar_log: Any = None, mcap_logger: Any = None) -> None:
        self.config, self.parts, self.seed, self.run_id, self.out_dir = config, parts, seed, run_id, out_dir
        self.started, self.cpu_started = started, cpu_started
        self.scalar_log, self.mcap_logger = scalar_log, mcap_logger
        self.counters = parts.counters
        self.stop_on_episodes = config.train.episodes is not None
        self.losses: list[float] = []  # mean loss of each learning batch since the last evaluation

    def wall_time(self) -> float:
        return self.counters["wall_offset"] + time.monotonic() - self.started

    def cpu_time(self) -> float | None:
        return run_cpu_time(self.counters["cpu_offset"], self.cpu_started)

    def _call(self, point: str, *args: Any) -> None:
        for hook in self.parts.hooks:
            getattr(hook, point)(self, *args)

    def extend(self, batch: Any) -> None:
        """A collected batch into the replay buffer (learning reward, bootstrap mask and n-step windows under their
        own keys, `ncbot.modules.replay.transitions`; what the hooks add), the MCAP log; then epsilon moves on."""
        config, parts, counters = self.config, self.parts, self.counters
        transitions = parts.transitions(batch)
        for hook in parts.hooks:
            transitions = hook.on_transitions(self, batch, transitions)
        parts.buffer.extend(transitions)
        self._call("on_collected", batch)
        if self.mcap_logger is not None:
            self.mcap_logger.record_steps(batch, phase="train", agent=config.agent.name, seed=self.seed,
                                          epsilon=float(parts.agent.egreedy.eps), env_steps=counters["frames"],
                                          env=parts.env)
        anneal_epsilon(parts.agent.egreedy, batch.numel())

    def learn(self) -> bool:
        """`optim.updates_per_batch` updates (sample, loss, backward, step, target update: `Learner.update_many`)
        once the burn-in is in the buffer; False before that."""
        from ncbot.modules.learner import scheduled_lr

        config, learner = self.config, self.parts.learner
        if len(self.parts.buffer) < config.collector.init_random_frames:
            return False
        if config.schedule.lr_end is not None:
            learner.set_lr(scheduled_lr(self.counters["frames"], config.optim.lr, config.schedule.lr_end,
                                        config.collector.total_frames))
        step_losses = learner.update_many(self.parts.buffer, config.optim.updates_per_batch)
        self.counters["updates"] += len(step_losses)
        self.losses.append(float(torch.stack(step_losses).mean()))
        return True

    def log_scalars(self, frames: int, seconds: float, updated: bool) -> None:
        self.scalar_log.log({
            "train/loss": self.losses[-1] if updated else None, "train/epsilon": float(self.parts.agent.egreedy.eps),
            "train/lr": self.parts.learner.optimizer.param_groups[0]["lr"], "train/frames_per_s": frames / seconds,
            "train/updates_per_s": self.config.optim.updates_per_batch / seconds if updated else 0.0,
        }, step=self.counters["frames"])

    def finished(self) -> bool:
        config, counters = self.config, self.counters
        done = (counters["episodes"] >= config.train.episodes) if self.stop_on_episodes else \
            counters["frames"] >= config.collector.total_frames
        return done or (config.train.max_games is not None and counters["episodes"] >= config.train.max_games)

    def run(self) -> None:
        """Collect, store, learn and call the hooks until the run's frames (or games) are done."""
        config, counters, agent = self.config, self.counters, self.parts.agent
        self._call("on_training_start")
        collector = self.parts.collector()  # built now: its first reset already plays what the hooks set up
        bar = self._progress_bar()
        batch_started = time.monotonic()
        for batch in collector if collector is not None else ():  # bool(collector) calls len(): inf when open-ended
            raise_if_terminated()  # a SIGTERM whose exception a finaliser swallowed still stops the run here
            frames, episodes_ended = batch.numel(), int(batch.get(("next", "done")).sum())
            counters["frames"] += frames
            counters["episodes"] += episodes_ended
            self.extend(batch)
            updated = self.learn()
            if self.scalar_log is not None:
                now = time.monotonic()
                seconds, batch_started = max(now - batch_started, 1e-9), now
                self.log_scalars(frames, seconds, updated)
            self._call("on_batch_end")
            last_eval = self.parts.history[-1] if self.parts.history else None
            bar.update(episodes_ended if self.stop_on_episodes else frames)
            bar.set_postfix(eps=f"{float(agent.egreedy.eps):.3f}", upd=counters["updates"],
                            success=f"{last_eval['task_success']:.3f}" if last_eval else "-", refresh=False)
            if self.finished():
                break
        bar.close()
        if collector is not None:
            collector.shutdown()
        self._call("on_collection_end")

    def _progress_bar(self) -> Any:
        from ncbot.pipelines.progress import progress_bar

        config, counters = self.config, self.counters
        return progress_bar(total=config.train.episodes if self.stop_on_episodes else config.collector.total_frames,
                            initial=counters["episodes"] if self.stop_on_episodes else counters["frames"],
                            unit="game" if self.stop_on_episodes else "frame", unit_scale=not self.stop_on_episodes,
                            disable=not config.logger.progress, desc=f"train {config.env.game} {config.agent.name}")

    def finish(self) -> dict[str, Any]:
        """The final agent (checkpoint.pt) and its evaluation from both seats; returns the run's report."""
        from ncbot.pipelines.checkpoint import FINAL_NAME, agent_state, atomic_save
        from ncbot.pipelines.evaluate.games import evaluate_agent
        from ncbot.pipelines.run_env import robot_seat

        config, counters, history = self.config, self.counters, self.parts.history
        atomic_save(agent_state(config, self.parts, self.run_id), self.out_dir / FINAL_NAME)
        report: dict[str, Any] = {
            "frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
            "seed": self.seed, "run_id": self.run_id,
            "train_wall_time_s": round(self.wall_time(), 2), "train_cpu_time_s": _rounded(self.cpu_time()),
            "time_to_0995_s": time_to_success(history),
        }
        for first in ("robot", "human"):
            result = evaluate_agent(config, self.parts.agent.greedy, games=config.eval.games, first=first,
                                    seed=self.seed + 2 * EVAL_SEED_OFFSET, logger=self.mcap_logger,
                                    agent_name=config.agent.name)
            report[robot_seat(first)] = result.to_dict()
        self._call("on_training_end", report)
        report["history"] = history
        return report
