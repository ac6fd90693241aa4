"""What MCAP logging costs: time added to training and bytes per 3x3 training episode (targets: <= 10 %, <= 2 KB).

Three measurements, each printed with the figures it produced:

  env     the real env (`ncbot.envs.make_env`) stepped by a uniformly random policy over the action mask, logged
          with the default packed training log and with one JSON message per action (random Q-values so
          the messages are as large as in training); time inside the logger against the rest of the same
          run. This is the WORST case for the ratio: real training also spends time on gradient updates
          and evaluations that logging does not touch.
  train   the share of a real training run's wall time spent inside the logger (timed in the same
          process, so machine noise cancels out); with --ab also the same `ncbot train` run with and
          without `--no-log` as separate processes (skip both with --skip-train).
  encode  the per-action /step messages written by `env`, re-encoded as protobuf (a schema built at run time with the
          same fields) vs our JSON, both in zstd-chunked MCAP: file size and encode time. Why JSON: see
          logs/README.md.

Timing on a shared 2-core machine is noisy, so every time ratio compares two times measured inside the
same run (logger calls timed around the call); each variant is run `--repeats` times and the median shown.

    python bench/mcap_overhead.py                       # all three, 3x3
    python bench/mcap_overhead.py --game ultimate --skip-train
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
torch.set_num_threads(1)


def random_policy_run(game: str, batch: int, steps: int, frames: int, seed: int, log_dir: Path | None,
                      detail: str = "packed") -> dict:
    """Step the real env with random legal actions; optionally log every step (phase train, `detail`).

    Steps are handed to the logger `frames` at a time as a (B, T) batch, as a TorchRL collector does."""
    from ncbot.envs import make_env
    from ncbot.logs import EpisodeLogger

    env = make_env(game=game, batch_size=(batch,), seed=seed)
    generator = torch.Generator().manual_seed(seed)
    logger = EpisodeLogger(log_dir, run_info={"bench": "mcap_overhead"}, step_detail={"train": detail}) \
        if log_dir is not None else None
    td = env.reset()
    episodes, window, inside = 0, [], 0.0
    started = time.perf_counter()
    for _ in range(steps):
        mask = td["action_mask"]
        td["action"] = torch.multinomial(mask.float(), 1, generator=generator).squeeze(-1)
        td["action_value"] = torch.randn(mask.shape, generator=generator) * 2.0
        td, next_root = env.step_and_maybe_reset(td)
        episodes += int(td["next", "done"].sum())
        window.append(td)
        if len(window) == frames:  # the (B, T) batch a collector hands over; built in every variant
            batch_td = torch.stack(window, dim=1)
            window = []
            if logger is not None:
                logging_started = time.perf_counter()
                logger.record_steps(batch_td, phase="train", agent="random", seed=seed, epsilon=1.0, env_steps=0,
                                    env=env)
                inside += time.perf_counter() - logging_started
        td = next_root
    if logger is not None:
        logging_started = time.perf_counter()
        logger.close()
        inside += time.perf_counter() - logging_started
    elapsed = time.perf_counter() - started
    env.close()
    return {"seconds": elapsed, "logger_seconds": inside, "episodes": episodes, "env_steps": steps * batch}


def bench_env(game: str, batch: int, steps: int, frames: int, repeats: int) -> Path:
    """Logger time relative to the rest of the same run (robust to a busy machine), and bytes per episode."""
    variants = ("packed", "per_action")
    ratios: dict[str, list[float]] = {variant: [] for variant in variants}
    per_step: dict[str, list[float]] = {variant: [] for variant in variants}
    sizes: dict[str, list[tuple[int, int]]] = {variant: [] for variant in variants}
    keep = Path(tempfile.mkdtemp(prefix="mcap_bench_"))
    for repeat in range(repeats):
        for variant in variants:
            log_dir = keep / f"{variant}{repeat}"
            result = random_policy_run(game, batch, steps, frames, seed=repeat, log_dir=log_dir, detail=variant)
            rest = result["seconds"] - result["logger_seconds"]
            ratios[variant].append(result["logger_seconds"] / rest)
            per_step[variant].append(result["logger_seconds"] / result["env_steps"])
            from ncbot.logs.reader import read_episodes

            total = sum(p.stat().st_size for p in log_dir.glob("*.mcap"))
            sizes[variant].append((total, len(read_episodes(log_dir))))
    print(f"[env] {game}, {batch} envs x {steps} steps, logged {frames} steps at a time as (B, T) batches, "
          f"{repeats} repeats, random policy on the real env; time inside the logger vs the rest of the same "
          f"run (env steps, policy, batching), medians")
    for variant in variants:
        per_episode = sum(s[0] for s in sizes[variant]) / max(1, sum(s[1] for s in sizes[variant]))
        print(f"  training steps {variant:<10}: +{100 * statistics.median(ratios[variant]):5.1f} % "
              f"({1e6 * statistics.median(per_step[variant]):.1f} us per logged step), "
              f"{per_episode:.0f} bytes per training episode on disk")
    return keep / "per_action0"


def bench_train(config: str, frames: int, repeats: int) -> None:
    """`ncbot train` with and without --no-log; compares the trainer's own "train wall time" (which
    includes its periodic evaluations, also logged) and the whole command's time."""
    import re

    timings: dict[str, list[float]] = {"off": [], "on": []}
    commands: dict[str, list[float]] = {"off": [], "on": []}
    summaries = []
    for repeat in range(repeats):
        for variant in ("off", "on"):
            out = Path(tempfile.mkdtemp(prefix=f"mcap_train_{variant}_"))
            command = [sys.executable, "-m", "ncbot", "train", config, f"collector.total_frames={frames}",
                       "--out", str(out), "--no-progress", "--seed", str(repeat)]
            if variant == "off":
                command.append("--no-log")
            started = time.perf_counter()
            result = subprocess.run(command, check=True, capture_output=True, text=True)
            commands[variant].append(time.perf_counter() - started)
            timings[variant].append(float(re.search(r"train wall time ([0-9.]+) s", result.stdout).group(1)))
            if variant == "on":
                from ncbot.logs.summary import summarize

                summaries.append(summarize(out))
    off, on = statistics.median(timings["off"]), statistics.median(timings["on"])
    print(f"[train] ncbot train {config} collector.total_frames={frames}, {repeats} repeats, seeds 0..{repeats - 1} (medians)")
    print(f"  train wall time: --no-log {off:.1f} s, with MCAP {on:.1f} s -> +{100 * (on - off) / off:.1f} %   "
          f"(whole command: {statistics.median(commands['off']):.1f} s vs {statistics.median(commands['on']):.1f} s)")
    last = summaries[-1]
    by_phase = {phase: stats["episodes"] for phase, stats in last["by_phase"].items()}
    print(f"  disk: {sum(f['bytes'] for f in last['files'])} bytes for {last['episodes']} episodes "
          f"= {last['bytes_per_episode']:.0f} bytes per episode (train and eval together: {by_phase})")


def bench_train_share(config: str, frames: int, repeats: int) -> None:
    """Time spent inside the logger as a share of the same process's whole training run.

    Immune to the between-run noise of a shared machine: both times come from one run. The logger's
    calls (record_steps, which also compresses and writes chunks, and close) are wrapped with a timer."""
    from ncbot.logs import EpisodeLogger
    from ncbot.pipelines.train.run import resolve_run, train

    spent = {"seconds": 0.0, "calls": 0}
    original_record, original_close = EpisodeLogger.record_steps, EpisodeLogger.close

    def timed(method):
        def wrapper(self, *args, **kwargs):
            started = time.perf_counter()
            try:
                return method(self, *args, **kwargs)
            finally:
                spent["seconds"] += time.perf_counter() - started
                spent["calls"] += 1
        return wrapper

    EpisodeLogger.record_steps, EpisodeLogger.close = timed(original_record), timed(original_close)
    shares = []
    try:
        for repeat in range(repeats):
            spent.update(seconds=0.0, calls=0)
            out = Path(tempfile.mkdtemp(prefix="mcap_share_"))
            run_config, run_dir, resuming = resolve_run(config, [f"collector.total_frames={frames}"], out=str(out),
                                                        seed=repeat, episodes=None, resume=None, mcap=True)
            run_config.logger.progress = False
            started = time.perf_counter()
            train(run_config, run_dir, resume=resuming)
            total = time.perf_counter() - started
            shares.append(spent["seconds"] / total)
            print(f"  run {repeat}: {total:.1f} s in train(), {spent['seconds']:.2f} s inside the logger "
                  f"({spent['calls']} calls) = {100 * shares[-1]:.1f} %")
    finally:
        EpisodeLogger.record_steps, EpisodeLogger.close = original_record, original_close
    print(f"[train-share] {config} collector.total_frames={frames}: logger share of training wall time, "
          f"median {100 * statistics.median(shares):.1f} % over {repeats} runs")


def bench_encoding(log_dir: Path) -> None:
    from mcap.writer import CompressionType, Writer

    from ncbot.logs.reader import LogReader

    steps = [m.data for m in LogReader(log_dir).messages(["/step"])]
    step_type, descriptor_set = _protobuf_step_type()
    results = {}
    for encoding in ("json", "protobuf"):
        path = log_dir.parent / f"steps-{encoding}.mcap"
        started = time.perf_counter()
        with open(path, "wb") as handle:
            writer = Writer(handle, compression=CompressionType.ZSTD)
            writer.start()
            if encoding == "json":
                schema = writer.register_schema("ncbot.Step", "jsonschema", b"{}")
            else:
                schema = writer.register_schema("ncbot.Step", "protobuf", descriptor_set)
            channel = writer.register_channel("/step", encoding, schema)
            for index, step in enumerate(steps):
                if encoding == "json":
                    data = json.dumps(step, separators=(",", ":")).encode()
                else:
                    data = step_type(episode=step["episode"], step=step["step"], who=step["who"], act=step["act"],
                                     mask=step["mask"], A=step.get("A", []), A_hat=step.get("A_hat", []),
                                     q=step.get("q", []), reward=step["reward"], on=step.get("on", []),
                                     val_index=[int(i) for i, _ in step.get("val", [])],
                                     val_value=[v for _, v in step.get("val", [])]).SerializeToString()
                writer.add_message(channel, log_time=index, publish_time=index, data=data)
            writer.finish()
        results[encoding] = (path.stat().st_size, time.perf_counter() - started)
    print(f"[encode] {len(steps)} /step messages from the env run, zstd-chunked MCAP")
    for encoding, (size, seconds) in results.items():
        print(f"  {encoding:<8} {size:>9} bytes ({size / len(steps):.1f} per step)  "
              f"{1e6 * seconds / len(steps):.1f} us per message to encode and write")


def _protobuf_step_type():
    """A protobuf message with the /step fields, built at run time (no protoc needed)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    proto = descriptor_pb2.FileDescriptorProto(name="ncbot_step.proto", package="ncbot", syntax="proto3")
    message = proto.message_type.add(name="Step")
    field = descriptor_pb2.FieldDescriptorProto
    spec = [("episode", field.TYPE_INT64, False), ("step", field.TYPE_INT32, False), ("who", field.TYPE_STRING, False),
            ("act", field.TYPE_INT32, False), ("mask", field.TYPE_INT32, True), ("A", field.TYPE_INT32, True),
            ("A_hat", field.TYPE_INT32, True), ("q", field.TYPE_FLOAT, True), ("reward", field.TYPE_FLOAT, False),
            ("on", field.TYPE_INT32, True), ("val_index", field.TYPE_INT32, True), ("val_value", field.TYPE_FLOAT, True)]
    for number, (name, kind, repeated) in enumerate(spec, start=1):
        message.field.add(name=name, number=number, type=kind,
                          label=field.LABEL_REPEATED if repeated else field.LABEL_OPTIONAL)
    pool = descriptor_pool.DescriptorPool()
    pool.Add(proto)
    descriptor_set = descriptor_pb2.FileDescriptorSet(file=[proto]).SerializeToString()
    return message_factory.GetMessageClass(pool.FindMessageTypeByName("ncbot.Step")), descriptor_set


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--game", default="standard", choices=["standard", "ultimate"])
    parser.add_argument("--batch", type=int, default=128, help="env batch size (the default training config uses 128)")
    parser.add_argument("--steps", type=int, default=240, help="batched env steps per run")
    parser.add_argument("--frames", type=int, default=8, help="steps per logged batch (collector frames / envs)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--config", default="pipelines/configs/default.yaml", help="training config for [train]")
    parser.add_argument("--train-frames", type=int, default=40960, help="collector.total_frames of each training run")
    parser.add_argument("--skip-train", action="store_true")
    parser.add_argument("--skip-env", action="store_true", help="only the [train] measurements")
    parser.add_argument("--ab", action="store_true", help="also run ncbot train with and without --no-log "
                                                          "(separate runs: noisy on a shared machine)")
    args = parser.parse_args()
    os.chdir(Path(__file__).resolve().parent.parent)
    if not args.skip_env:
        log_dir = bench_env(args.game, args.batch, args.steps, args.frames, args.repeats)
        bench_encoding(log_dir)
    if not args.skip_train:
        bench_train_share(args.config, args.train_frames, args.repeats)
        if args.ab:
            bench_train(args.config, args.train_frames, args.repeats)


if __name__ == "__main__":
    main()
