"""What a training run does besides collect, store and learn, as hooks the loop calls at fixed points
(Stable-Baselines3's callbacks): the loop knows nothing of what they do.

Points, in the order the loop reaches them for every collected batch:
- `on_training_start(loop)`: once, before the first batch (after a resume's state is loaded);
- `on_transitions(loop, batch, transitions)`: the flat transitions of a batch before the replay buffer stores them;
  returns what to store (recurrent replay adds the dialogue ids, steps and hidden states);
- `on_collected(loop, batch)`: the batch is stored (search targets label it, self-play snapshots the network);
- `on_batch_end(loop)`: after the batch's updates and its scalars (periodic evaluation, then checkpoints);
- `on_collection_end(loop)`: after the last batch, before the final agent is saved;
- `on_training_end(loop, report)`: the final report, after the final evaluation from both seats.
A hook with state a resumed run needs names its `checkpoint_key`; `ncbot.pipelines.checkpoint` stores its
`state_dict()` there and gives it back through `load_state_dict`.

A new hook: subclass `TrainingHook`, override the points it needs, and add it in `ncbot.pipelines.train.build.make_hooks`.
"""
from __future__ import annotations

from typing import Any

from ncbot.pipelines.train.loop import EVAL_SEED_OFFSET


def next_multiple(frames: int, every: int) -> int:
    """The first multiple of `every` strictly after `frames`: when the next evaluation or checkpoint is due."""
    return (frames // every + 1) * every


class TrainingHook:
    """A hook that does nothing at every point; subclasses override the points they need."""

    checkpoint_key: str | None = None  # where its state lives in a periodic checkpoint, if it has any

    def on_training_start(self, loop: Any) -> None:
        pass

    def on_transitions(self, loop: Any, batch: Any, transitions: Any) -> Any:
        return transitions

    def on_collected(self, loop: Any, batch: Any) -> None:
        pass

    def on_batch_end(self, loop: Any) -> None:
        pass

    def on_collection_end(self, loop: Any) -> None:
        pass

    def on_training_end(self, loop: Any, report: dict[str, Any]) -> None:
        pass

    def state_dict(self) -> Any:
        return None

    def load_state_dict(self, state: Any) -> None:
        pass


class PeriodicEvaluation(TrainingHook):
    """Greedy games against the simulated user every `train.eval_every_frames` and at the end of training, each
    recorded in the run's history (and the scalar log)."""

    def on_training_start(self, loop: Any) -> None:
        self.next_frames = next_multiple(loop.counters["frames"], loop.config.train.eval_every_frames)

    def on_batch_end(self, loop: Any) -> None:
        frames = loop.counters["frames"]
        if frames >= self.next_frames or loop.finished():
            evaluate(loop)
            self.next_frames = next_multiple(frames, loop.config.train.eval_every_frames)

    def on_collection_end(self, loop: Any) -> None:
        """The final agent's history ends with an evaluation at its last frame."""
        history = loop.parts.history
        if not history or history[-1]["frames"] != loop.counters["frames"]:
            evaluate(loop)


def evaluate(loop: Any) -> dict[str, Any]:
    """A periodic greedy evaluation, recorded in the run's history (and the scalar log); the losses since the last
    one are its `train_loss`."""
    import numpy as np

    from ncbot.pipelines.evaluate.games import evaluate_agent
    from ncbot.pipelines.scalars import eval_scalars

    config, counters, agent = loop.config, loop.counters, loop.parts.agent
    result = evaluate_agent(config, agent.greedy, games=config.eval.periodic_games, first="alternate",
                            seed=loop.seed + EVAL_SEED_OFFSET)
    record = {"frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
              "wall_time": round(loop.wall_time(), 3),
              "train_loss": float(np.mean(loop.losses)) if loop.losses else float("nan"),
              "epsilon": float(agent.egreedy.eps), **result.to_dict()}
    loop.parts.history.append(record)
    if loop.scalar_log is not None:
        loop.scalar_log.log(eval_scalars(record), step=counters["frames"])
    loop.losses.clear()
    return record


class PeriodicCheckpoint(TrainingHook):
    """A periodic checkpoint every `checkpoint.every_frames` (`ncbot.pipelines.checkpoint`); the MCAP log rolls
    there, so its finished files hold exactly the episodes the checkpoint counts."""

    def on_training_start(self, loop: Any) -> None:
        self.next_frames = next_multiple(loop.counters["frames"], loop.config.checkpoint.every_frames)

    def on_batch_end(self, loop: Any) -> None:
        from ncbot.pipelines.checkpoint import save_periodic, training_state

        frames = loop.counters["frames"]
        if frames < self.next_frames:
            return
        log_next = loop.mcap_logger.roll() if loop.mcap_logger is not None else None
        state = training_state(loop.config, loop.parts, loop.run_id, loop.wall_time(), loop.cpu_time(), log_next)
        save_periodic(state, loop.out_dir, frames, loop.config.checkpoint.keep)
        self.next_frames = next_multiple(frames, loop.config.checkpoint.every_frames)


class RecurrentReplay(TrainingHook):
    """Recurrent replay (an objective that replays slices of dialogues): each stored transition also carries its
    dialogue id, step number, `is_init` and the hidden state before it (`ncbot.modules.replay.sequences.SequenceRows`)."""

    def __init__(self, memory: str) -> None:
        from ncbot.modules.replay.sequences import SequenceRows

        self.rows = SequenceRows(memory)

    def on_transitions(self, loop: Any, batch: Any, transitions: Any) -> Any:
        return self.rows(batch, transitions, loop.counters["frames"] - batch.numel())


class SearchTargets(TrainingHook):
    """Search targets (`search_targets`): after `start_frames`, robot moves of every stored batch are searched and
    kept as labels (`ncbot.modules.search.search_targets.SearchTeacher`, which the learner also adds as its margin
    loss); its generators, counts and labels are checkpointed."""

    checkpoint_key = "teacher"

    def __init__(self, teacher: Any, start_frames: int, keep_labels: bool) -> None:
        self.teacher, self.start_frames, self.keep_labels = teacher, start_frames, keep_labels

    def on_collected(self, loop: Any, batch: Any) -> None:
        if loop.counters["frames"] >= self.start_frames:
            self.teacher.label(batch)

    def on_training_end(self, loop: Any, report: dict[str, Any]) -> None:
        teacher = self.teacher
        report["search_targets"] = {"searched": teacher.searched, "labels": teacher.kept,
                                    "search_cpu_s": round(teacher.cpu_seconds, 2)}

    def state_dict(self) -> Any:
        return self.teacher.state_dict(keep_labels=self.keep_labels)

    def load_state_dict(self, state: Any) -> None:
        self.teacher.load_state_dict(state)
