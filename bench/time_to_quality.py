"""Time to a good agent, side by side: our default agent against OpenSpiel's PyTorch DQN, on this machine, in one run.

What users feel is not updates per second but how long until the agent is good. This bench trains both learners
one after the other (each alone on the machine as far as this bench goes; other load is reported), snapshots
each every few seconds of its own training clock, then evaluates every snapshot the same way: greedy, ``--games``
games per seat against the uniform random player, refereed by our rules; task success = 1 - loss rate.
It prints the training wall time at which each first reaches task success 0.95 and 0.995 in BOTH seats (or
"never" within ``--cap-seconds``) and the ratio.

- Ours: ``ncbot train pipelines/configs/default.yaml`` (``--ultimate``: ``ultimate.yaml``) in a subprocess, with
  its in-training evaluations switched off (``train.eval_every_frames`` past the end: evaluating is not training)
  and a periodic checkpoint every ``--snapshot-frames`` frames, whose saved ``wall_time`` is the training clock.
  Evaluated as it is deployed: the robot in its dialogue env against the random user (``ncbot eval``'s code).
- Theirs: ``open_spiel.python.pytorch.dqn.DQN`` with the settings of OpenSpiel's
  ``examples/tic_tac_toe_dqn_vs_tabular.py`` (hidden [32, 32], replay capacity 10,000, every other argument at
  its default), one DQN per seat. ``--dqn-opponent dqn`` (default): the two DQNs learn against each other
  (OpenSpiel's two-player DQN examples; the tic_tac_toe example's opponent also learns); ``random``: each seat's
  DQN learns against the uniform random player, as our agent does. Snapshots every ``--snapshot-seconds`` of its
  training clock (the copy is taken off the clock). Evaluated through ``ncbot.envs.opponents.arena`` with OpenSpiel's
  own observation tensor, its moves checked against our rules (``ncbot.envs.opponents.openspiel``).

Snapshots are evaluated in time order and evaluation stops at the first snapshot with 0.995 in both seats.

``--exact`` (3x3 only) scores every snapshot of both learners exactly instead: every branch of the uniform random
player (ours: ``ncbot eval --exhaustive``, 8 dialogue draws; theirs: OpenSpiel's game tree under the DQN's greedy
moves). Why: a policy that loses 0.5 % of games shows <= 5 losses in 1000 with probability ~0.6, so the first
sampled crossing of 0.995 is partly luck, for either side.

``--ours-search N [--ours-value V]`` adds a second curve for ours, "ours + search": the same snapshots deciding every
game move by the Q-guided search (``ncbot eval --search N --value V``), with the value network's own CPU seconds
(labelling + training, its value.json) added to both clocks. It answers "how soon do I have an agent that plays
this well as deployed with search"; greedy stays the headline (OpenSpiel's DQN has no search).

    python bench/time_to_quality.py                          # 3x3
    python bench/time_to_quality.py --exact --clock cpu      # 3x3, exact scores (no evaluation noise)
    python bench/time_to_quality.py --game ultimate --clock cpu --cap-seconds 900

Ultimate: OpenSpiel's ``ultimate_tic_tac_toe`` is our ``open_subgrids`` rule (sent to a decided subgrid, play in
any undecided one), so ours trains ``ultimate.yaml`` with ``env.free_move=open_subgrids`` (the config's
``env.free_move`` selects the rule; ``--free-move`` overrides it) and both are evaluated under that rule.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

THRESHOLDS = (0.95, 0.995)
NEVER_EVALUATE = 10**10  # train.eval_every_frames past any run's end (the config caps it at 1e10)

from ncbot.pipelines.evaluate.openspiel_dqn import dqn_worker, evaluate_dqn, exact_dqn, first_time  # noqa: E402


def load_average() -> str:
    return " / ".join(f"{x:.1f}" for x in os.getloadavg())


def process_cpu(pid: int) -> float | None:
    """CPU seconds (user + system, with waited-for children) of a running process, from /proc; None once gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")  # utime stime cutime cstime


def run_timed(command: list[str], timeout: float | None = None, cpu_timeout: float | None = None) -> dict[str, Any]:
    """Run a trainer subprocess, sampling its CPU seconds every 0.2 s (``samples``: (epoch seconds, CPU seconds)).

    Wall times swing with the other load on this shared machine; CPU seconds much less (not at all is too
    much to hope: shared caches), so both are reported."""
    load_before, began = load_average(), time.monotonic()
    process = subprocess.Popen(command, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL)
    samples: list[tuple[float, float]] = []
    stopped = False
    while process.poll() is None:
        cpu = process_cpu(process.pid)
        if cpu is not None:
            samples.append((time.time(), cpu))
        over_cpu = cpu_timeout is not None and cpu is not None and cpu > cpu_timeout
        if over_cpu or timeout is not None and time.monotonic() - began > timeout:  # killed at the cap: its snapshots count
            process.kill()
            stopped = True
            break
        time.sleep(0.2)
    if process.wait() != 0 and not stopped:
        raise RuntimeError(f"{command[2] if len(command) > 2 else command} failed with exit code {process.returncode}")
    wall = time.monotonic() - began
    cpu = samples[-1][1] if samples else 0.0
    return {"command": " ".join(command), "stopped_at_cap": stopped, "process_seconds": round(wall, 1),
            "cpu_seconds": round(cpu, 1), "cpu_share": round(cpu / wall, 2), "load_before": load_before,
            "load_after": load_average(), "samples": samples}


def cpu_at(samples: list[tuple[float, float]], epoch: float) -> float:
    """The sampled CPU seconds of a process at ``epoch`` (linear between samples)."""
    import numpy as np

    return float(np.interp(epoch, [t for t, _ in samples], [c for _, c in samples]))


# ------------------------------------------------------------------------------------------------------ ours
def train_ours(config: str, out: Path, cap: float, clock: str, snapshot_frames: int, seed: int,
               overrides: list[str] | None = None) -> dict[str, Any]:
    """Run ``ncbot train`` (this tree's code) in a subprocess, stopped at ``cap`` seconds of ``clock``; snapshots
    with their train clock (wall) and the CPU seconds the process spent since the train clock started."""
    import shutil

    from ncbot.pipelines.checkpoint import periodic_checkpoints

    shutil.rmtree(out, ignore_errors=True)  # snapshots of an earlier run must not count

    command = [sys.executable, "-m", "ncbot", "train", config, "--out", str(out), "--no-log", "--no-progress",
               "--seed", str(seed), f"train.eval_every_frames={NEVER_EVALUATE}",
               f"checkpoint.every_frames={snapshot_frames}", "checkpoint.keep=1000", "checkpoint.save_buffer=false",
               "eval.games=10", "eval.periodic_games=10", *(overrides or [])]
    # start-up (imports, env and tables) is off the train clock: allow it on top of the cap
    run = run_timed(command, timeout=cap + 60) if clock == "wall_time" else run_timed(command, cpu_timeout=cap + 30)
    import torch

    snapshots = []
    samples = run.pop("samples")
    for path in periodic_checkpoints(out):
        data = torch.load(path, map_location="cpu", weights_only=True)
        saved = path.stat().st_mtime  # the train clock starts inside train(): imports and CLI set-up excluded
        cpu = cpu_at(samples, saved) - cpu_at(samples, saved - data["wall_time"]) if samples else float("nan")
        if (data["wall_time"] if clock == "wall_time" else cpu) <= cap:
            snapshots.append({"wall_time": float(data["wall_time"]), "cpu_time": round(cpu, 2),
                              "frames": int(data["frames"]), "episodes": int(data["episodes"]), "path": str(path)})
    return {**run, "snapshots": snapshots}


def evaluate_ours(snapshot: dict[str, Any], games: int, seed: int, search: int | None = None,
                  value: str | None = None) -> dict[str, float]:
    """Task success of a snapshot from each seat: greedy, or (``search``) with its game moves chosen by the
    Q-guided search of ``search`` simulations (``value``: a value network scores the leaves), as ``ncbot eval
    --search N --value V`` plays it."""
    from ncbot.pipelines.agents import load_agent, load_guided_agent
    from ncbot.pipelines.evaluate.games import evaluate_agent

    config, policy = load_guided_agent(snapshot["path"], search, seed, value) if search else load_agent(snapshot["path"])
    from ncbot.pipelines.run_env import robot_seat

    return {robot_seat(first): evaluate_agent(config, policy, games=games, first=first, seed=seed).task_success
            for first in ("robot", "human")}


def exact_ours(snapshot: dict[str, Any]) -> dict[str, float]:
    """Exact task success of a 3x3 snapshot from each seat: every branch of the uniform random user, 8 dialogue
    draws (``ncbot eval --exhaustive``): no evaluation noise, which near 0.995 is most of a 1000-game figure."""
    from ncbot.pipelines.evaluate.exact import exact_checkpoint

    return {result.seat: result.task_success for result in exact_checkpoint(snapshot["path"])}


def value_network_cpu(value: str) -> float:
    """CPU seconds that made a value network (labelling + training, from the value.json ncbot train-value wrote
    beside it): part of the time to an agent that searches with it."""
    report = json.loads((Path(value).parent / "value.json").read_text())
    return float(report["labelling_cpu_s"]) + float(report["training_cpu_s"])


def check_search_options(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """--ours-search / --ours-value: a positive budget; a value network for the rule ours trains on, with the
    value.json its CPU seconds are read from (one line and exit 2 otherwise, via ``parser.error``)."""
    if args.ours_search is not None and args.ours_search < 1:
        parser.error(f"--ours-search must be a positive number of simulations, got {args.ours_search}")
    if args.ours_value is None:
        return
    if not args.ours_search:
        parser.error("--ours-value scores the leaves of the search: give --ours-search N too")
    if not args.ultimate:
        parser.error("--ours-value is for Ultimate (--game ultimate): value networks score Ultimate positions")
    from ncbot.modules.search.value_net import load_value_net

    try:
        load_value_net(args.ours_value, args.free_move)
        value_network_cpu(args.ours_value)
    except (OSError, ValueError, KeyError) as error:
        parser.error(f"--ours-value: {error}")


# ------------------------------------------------------------------------------------------------------ theirs
def train_dqn(game: str, out: Path, cap: float, clock: str, every: float, opponent: str, hidden: list[int],
              seed: int) -> dict[str, Any]:
    command = [sys.executable, str(Path(__file__).resolve()), "--worker", "--cap-seconds", str(cap), "--clock", clock.split("_")[0],
               "--snapshot-seconds", str(every), "--dqn-opponent", opponent, "--dqn-hidden",
               ",".join(map(str, hidden)), "--seed", str(seed), "--out", str(out)] + (["--ultimate"] if game == "ultimate" else [])
    run = run_timed(command)
    run.pop("samples")
    import torch

    return {**run, "data": torch.load(out, map_location="cpu", weights_only=True)}


# ------------------------------------------------------------------------------------------------------ report
def curve(snapshots: list[dict[str, Any]], evaluate) -> list[dict[str, Any]]:
    """Evaluate snapshots in time order until both seats reach the top threshold."""
    points = []
    for snapshot in snapshots:
        success = evaluate(snapshot)
        point = {k: snapshot[k] for k in ("wall_time", "cpu_time", "frames", "episodes", "steps") if k in snapshot} | success
        points.append(point)
        print(f"  t={point['wall_time']:7.1f}s cpu={point['cpu_time']:7.1f}s first {success['first']:.4f} second {success['second']:.4f}", flush=True)
        if min(success.values()) >= THRESHOLDS[-1]:
            break
    return points


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--game", choices=("standard", "ultimate"), default="standard",
                        help="ultimate: ours ultimate.yaml on the open_subgrids rule; theirs ultimate_tic_tac_toe")
    parser.add_argument("--ultimate", action="store_true", help="same as --game ultimate")
    parser.add_argument("--free-move", choices=("anywhere", "open_subgrids"), default="open_subgrids",
                        help="Ultimate rule our agent trains on (OpenSpiel's game is open_subgrids; default)")
    parser.add_argument("--cap-seconds", type=float, default=600.0, help="training time limit of each learner (--clock)")
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                        help="what the cap and the DQN snapshot period count: wall seconds, or CPU seconds of the "
                             "trainer's process (for a machine loaded by others; both are reported either way)")
    parser.add_argument("--snapshot-seconds", type=float, default=5.0, help="DQN snapshot period (its training clock)")
    parser.add_argument("--snapshot-frames", type=int, default=None, help="our snapshot period in env frames (default: ~every 2-8 s)")
    parser.add_argument("--games", type=int, default=1000, help="evaluation games per seat and snapshot")
    parser.add_argument("--dqn-opponent", choices=("dqn", "random"), default="dqn")
    parser.add_argument("--dqn-hidden", default="32,32", help="DQN hidden layers (the tic_tac_toe example: 32,32)")
    parser.add_argument("--config", default=None, help="our config (default: default.yaml / ultimate.yaml)")
    parser.add_argument("--only", choices=("ours", "dqn"), default=None, help="train and evaluate one side only")
    parser.add_argument("--ours-search", type=int, default=None,
                        help="also evaluate our snapshots with the Q-guided search of N simulations at decision time "
                             "(a second curve, 'ours + search'; greedy stays the headline)")
    parser.add_argument("--ours-value", default=None,
                        help="with --ours-search on Ultimate: the value network (ncbot train-value) for the search's "
                             "leaves; its labelling + training CPU seconds are added to that curve's clocks")
    parser.add_argument("--exact", action="store_true",
                        help="3x3: score every snapshot of both learners exactly (every branch of the random player) "
                             "instead of --games sampled games per seat")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="/tmp/time_to_quality")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    game = "ultimate" if args.ultimate else args.game
    args.ultimate = game == "ultimate"
    clock = f"{args.clock}_time"
    hidden = [int(h) for h in args.dqn_hidden.split(",") if h]
    if args.worker:
        dqn_worker(game, args.cap_seconds, clock, args.snapshot_seconds, args.dqn_opponent, hidden, Path(args.out), args.seed)
        return
    check_search_options(parser, args)  # before any training: a bad value network must not cost a run
    if args.exact and (args.ultimate or args.ours_search):
        parser.error("--exact scores 3x3 greedy snapshots only (Ultimate's game tree is too large to enumerate)")
    from ncbot.envs.opponents.openspiel import import_pyspiel

    import_pyspiel()  # one clear line if the optional package is missing, before any training
    out = Path(args.out) / game
    out.mkdir(parents=True, exist_ok=True)
    config = args.config or str(ROOT / "pipelines" / "configs" / ("ultimate.yaml" if args.ultimate else "default.yaml"))
    snapshot_frames = args.snapshot_frames or (51200 if args.ultimate else 4096)
    report: dict[str, Any] = {"game": game, "games_per_seat": "exact" if args.exact else args.games,
                              "cap_seconds": args.cap_seconds, "clock": clock,
                              "cpus": os.cpu_count()}
    if args.only in (None, "ours"):
        overrides = [f"env.free_move={args.free_move}"] if args.ultimate else []
        print(f"ours: training {config} {' '.join(overrides)} (load {load_average()})", flush=True)
        report["ours_overrides"] = overrides
        ours = train_ours(config, out / "ours", args.cap_seconds, clock, snapshot_frames, args.seed, overrides)
        print(f"ours: {len(ours['snapshots'])} snapshots; evaluating", flush=True)
        ours["points"] = curve(ours["snapshots"], exact_ours if args.exact else
                               lambda s: evaluate_ours(s, args.games, args.seed + 17))
        report["ours"] = {k: v for k, v in ours.items() if k != "snapshots"}
        if args.ours_search:
            extra = value_network_cpu(args.ours_value) if args.ours_value else 0.0
            print(f"ours + search {args.ours_search}{' + value network' if args.ours_value else ''}: evaluating "
                  f"(+{extra:.1f} s on both clocks for the value network)", flush=True)
            points = curve(ours["snapshots"], lambda s: evaluate_ours(s, args.games, args.seed + 17, args.ours_search,
                                                                      args.ours_value))
            for point in points:
                point["wall_time"] += extra
                point["cpu_time"] += extra
            report["ours_search"] = {**{k: v for k, v in ours.items() if k not in ("snapshots", "points")},
                                     "points": points, "simulations": args.ours_search, "value": args.ours_value,
                                     "value_network_cpu_s": extra}
    if args.only in (None, "dqn"):
        print(f"OpenSpiel DQN: training (load {load_average()})", flush=True)
        theirs = train_dqn(game, out / "dqn_snapshots.pt", args.cap_seconds, clock, args.snapshot_seconds, args.dqn_opponent,
                           hidden, args.seed)
        data = theirs.pop("data")
        print(f"OpenSpiel DQN: {len(data['snapshots'])} snapshots; evaluating", flush=True)
        theirs["points"] = curve(data["snapshots"], (lambda s: exact_dqn(s, data)) if args.exact else
                                 lambda s: evaluate_dqn(s, data, game, args.games, args.seed + 17))
        theirs["settings"], theirs["opponent"] = data["settings"], data["opponent"]
        report["dqn"] = theirs
    scored = "exact over every random-player branch" if args.exact else f"{args.games} games per seat"
    print(f"\n{game}: training wall time to task success vs uniform random, both seats ({scored}), "
          f"cap {args.cap_seconds:.0f} {args.clock} s")
    sides = ("ours", "ours_search", "dqn")
    print("| threshold | clock | ours, greedy (s) | ours + search (s) | OpenSpiel DQN (s) | DQN / ours greedy | "
          "DQN / ours + search |\n|---|---|---|---|---|---|---|")
    for threshold in THRESHOLDS:
        for clock in ("wall_time", "cpu_time"):
            times = {side: first_time(report[side]["points"], threshold, clock) if side in report else None
                     for side in sides}
            report[f"{clock}_to_{threshold}"] = times
            shown = {side: "-" if side not in report else ("never" if t is None else f"{t:.1f}") for side, t in times.items()}

            def ratio(side: str) -> str:
                if times[side] and times["dqn"]:
                    return f"{times['dqn'] / times[side]:.1f}x"
                if times[side] and "dqn" in report:  # the DQN never got there: a lower bound from its last point
                    return f"> {report['dqn']['points'][-1][clock] / times[side]:.1f}x"
                return "-"

            print(f"| {threshold} | {clock.split('_')[0]} | {shown['ours']} | {shown['ours_search']} | {shown['dqn']} | "
                  f"{ratio('ours')} | {ratio('ours_search')} |")
    for side in sides:
        if side in report:
            print(f"{side}: load average {report[side]['load_before']} -> {report[side]['load_after']}, "
                  f"{report[side]['cpu_share']:.2f} of a core ({report[side]['cpu_seconds']} CPU s in "
                  f"{report[side]['process_seconds']} s); last point {report[side]['points'][-1] if report[side]['points'] else None}")
    (out / "report.json").write_text(json.dumps(report, indent=2, default=str) + "\n")
    print(f"report: {out / 'report.json'}")


if __name__ == "__main__":
    main()
