"""The whole training story of one run, top to bottom (TorchRL sota-dqn style):

config -> batched dialogue env -> Q-network + look-ahead policies -> Collector -> replay buffer -> competitive DQN
loss + target updater -> periodic greedy evaluation and checkpoints -> MCAP log -> final checkpoint, eval.json and
learning-curve PNG. Building the run's objects and restoring them: `ncbot.pipelines.train.build`; the loop:
`ncbot.pipelines.train.loop`.

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
import sys
import time
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.config import RunConfig, config_from_dict, dump_config
from ncbot.pipelines.machine import machine_record
from ncbot.pipelines.train.build import (build_parts, check_teacher_value, checkpoint_bytes, env_sizes, frames_per_batch,
                                   make_collector, restore)
from ncbot.pipelines.train.loop import TrainingLoop


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def train(config: RunConfig, out_dir: str | Path, *, resume: bool = False, overwrite: bool = False) -> dict[str, Any]:
    """Train one agent into `out_dir`; returns the final evaluation (also written to eval.json).

    Start-up (pipelines/run_folder.py) before any work: the folder is checked (writable, not a file, room for a
    checkpoint), locked against a second writer, then claimed (a folder holding another run is refused unless
    `overwrite`) or, with `resume`, its newest checkpoint of this run that loads is picked (and named on stderr).
    """
    from ncbot.pipelines.checkpoint import check_training_state
    from ncbot.pipelines.outputs import check_free_space, check_writable_dir
    from ncbot.pipelines.run_folder import RunFolder

    from ncbot.modules.device import resolve_device

    resolve_device(config.train.device)  # before the run folder is claimed: no GPU here is one line, nothing written
    check_teacher_value(config)  # before the run folder is claimed: a bad path must not leave a started run
    check_writable_dir(out_dir, "--resume" if resume else "--out")
    check_free_space(out_dir, checkpoint_bytes(config, *env_sizes(config)), "a checkpoint of this run")
    run = RunFolder.open(out_dir, resume=resume, overwrite=overwrite,
                         validate=lambda state, path: check_training_state(state, path, config))
    try:
        for note in run.notes:
            print(f"ncbot: note: {note}", file=sys.stderr)
        if config.agent.name == "uniform":
            from ncbot.pipelines.train.uniform import evaluate_uniform

            return evaluate_uniform(config, run)
        return _train(config, run)
    finally:
        run.release()


def _train(config: RunConfig, run: Any) -> dict[str, Any]:
    """The run itself, in a locked run folder (`run.state`: the training state to resume from, or None)."""
    from ncbot.pipelines.plots import plot_learning_curve
    from ncbot.pipelines.scalars import open_scalar_log

    logging.getLogger("torchrl").setLevel(logging.WARNING)
    started, cpu_started = time.monotonic(), time.process_time()
    out_dir, state = run.path, run.state
    scalar_log = open_scalar_log(config.logger.backend, out_dir)  # train/... and eval/... scalars (TorchRL logger)
    atomic_write_text(dump_config(config), out_dir / "config.yaml")
    torch.set_num_threads(config.train.num_threads)
    seed = config.train.seed
    seed_everything(seed)

    parts = build_parts(config, seed, frames_done=state["frames"] if state else 0)
    if state:
        restore(parts, state, run.state_path)
    if parts.selfplay_pool is not None:
        parts.selfplay_pool.maybe_add(parts.qnet, parts.counters["frames"])

    # --- the Collector: exploratory games with the same masks as at test time -----------------------------------
    batch_frames = frames_per_batch(config)
    remaining = -1 if config.train.episodes is not None else \
        max(0, config.collector.total_frames - parts.counters["frames"])
    if remaining > 0:  # whole collector batches (TorchRL would round up anyway, with a warning)
        remaining = -(-remaining // batch_frames) * batch_frames
    collector = None
    if remaining != 0:
        collector = make_collector(parts.env, parts.agent.explore, batch_frames, remaining,
                                   keeps_views=parts.multistep is not None, device=parts.device)

    mcap_logger = _open_mcap(config, out_dir)
    loop = TrainingLoop(config, parts, seed=seed, run_id=run.run_id, out_dir=out_dir, started=started,
                        cpu_started=cpu_started, scalar_log=scalar_log, mcap_logger=mcap_logger)
    with mcap_logger or nullcontext():
        loop.run(collector)
        report = loop.finish()
    report["machine"] = machine_record()  # which CPU, kernels, threads and versions made these numbers
    atomic_write_text(json.dumps(report, indent=2) + "\n", out_dir / "eval.json")
    plot_learning_curve(parts.history, out_dir / "learning_curve.png",
                        title=f"{config.env.game} {config.agent.name} temporal={config.env.temporal} seed={seed}")
    parts.env.close()
    return report


def _open_mcap(config: RunConfig, out_dir: Path):
    """The run's MCAP episode log (logs.EpisodeLogger), or None when switched off."""
    if not config.logger.mcap:
        return None
    from ncbot.logs import EpisodeLogger

    return EpisodeLogger(out_dir, run_info={"command": "train", "config": config.to_dict()})


def resolve_run(config_path: str | None, overrides: list[str], *, out: str | None, seed: int | None,
                episodes: int | None, resume: str | None, mcap: bool) -> tuple[RunConfig, Path, bool]:
    """CLI arguments -> (config, run folder, resume?). With --resume the run's own config.yaml is the base.
    --seed and --episodes are validated with the config (same bounds, one line naming the option)."""
    from ncbot.fileio.yaml_file import read_yaml
    from ncbot.pipelines.config import MAX_SEED, apply_overrides, load_config

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
