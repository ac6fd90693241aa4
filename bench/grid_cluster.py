"""A grid on a two-node local Ray cluster: the speed-up of 2 workers over 1, and a chaos run against an undisturbed one.

    python bench/grid_cluster.py [--out results/cluster] [--runs /tmp/grid_cluster] [--rows standard]
                                 [--parts speedup chaos]

The grid is `ncbot reproduce table --budget quick`'s (pipelines/reproduce/grid.py), its game rows limited to --rows,
with periodic checkpoints every 10,000 frames (`checkpoint.every_frames=10000`, so a killed run has one to resume
from; checkpoints change no number). The cluster is `ray.cluster_utils.Cluster`: two nodes of one CPU each on this
machine, sharing the runs folder trivially. Parts:
- speedup: the grid with --workers 1, then 2 (fresh runs folders): wall time, and the ratio.
- chaos: the grid with --workers 2 again; when half its runs finished, the second node is removed (its raylet and
  workers SIGKILLed, the `ncbot train` it ran dies with them) and a fresh node joins 5 s later. Its per-seed numbers
  are compared with the undisturbed 2-worker run, and its CPU seconds with that run's.
CPU seconds: every `ncbot train` process of the runs folder is sampled each second (psutil, user + system; a killed
process counts up to its last sample). The machine's load average is printed beside every figure: on a shared machine
wall times move with the load, CPU seconds much less. Writes OUT/grid_cluster.json, OUT/grid_cluster.png.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import sys
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree, not an installed copy

CHECKPOINT_EVERY = "checkpoint.every_frames=10000"


class CpuSampler:
    """CPU seconds of the `ncbot train` processes working under a folder, sampled every second."""

    def __init__(self, folder: Path) -> None:
        self.folder, self.seen = str(folder), {}
        self.loads: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> "CpuSampler":
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        import psutil

        while not self._stop.wait(1.0):
            self.loads.append(os.getloadavg()[0])
            for process in psutil.process_iter(["pid", "cmdline", "cpu_times", "create_time"]):
                command = process.info["cmdline"] or []
                if "train" in command and any(self.folder in part for part in command):
                    times = process.info["cpu_times"]
                    if times is not None:
                        self.seen[(process.info["pid"], process.info["create_time"])] = times.user + times.system

    @property
    def cpu_s(self) -> float:
        return sum(self.seen.values())


def plan(rows: tuple[str, ...], runs_dir: Path) -> tuple[Path, int]:
    """The quick budget's grid over ``rows``, written into ``runs_dir``; (grid file, seeds)."""
    from ncbot.pipelines.reproduce.grid import BUDGETS, write_grid

    budget = dataclasses.replace(BUDGETS["quick"], rows=rows, extra_overrides=(CHECKPOINT_EVERY,))
    return write_grid(budget, runs_dir), budget.seeds


def per_seed(runs_dir: Path) -> dict[str, dict[str, float]]:
    numbers = {}
    for path in sorted(runs_dir.glob("paper/*/*/seed*/eval.json")):
        report = json.loads(path.read_text())
        numbers[str(path.parent.relative_to(runs_dir))] = {
            "first": report["first"]["task_success"], "second": report["second"]["task_success"],
            "avg_reward": report["first"]["avg_reward"], "frames": report["frames"],
            "train_cpu_s": report.get("train_cpu_time_s")}
    return numbers


def run_grid(rows: tuple[str, ...], runs_dir: Path, workers: int, chaos: bool) -> dict[str, Any]:
    """One grid on a fresh two-node cluster (module doc); its wall time, CPU seconds, summary and per-seed numbers."""
    import ray
    from ray.cluster_utils import Cluster as RayCluster

    from ncbot.pipelines.grid.plan import plan_runs
    from ncbot.pipelines.grid.runner import Cluster, run_ablation

    shutil.rmtree(runs_dir, ignore_errors=True)
    grid, seeds = plan(rows, runs_dir)
    planned = [run.run_dir for run in plan_runs(grid, seeds=seeds, runs_dir=runs_dir)]
    nodes = RayCluster()
    nodes.add_node(num_cpus=1, include_dashboard=False)
    second = nodes.add_node(num_cpus=1)
    ray.init(address=nodes.address, log_to_driver=False)
    events: list[str] = []
    try:
        with CpuSampler(runs_dir) as sampler:
            done: dict[str, Any] = {}

            def drive() -> None:  # the grid in a thread: Ray adds nodes only from the main thread (signal handlers)
                done["summary"] = run_ablation(grid, seeds=seeds, cluster=Cluster("ray", workers=workers),
                                               out=runs_dir)

            started = time.monotonic()
            driver = threading.Thread(target=drive, daemon=True)
            driver.start()
            if chaos:
                _half_way_node_loss(nodes, second, planned, events)
            driver.join()
            wall = time.monotonic() - started
            summary = done["summary"]
    finally:
        ray.shutdown()
        nodes.shutdown()
    return {"workers": workers, "chaos": chaos, "wall_s": round(wall, 1), "cpu_s": round(sampler.cpu_s, 1),
            "load_avg": round(sum(sampler.loads) / max(1, len(sampler.loads)), 2), "events": events,
            "summary": {key: summary[key] for key in ("done", "failed", "retried", "unfinished")},
            "per_seed": per_seed(runs_dir)}


def _half_way_node_loss(nodes: Any, second: Any, planned: list[Path], events: list[str]) -> None:
    """When half the grid's runs finished: remove the second node (waiting up to 180 s for a moment its run has its
    first checkpoint, so it has one to resume from and most of its training left), then add a fresh node."""
    from ncbot.pipelines.grid.attempts import read_attempts

    def finished() -> int:
        return sum((run / "eval.json").is_file() for run in planned)

    while finished() * 2 < len(planned):
        time.sleep(1.0)
    node, deadline = second.node_id[:12], time.monotonic() + 180
    while time.monotonic() < deadline:
        there = [run for run in planned if (read_attempts(run) or [{}])[-1].get("node") == node
                 and (read_attempts(run) or [{}])[-1].get("outcome") == "running"]
        if there and any(len(list((run / "checkpoints").glob("step-*.pt"))) == 1 for run in there):
            break
        time.sleep(0.5)
    events.append(f"{time.strftime('%H:%M:%S')}: removed node {node} with {finished()} of {len(planned)} runs "
                  "finished")
    nodes.remove_node(second, allow_graceful=False)
    time.sleep(5.0)
    fresh = nodes.add_node(num_cpus=1)
    events.append(f"{time.strftime('%H:%M:%S')}: node {fresh.node_id[:12]} joined")


def compare(undisturbed: dict[str, Any], chaos: dict[str, Any]) -> list[dict[str, Any]]:
    retried = {entry["run"] for entry in chaos["summary"]["retried"]}
    rows = []
    for run, numbers in undisturbed["per_seed"].items():
        other = chaos["per_seed"].get(run, {})
        rows.append({"run": run, "retried": run in retried,
                     "same": all(numbers[key] == other.get(key) for key in ("first", "second", "avg_reward", "frames")),
                     "undisturbed": numbers, "chaos": other})
    return rows


def plot(result: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grids = result["grids"]
    figure, (walls, seeds) = plt.subplots(1, 2, figsize=(11, 4))
    labels = [f"{g['workers']} worker{'s' if g['workers'] > 1 else ''}{' + node lost' if g['chaos'] else ''}"
              for g in grids]
    walls.bar(labels, [g["wall_s"] / 60 for g in grids], color=["#888", "#3a7", "#d63"][:len(grids)])
    walls.set_ylabel("wall time (min)")
    walls.set_ylim(0, 1.25 * max(g["wall_s"] for g in grids) / 60)
    walls.set_title(f"grid of {len(grids[0]['per_seed'])} runs, two-node local Ray cluster")
    for index, grid in enumerate(grids):
        walls.text(index, grid["wall_s"] / 60, f"{grid['cpu_s']:.0f} CPU s\nload {grid['load_avg']}",
                   ha="center", va="bottom", fontsize=8)
    if result.get("comparison"):
        for row in result["comparison"]:
            marker = "o" if not row["retried"] else "x"
            seeds.scatter(row["undisturbed"]["first"], row["chaos"].get("first", float("nan")), marker=marker,
                          color="#d63" if row["retried"] else "#3a7")
        seeds.plot([0, 1], [0, 1], color="#ccc", lw=1)
        seeds.set_xlabel("task success, robot first: undisturbed")
        seeds.set_ylabel("the same run in the chaos grid")
        seeds.set_title("per seed (x: a run whose try was lost)")
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/cluster")
    parser.add_argument("--runs", default="/tmp/grid_cluster")
    parser.add_argument("--rows", nargs="+", default=["standard"])
    parser.add_argument("--parts", nargs="+", default=["speedup", "chaos"], choices=["speedup", "chaos"])
    parser.add_argument("--reference", help="the JSON of an earlier speedup part: its 2-worker grid is the "
                        "undisturbed run the chaos run is compared with")
    args = parser.parse_args()
    out, runs = Path(args.out), Path(args.runs).resolve()
    out.mkdir(parents=True, exist_ok=True)
    rows = tuple(args.rows)
    result: dict[str, Any] = {"date": time.strftime("%Y-%m-%d"), "rows": rows, "command": " ".join(sys.argv),
                              "cpus": os.cpu_count(), "grids": []}
    undisturbed = None
    if args.reference:
        undisturbed = [g for g in json.loads(Path(args.reference).read_text())["grids"]
                       if g["workers"] == 2 and not g["chaos"]][0]
    if "speedup" in args.parts:
        for workers in (1, 2):
            grid = run_grid(rows, runs / f"workers{workers}", workers, chaos=False)
            result["grids"].append(grid)
            (out / "grid_cluster.json").write_text(json.dumps(result, indent=1) + "\n")  # kept as it goes
            print(f"{workers} worker(s): {grid['wall_s']:.0f} s wall, {grid['cpu_s']:.0f} CPU s, load {grid['load_avg']}",
                  flush=True)
            undisturbed = grid
        result["speedup"] = round(result["grids"][0]["wall_s"] / result["grids"][1]["wall_s"], 2)
        print(f"speed-up of 2 workers over 1: {result['speedup']}x", flush=True)
    if "chaos" in args.parts:
        chaos = run_grid(rows, runs / "chaos", 2, chaos=True)
        result["grids"].append(chaos)
        print(f"chaos: {chaos['wall_s']:.0f} s wall, {chaos['cpu_s']:.0f} CPU s, retried "
              f"{[entry['run'] for entry in chaos['summary']['retried']]}; {'; '.join(chaos['events'])}", flush=True)
        if undisturbed is not None:
            result["comparison"] = compare(undisturbed, chaos)
            result["extra_cpu_s"] = round(chaos["cpu_s"] - undisturbed["cpu_s"], 1)
            same = sum(row["same"] for row in result["comparison"])
            print(f"per-seed numbers the same in {same} of {len(result['comparison'])} runs; extra CPU "
                  f"{result['extra_cpu_s']} s", flush=True)
    (out / "grid_cluster.json").write_text(json.dumps(result, indent=1) + "\n")
    plot(result, out / "grid_cluster.png")
    print(f"wrote {out / 'grid_cluster.json'} and {out / 'grid_cluster.png'}")


if __name__ == "__main__":
    main()
