"""CPU against GPU on the same recipe and seed (`train.device`): env frames/s, gradient updates/s, and the wall time
to the same periodic task success, with the ratio GPU/CPU of each.

    python bench/device_speed.py --quick            # a few minutes on a 16-core machine with one H100/H200
    python bench/device_speed.py                    # the full recipes (the 3x3 default run; a long Ultimate run)
    python bench/device_speed.py --json results.json --recipes 3x3

Recipes: `3x3` is pipelines/configs/default.yaml (256x256 network, batches of 1024); `ultimate-wide` is
pipelines/configs/ultimate.yaml with a wider network (agent.hidden=[512, 512, 512]), where the learner's products
are large enough for a GPU to matter. Each recipe trains once per device with the same config and seed (the env on
the CPU in both; on the GPU the networks, loss, optimiser and replay storage are there). Rates are per second of
the run's wall time (collection, updates and the periodic evaluations together); "to quality" is the wall time of
the first periodic evaluation whose task success reached `--threshold`, or, when a run never reaches it, the
highest success both runs reached (named in the output). The two devices draw different random streams, so
their learning curves differ a little: compare times, not the last digits of the success rates.

Without a CUDA GPU the script prints one line saying so and exits 0 (nothing to compare).
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
import time
import traceback
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # measure this tree, not an installed copy

RECIPES = {
    "3x3": (ROOT / "pipelines/configs/default.yaml", []),
    "ultimate-wide": (ROOT / "pipelines/configs/ultimate.yaml", ["agent.hidden=[512,512,512]"]),
}
# --quick: the same recipes, fewer frames and test games (about a minute per run on one H100 machine)
QUICK = {
    "3x3": ["collector.total_frames=102400", "train.eval_every_frames=20480", "eval.periodic_games=500",
            "eval.games=500", "checkpoint.every_frames=1000000"],
    "ultimate-wide": ["collector.total_frames=61440", "collector.annealing_frames=40960",
                      "train.eval_every_frames=20480", "eval.periodic_games=200", "eval.games=200",
                      "checkpoint.every_frames=1000000"],
}
FULL = {
    "3x3": [],
    "ultimate-wide": ["collector.total_frames=1001472", "train.eval_every_frames=100352",
                      "checkpoint.every_frames=10000000"],
}


def first_reaching(history: list[dict], level: float) -> float | None:
    """Wall time of the first periodic evaluation with task success >= level."""
    return next((h["wall_time"] for h in history if h["task_success"] >= level), None)


def run_one(recipe: str, device: str, quick: bool, seed: int, out: Path) -> dict:
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.run import train

    path, overrides = RECIPES[recipe]
    overrides = overrides + (QUICK if quick else FULL)[recipe] + [
        f"train.device={device}", f"train.seed={seed}", "logger.mcap=false", "logger.progress=false",
        "logger.backend=none", "checkpoint.save_buffer=false"]
    config = load_config(path, overrides)
    started = time.monotonic()
    report = train(config, out / f"{recipe}-{device.replace(':', '')}", overwrite=True)
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    wall = report["train_wall_time_s"]
    history = report["history"]
    return {"recipe": recipe, "device": device, "frames": report["frames"], "updates": report["updates"],
            "train_wall_s": wall, "total_wall_s": round(time.monotonic() - started, 2),
            "frames_per_s": report["frames"] / wall, "updates_per_s": report["updates"] / wall,
            "history": [(h["frames"], h["wall_time"], h["task_success"]) for h in history],
            "final_success": {seat: report[seat]["win"] + report[seat]["draw"] for seat in ("first", "second")},
            "best_periodic_success": max((h["task_success"] for h in history), default=0.0)}


def compare(cpu: dict, gpu: dict, threshold: float) -> dict:
    """Ratios GPU/CPU of the rates and of the wall time to the same quality."""
    level = threshold
    if first_reaching(cpu["history_full"], level) is None or first_reaching(gpu["history_full"], level) is None:
        level = min(cpu["best_periodic_success"], gpu["best_periodic_success"])
    t_cpu, t_gpu = first_reaching(cpu["history_full"], level), first_reaching(gpu["history_full"], level)
    return {"recipe": cpu["recipe"], "quality": level, "quality_is_threshold": level == threshold,
            "cpu_s_to_quality": t_cpu, "gpu_s_to_quality": t_gpu,
            "time_to_quality_gpu_over_cpu": (t_gpu / t_cpu) if t_cpu and t_gpu else None,
            "frames_per_s_gpu_over_cpu": gpu["frames_per_s"] / cpu["frames_per_s"],
            "updates_per_s_gpu_over_cpu": gpu["updates_per_s"] / cpu["updates_per_s"],
            "wall_gpu_over_cpu": gpu["train_wall_s"] / cpu["train_wall_s"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer frames and test games (a few minutes)")
    parser.add_argument("--recipes", default=",".join(RECIPES), help=f"comma-separated, of {', '.join(RECIPES)}")
    parser.add_argument("--gpu", default="cuda", help="the GPU device to compare (cuda or cuda:N)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threshold", type=float, default=0.995,
                        help="periodic task success that counts as 'the same quality' (default 0.995)")
    parser.add_argument("--json", default=None, help="also write every figure to this JSON file")
    args = parser.parse_args(argv)
    if not torch.cuda.is_available():
        print(f"device_speed: skipped: no CUDA GPU here (torch {torch.__version__} sees none); nothing to compare")
        return 0
    recipes = [name.strip() for name in args.recipes.split(",") if name.strip()]
    unknown = [name for name in recipes if name not in RECIPES]
    if unknown:
        parser.error(f"unknown recipe {unknown[0]!r}; expected {', '.join(RECIPES)}")
    threshold = args.threshold
    logging.getLogger("torchrl").setLevel(logging.WARNING)
    print(f"device_speed: {torch.cuda.get_device_name(args.gpu)} vs CPU, torch {torch.__version__}, "
          f"{'quick' if args.quick else 'full'} recipes, seed {args.seed}, quality = periodic success >= {threshold}",
          flush=True)
    results: dict = {"gpu_name": torch.cuda.get_device_name(args.gpu), "torch": torch.__version__,
                     "quick": args.quick, "seed": args.seed, "threshold": threshold, "runs": [], "ratios": []}
    with tempfile.TemporaryDirectory(prefix="device_speed-") as scratch:
        for recipe in recipes:
            pair = {}
            for device in ("cpu", args.gpu):
                try:
                    run = run_one(recipe, device, args.quick, args.seed, Path(scratch))
                except Exception as error:  # noqa: BLE001 - report it and go on with the next run
                    traceback.print_exc()
                    print(f"device_speed: {recipe} on {device} FAILED: {type(error).__name__}: {error}", flush=True)
                    results["runs"].append({"recipe": recipe, "device": device, "error": repr(error)})
                    continue
                run["history_full"] = [{"frames": f, "wall_time": w, "task_success": s} for f, w, s in run["history"]]
                pair[device] = run
                results["runs"].append({k: v for k, v in run.items() if k != "history_full"})
                print(f"  {recipe:14s} {device:7s} frames/s {run['frames_per_s']:9.0f}  updates/s "
                      f"{run['updates_per_s']:8.1f}  wall {run['train_wall_s']:7.1f} s  best periodic success "
                      f"{run['best_periodic_success']:.4f}  final first/second "
                      f"{run['final_success']['first']:.4f}/{run['final_success']['second']:.4f}", flush=True)
            if len(pair) == 2:
                ratio = compare(pair["cpu"], pair[args.gpu], threshold)
                results["ratios"].append(ratio)
                to_quality = ratio["time_to_quality_gpu_over_cpu"]
                print(f"  {recipe:14s} GPU/CPU: frames/s x{ratio['frames_per_s_gpu_over_cpu']:.2f}, updates/s "
                      f"x{ratio['updates_per_s_gpu_over_cpu']:.2f}, wall x{ratio['wall_gpu_over_cpu']:.2f}, time to "
                      f"success {ratio['quality']:.4f}{'' if ratio['quality_is_threshold'] else ' (best both reached)'}"
                      f": {ratio['cpu_s_to_quality']} s CPU, {ratio['gpu_s_to_quality']} s GPU"
                      + (f" (x{to_quality:.2f})" if to_quality else ""), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2) + "\n")
    return 1 if any("error" in run for run in results["runs"]) else 0


if __name__ == "__main__":
    sys.exit(main())
