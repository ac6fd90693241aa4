"""The whole training story of one run, top to bottom (TorchRL sota-dqn style):

config -> batched dialogue env -> Q-network + look-ahead policies -> Collector -> replay buffer -> competitive DQN
loss + target updater -> periodic greedy evaluation and checkpoints -> MCAP log -> final checkpoint, eval.json and
learning-curve PNG.

Resuming (`resume=True`) reloads the newest periodic checkpoint, which holds the networks, optimiser, epsilon,
counters, RNG state, evaluation history AND the replay buffer (config `checkpoint.save_buffer`; when it is off the
buffer is rebuilt from fresh experience and updates wait for the burn-in again). The env restarts from fresh games:
a game in progress at the kill is lost, so a resumed run is a faithful continuation but not bit-identical to an
uninterrupted one. The MCAP log rolls to a new file at every periodic checkpoint and a resume deletes the files
written after the checkpoint it continues from: the log then holds exactly the training episodes the counters
count (episodes of the killed stretch are replayed, not double-logged).
"""
from __future__ import annotations

import json
import logging
import random
import time
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fileio import atomic_write_text
from pipelines.checkpoint import FINAL_NAME, FORMAT, atomic_save, save_periodic
from pipelines.config import RunConfig, config_from_dict, dump_config
from pipelines.run_folder import MCAP_KEY

SUCCESS_THRESHOLD = 0.995
EVAL_SEED_OFFSET = 1_000_003  # periodic evaluations play games that training never sees


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def frames_per_batch(config: RunConfig) -> int:
    """Collector batch rounded to a multiple of the env batch (a batched env steps all its games at once)."""
    batch = config.env.batch_size
    return max(batch, (config.collector.frames_per_batch // batch) * batch)


def next_multiple(frames: int, every: int) -> int:
    """The first multiple of `every` strictly after `frames`: when the next evaluation or checkpoint is due."""
    return (frames // every + 1) * every


def time_to_success(history: list[dict[str, Any]], threshold: float = SUCCESS_THRESHOLD) -> float | None:
    """Wall time of the first periodic evaluation whose task success reached `threshold`."""
    for record in history:
        if record["task_success"] >= threshold:
            return record["wall_time"]
    return None


def anneal_epsilon(egreedy: Any, frames: int) -> None:
    """TorchRL's `EGreedyModule.step(frames)`, skipped once annealing down has reached eps_end: from there a step
    leaves eps as it is (max(eps_end, eps_end - delta) = eps_end), and it runs a loop of tensor ops per frame."""
    if egreedy.eps_init >= egreedy.eps_end and bool(egreedy.eps <= egreedy.eps_end):
        return
    egreedy.step(frames)


def checkpoint_bytes(config: RunConfig) -> int:
    """About how large one periodic checkpoint of this run is (networks, Adam moments, replay buffer): the free
    space a run needs before it starts, so a full disk is one line at start-up rather than an error hours in."""
    features, actions = (289, 90) if config.env.game == "ultimate" else (73, 18)  # the larger (temporal) features
    widths = [features, *config.agent.hidden, actions]
    params = sum(a * b + b for a, b in zip(widths, widths[1:]))
    buffer = config.buffer.size * (2 * features * 4 + 2 * actions + 64) if config.checkpoint.save_buffer else 0
    return 4 * 4 * params + buffer + 2**20


def make_collector(env: Any, policy: Any, frames_per_batch: int, total_frames: int, *, keeps_views: bool = False):
    """TorchRL's Collector as the training loop uses it (and bench/learner_throughput.py measures it).

    Per-step overhead is most of a frame at the paper's 8-frame batches (docs/learner-speed.md): with device "cpu"
    named, the Collector keeps its TensorDicts there instead of casting every step to the env's device; each batch
    is used up before the next is collected (the buffer copies it, the MCAP log packs it into rows of its own), so
    it may hand out its own storage instead of a clone, unless the consumer `keeps_views` (n-step's
    MultiStepTransform keeps views of the last steps); nothing reads ("collector", "traj_ids").
    """
    from torchrl.collectors import Collector

    return Collector(env, policy, frames_per_batch=frames_per_batch, total_frames=total_frames, device="cpu",
                     auto_register_policy_transforms=False, return_same_td=not keeps_views, track_traj_ids=False)


def train(config: RunConfig, out_dir: str | Path, *, resume: bool = False, overwrite: bool = False) -> dict[str, Any]:
    """Train one agent into `out_dir`; returns the final evaluation (also written to eval.json).

    Start-up (pipelines/run_folder.py) before any work: the folder is checked (writable, not a file, room for a
    checkpoint), locked against a second writer, then claimed (a folder holding another run is refused unless
    `overwrite`) or, with `resume`, its newest checkpoint of this run that loads is picked (and named on stderr).
    """
    import sys

    from pipelines.checkpoint import check_training_state
    from pipelines.outputs import check_free_space, check_writable_dir
    from pipelines.run_folder import RunFolder

    _check_teacher_value(config)  # before the run folder is claimed: a bad path must not leave a started run
    check_writable_dir(out_dir, "--resume" if resume else "--out")
    check_free_space(out_dir, checkpoint_bytes(config), "a checkpoint of this run")
    run = RunFolder.open(out_dir, resume=resume, overwrite=overwrite,
                         validate=lambda state, path: check_training_state(state, path, config))
    try:
        for note in run.notes:
            print(f"ncbot: note: {note}", file=sys.stderr)
        return _train(config, run)
    finally:
        run.release()


def _train(config: RunConfig, run: Any) -> dict[str, Any]:
    """The run itself, in a locked run folder (`run.state`: the training state to resume from, or None)."""
    from modules.policy import make_policies
    from modules.recurrent import SequenceRows, make_agent_qnet, memory_env
    from modules.symmetry import make_symmetries
    from modules.transitions import make_multistep, prepare_transitions
    from pipelines.evaluate import evaluate_agent
    from pipelines.learner import Learner, make_replay_buffer, scheduled_lr
    from pipelines.plots import plot_learning_curve
    from pipelines.progress import progress_bar
    from pipelines.scalars import eval_scalars, open_scalar_log
    from pipelines.run_env import make_run_env

    logging.getLogger("torchrl").setLevel(logging.WARNING)
    started = time.monotonic()
    out_dir, state = run.path, run.state
    scalar_log = open_scalar_log(config.logger.backend, out_dir)  # train/... and eval/... scalars (TorchRL logger)
    atomic_write_text(dump_config(config), out_dir / "config.yaml")
    torch.set_num_threads(config.train.num_threads)
    seed = config.train.seed
    seed_everything(seed)

    # --- env and agent -------------------------------------------------------------------------------------------
    frames_done = state["frames"] if state else 0
    selfplay_pool = None
    if config.selfplay.enabled:  # the user's moves come from frozen snapshots of this agent (pipelines/selfplay.py)
        from pipelines.selfplay import make_selfplay_pool

        selfplay_pool = make_selfplay_pool(config.env, config.selfplay, seed)
    env = make_run_env(config.env, batch_size=config.env.batch_size, seed=seed + frames_done, opponent=selfplay_pool)
    qnet = make_agent_qnet(env.n_features, env.n_actions, config.agent, seed)  # the MLP, or agent.memory's network
    agent = make_policies(
        qnet, env.action_spec_unbatched, config.lookahead,
        eps_init=config.collector.eps_init, eps_end=config.collector.eps_end,
        annealing_frames=config.collector.annealing_frames,
    )
    env = memory_env(env, agent.explore)  # agent.memory: is_init and the hidden state carried by the env

    # --- loss, target network, optimiser, replay buffer ------------------------------------------------------------
    symmetries = make_symmetries(config.buffer.augment, env, seed)
    learner = Learner.from_config(qnet, config, symmetries)
    teacher = _make_teacher(config, agent.greedy, seed)  # search_targets: labels of the Q-guided search, or None
    learner.teacher = teacher
    if teacher is not None:
        learner.teacher_weight, learner.teacher_margin = config.search_targets.weight, config.search_targets.margin
    multistep = make_multistep(config.loss.n_step, config.loss.gamma)  # n-step returns when loss.n_step > 1
    buffer = make_replay_buffer(config.buffer.size, config.buffer.batch_size, prioritized=config.buffer.prioritized,
                                alpha=config.buffer.alpha, beta=config.buffer.beta,
                                sequence_length=config.buffer.sequence_length if config.agent.memory != "none" else None)
    sequence_rows = SequenceRows(config.agent.memory) if config.agent.memory != "none" else None

    counters = {"frames": 0, "updates": 0, "episodes": 0, "wall_offset": 0.0}
    history: list[dict[str, Any]] = []
    if state:
        try:
            qnet.load_state_dict(state["qnet"])
            learner.load_state_dict(state["learner"])
            agent.egreedy.load_state_dict(state["egreedy"])
            if state.get("buffer") is not None:
                buffer.load_state_dict(state["buffer"])
            if teacher is not None and state.get("teacher") is not None:
                teacher.load_state_dict(state["teacher"])
            torch.set_rng_state(state["rng"])
        except (RuntimeError, KeyError, TypeError, ValueError) as error:  # the checkpoint's parts do not fit this config
            raise ValueError(f"checkpoint {str(run.state_path)!r} does not fit the run's config "
                             f"({str(error).splitlines()[0][:160]})") from None
        counters.update({k: state[k] for k in ("frames", "updates", "episodes")})
        counters["wall_offset"] = state["wall_time"]
        history = list(state["history"])
    if selfplay_pool is not None:
        selfplay_pool.maybe_add(qnet, counters["frames"])

    # --- the Collector: exploratory games with the same masks as at test time -----------------------------------
    batch_frames = frames_per_batch(config)
    stop_on_episodes = config.train.episodes is not None
    remaining = -1 if stop_on_episodes else max(0, config.collector.total_frames - counters["frames"])
    if remaining > 0:  # whole collector batches (TorchRL would round up anyway, with a warning)
        remaining = -(-remaining // batch_frames) * batch_frames
    collector = None
    if remaining != 0:
        collector = make_collector(env, agent.explore, batch_frames, remaining, keeps_views=multistep is not None)

    def periodic_eval(recent_loss: float) -> dict[str, Any]:
        result = evaluate_agent(config, agent.greedy, games=config.eval.periodic_games, seat="alternate",
                                seed=seed + EVAL_SEED_OFFSET)
        record = {"frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
                  "wall_time": round(counters["wall_offset"] + time.monotonic() - started, 3),
                  "train_loss": recent_loss, "epsilon": float(agent.egreedy.eps), **result.to_dict()}
        history.append(record)
        if scalar_log is not None:
            scalar_log.log(eval_scalars(record), step=counters["frames"])
        return record

    def training_state() -> dict[str, Any]:
        return {
            "config": config.to_dict(), "n_features": env.n_features, "n_actions": env.n_actions,
            "qnet": qnet.state_dict(), "learner": learner.state_dict(), "egreedy": agent.egreedy.state_dict(),
            "buffer": buffer.state_dict() if config.checkpoint.save_buffer else None,
            "teacher": teacher.state_dict(keep_labels=config.checkpoint.save_buffer) if teacher is not None else None,
            "rng": torch.get_rng_state(), "history": history, "run_id": run.run_id,
            "frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
            "wall_time": counters["wall_offset"] + time.monotonic() - started,
        }

    mcap_logger = _open_mcap(config, out_dir)
    next_eval = next_multiple(counters["frames"], config.train.eval_every_frames)
    next_ckpt = next_multiple(counters["frames"], config.checkpoint.every_frames)
    bar_total = config.train.episodes if stop_on_episodes else config.collector.total_frames
    bar = progress_bar(total=bar_total, initial=counters["episodes"] if stop_on_episodes else counters["frames"],
                       unit="game" if stop_on_episodes else "frame", unit_scale=not stop_on_episodes,
                       disable=not config.logger.progress, desc=f"train {config.env.game} {config.agent.name}")
    batch_started = time.monotonic()
    losses: list[float] = []
    last_eval = history[-1] if history else None
    with mcap_logger or nullcontext():
        for batch in collector if collector is not None else ():  # bool(collector) calls len(): inf when open-ended
            frames, episodes_ended = batch.numel(), int(batch.get(("next", "done")).sum())
            counters["frames"] += frames
            counters["episodes"] += episodes_ended
            # learning reward, bootstrap mask and n-step windows under their own keys (modules/transitions.py)
            transitions = prepare_transitions(batch, config, multistep)
            if sequence_rows is not None:  # agent.memory: + dialogue id, step, is_init and hidden state
                transitions = sequence_rows(batch, transitions, counters["frames"] - frames)
            buffer.extend(transitions)
            if teacher is not None and counters["frames"] >= config.search_targets.start_frames:
                teacher.label(batch)
            if mcap_logger is not None:
                mcap_logger.record_steps(batch, phase="train", agent=config.agent.name, seed=seed,
                                         epsilon=float(agent.egreedy.eps), env_steps=counters["frames"], env=env)
            anneal_epsilon(agent.egreedy, frames)
            if selfplay_pool is not None:
                selfplay_pool.maybe_add(qnet, counters["frames"])

            # --- learning: several updates per collected batch once the burn-in is in the buffer ----------------
            if len(buffer) >= config.collector.init_random_frames:
                if config.schedule.lr_end is not None:
                    learner.set_lr(scheduled_lr(config, counters["frames"]))
                step_losses = learner.update_many(buffer, config.optim.updates_per_batch)
                counters["updates"] += len(step_losses)
                losses.append(float(torch.stack(step_losses).mean()))
            if scalar_log is not None:
                now = time.monotonic()
                seconds, batch_started = max(now - batch_started, 1e-9), now
                updated = len(buffer) >= config.collector.init_random_frames
                scalar_log.log({
                    "train/loss": losses[-1] if updated else None, "train/epsilon": float(agent.egreedy.eps),
                    "train/lr": learner.optimizer.param_groups[0]["lr"], "train/frames_per_s": frames / seconds,
                    "train/updates_per_s": config.optim.updates_per_batch / seconds if updated else 0.0,
                }, step=counters["frames"])

            # --- periodic greedy evaluation and checkpoint --------------------------------------------------------
            finished = (counters["episodes"] >= config.train.episodes) if stop_on_episodes else \
                counters["frames"] >= config.collector.total_frames
            finished = finished or (config.train.max_games is not None and counters["episodes"] >= config.train.max_games)
            if counters["frames"] >= next_eval or finished:
                last_eval = periodic_eval(float(np.mean(losses)) if losses else float("nan"))
                losses.clear()
                next_eval = next_multiple(counters["frames"], config.train.eval_every_frames)
            if counters["frames"] >= next_ckpt:
                # the log rolls here: its finished files hold exactly the episodes this checkpoint counts
                log_next = mcap_logger.roll() if mcap_logger is not None else None
                save_periodic({**training_state(), MCAP_KEY: log_next}, out_dir, counters["frames"],
                              config.checkpoint.keep)
                next_ckpt = next_multiple(counters["frames"], config.checkpoint.every_frames)
            bar.update(episodes_ended if stop_on_episodes else frames)
            bar.set_postfix(eps=f"{float(agent.egreedy.eps):.3f}", upd=counters["updates"],
                            success=f"{last_eval['task_success']:.3f}" if last_eval else "-", refresh=False)
            if finished:
                break
        bar.close()
        if collector is not None:
            collector.shutdown()

        # --- final agent, evaluation from both seats, curve ---------------------------------------------------------
        if not history or history[-1]["frames"] != counters["frames"]:
            periodic_eval(float(np.mean(losses)) if losses else float("nan"))
        final = {"format": FORMAT, "config": config.to_dict(), "n_features": env.n_features,
                 "n_actions": env.n_actions, "qnet": qnet.state_dict(), "frames": counters["frames"],
                 "updates": counters["updates"], "episodes": counters["episodes"], "run_id": run.run_id}
        atomic_save(final, out_dir / FINAL_NAME)
        report: dict[str, Any] = {
            "frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
            "train_wall_time_s": round(counters["wall_offset"] + time.monotonic() - started, 2),
            "time_to_0995_s": time_to_success(history),
        }
        for seat in ("first", "second"):
            result = evaluate_agent(config, agent.greedy, games=config.eval.games, seat=seat, seed=seed + 2 * EVAL_SEED_OFFSET,
                                    logger=mcap_logger, agent_name=config.agent.name)
            report[seat] = result.to_dict()
        if teacher is not None:
            report["search_targets"] = {"searched": teacher.searched, "labels": teacher.kept,
                                        "search_cpu_s": round(teacher.cpu_seconds, 2)}
        if selfplay_pool is not None:
            from pipelines.selfplay import pool_summary

            report["selfplay"] = pool_summary(selfplay_pool)
        report["history"] = history
    atomic_write_text(json.dumps(report, indent=2) + "\n", out_dir / "eval.json")
    plot_learning_curve(history, out_dir / "learning_curve.png",
                        title=f"{config.env.game} {config.agent.name} temporal={config.env.temporal} seed={seed}")
    env.close()
    return report


def _check_teacher_value(config: RunConfig) -> None:
    """`search_targets.value` names a value network for this run's game and rule (one-line errors otherwise)."""
    settings = config.search_targets
    if not settings.enabled or settings.value is None:
        return
    if config.env.game != "ultimate":
        raise ValueError(f"config key 'search_targets.value' scores Ultimate positions; this run plays "
                         f"{config.env.game} (leave it null)")
    from modules.value_net import load_value_net

    with torch.random.fork_rng():
        load_value_net(settings.value, config.env.free_move)


def _make_teacher(config: RunConfig, greedy: Any, seed: int):
    """The search teacher of `search_targets` (modules/search_targets.py) on the run's own Q-network, or None."""
    settings = config.search_targets
    if not settings.enabled:
        return None
    from modules.search_targets import SearchTeacher
    from pipelines.agents import guided_search

    with torch.random.fork_rng():  # building it draws no number from the run's stream: same run up to start_frames
        search = guided_search(config, greedy, settings.simulations, value=settings.value)
        return SearchTeacher(greedy, search, rows_per_batch=settings.rows_per_batch, seat=settings.seat,
                             gap=settings.gap, buffer_size=settings.buffer_size, batch_size=settings.batch_size,
                             seed=seed)


def _open_mcap(config: RunConfig, out_dir: Path):
    """The run's MCAP episode log (logs.EpisodeLogger), or None when switched off."""
    if not config.logger.mcap:
        return None
    from logs import EpisodeLogger

    return EpisodeLogger(out_dir, run_info={"command": "train", "config": config.to_dict()})


def resolve_run(config_path: str | None, overrides: list[str], *, out: str | None, seed: int | None,
                episodes: int | None, resume: str | None, mcap: bool) -> tuple[RunConfig, Path, bool]:
    """CLI arguments -> (config, run folder, resume?). With --resume the run's own config.yaml is the base.
    --seed and --episodes are validated with the config (same bounds, one line naming the option)."""
    from fileio.yaml_file import read_yaml
    from pipelines.config import MAX_SEED, apply_overrides, load_config

    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise ValueError(f"--seed must be between 0 and {MAX_SEED}, got {seed}")
    if episodes is not None and not 0 < episodes <= 10**9:
        raise ValueError(f"--episodes must be a positive number of training games (at most 1000000000), got {episodes}")
    overrides = list(overrides) + ([f"train.seed={seed}"] if seed is not None else []) \
        + ([f"train.episodes={episodes}"] if episodes is not None else []) + ([] if mcap else ["logger.mcap=false"])
    if resume:
        run_dir = Path(resume)
        if not run_dir.is_dir():
            raise FileNotFoundError(f"cannot resume: run folder {str(run_dir)!r} not found (expected the --out folder "
                                    "of an earlier ncbot train)")
        saved = run_dir / "config.yaml"
        if not saved.is_file():
            raise FileNotFoundError(f"cannot resume: {str(saved)!r} not found (expected a run folder of ncbot train)")
        data = read_yaml(saved, "run config", "the config.yaml ncbot train wrote into its run folder")
        if not isinstance(data, dict):
            raise ValueError(f"run config {str(saved)!r} must hold a mapping of sections; expected the config.yaml "
                             "ncbot train wrote")
        config = config_from_dict(apply_overrides(data, overrides))
    else:
        if config_path is None:
            raise ValueError("ncbot train needs a CONFIG file (e.g. pipelines/configs/default.yaml) or --resume DIR")
        config = load_config(config_path, overrides)
        run_dir = Path(out) if out else Path("runs") / Path(config_path).stem
    return config, run_dir, bool(resume)
