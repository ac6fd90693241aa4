"""Exact learning curves of 3x3 runs: the exact loss probability per seat of every saved snapshot.

Why: a 1000-game evaluation cannot tell a loss rate of 0.004 from 0.007 (a policy losing 0.5 % of games shows
<= 5 losses in 1000 with probability ~0.6), so sampled curves near 0.995 mostly show luck. `ncbot eval
--exhaustive` enumerates every branch of the uniform random user (8 dialogue draws) and gives the exact loss, so
two learner settings can be compared snapshot by snapshot without evaluation noise (docs/learning.md,
"Prioritised replay on 3x3").

Train with periodic snapshots kept, e.g.

    ncbot train pipelines/configs/default.yaml --out /tmp/c/per_s10 --seed 10 --no-log --no-progress \\
        train.eval_every_frames=10000000000 checkpoint.every_frames=8192 checkpoint.keep=1000 checkpoint.save_buffer=false

(stop it whenever: every snapshot is complete on disk), then

    python bench/studies/exact_curve.py /tmp/c/per_s10 /tmp/c/base_s10 --png /tmp/c/curves.png

prints, per run and snapshot, frames, the training wall seconds saved in the snapshot, and the exact loss of the
robot first and second; then per run the first snapshot with both losses <= 0.005 (task success >= 0.995) and
the first after which every later snapshot stays there.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

LOSS_LIMIT = 0.005  # task success 0.995


def run_curve(run_dir: Path, dialogue_seeds: int) -> list[tuple[int, float, float, float]]:
    """(frames, wall seconds, exact loss first, exact loss second) of every snapshot under run_dir/checkpoints."""
    from ncbot.pipelines.checkpoint import load_checkpoint
    from ncbot.pipelines.evaluate.exact import exact_checkpoint

    rows = []
    for path in sorted((run_dir / "checkpoints").glob("step-*.pt")):
        saved = load_checkpoint(path)  # one-line ValueError for a corrupt or foreign file
        first, second = exact_checkpoint(str(path), dialogue_seeds=dialogue_seeds)
        rows.append((int(saved["frames"]), float(saved["wall_time"]), first.loss, second.loss))
        print(f"{run_dir.name} {rows[-1][0]:>8d} {rows[-1][1]:7.2f} s  first {first.loss:.4f}  second {second.loss:.4f}",
              flush=True)
    return rows


def first_reaching(rows, settled: bool = False):
    """The first snapshot with both losses <= LOSS_LIMIT (settled: and every later one too), or None."""
    good = [max(first, second) <= LOSS_LIMIT for _, _, first, second in rows]
    for i, row in enumerate(rows):
        if good[i] and (not settled or all(good[i:])):
            return row
    return None


def draw(curves: dict[str, list], png: Path, styles: dict[str, dict] | None = None) -> None:
    """Loss per seat against frames, one line per run (``styles``: matplotlib keyword arguments per run name)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for name, rows in curves.items():
        frames = [row[0] / 1000 for row in rows]
        for axis, column in zip(axes, (2, 3)):
            axis.plot(frames, [max(row[column], 1e-4) for row in rows], marker=".", label=name,
                      **(styles or {}).get(name, {}))
    for axis, seat in zip(axes, ("robot first", "robot second")):
        axis.axhline(LOSS_LIMIT, color="grey", linestyle="--", linewidth=1)
        axis.set_yscale("log")
        axis.set_xlabel("training frames (K)")
        axis.set_title(f"{seat}: exact loss vs uniform random (0 drawn at 1e-4)")
    axes[0].set_ylabel("exact loss probability")
    axes[1].legend(fontsize=8)
    figure.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(png, dpi=110)
    print(f"curves: {png}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run folders with checkpoints/step-*.pt (3x3)")
    parser.add_argument("--dialogue-seeds", type=int, default=8, help="dialogue draws per snapshot (ncbot eval's default)")
    parser.add_argument("--png", type=Path, default=None, help="draw the curves here")
    args = parser.parse_args()
    for run in args.runs:
        if not list((run / "checkpoints").glob("step-*.pt")):
            print(f"error: {run} has no checkpoints/step-*.pt (train with checkpoint.keep large enough)", file=sys.stderr)
            return 2
    try:
        curves = {run.name: run_curve(run, args.dialogue_seeds) for run in args.runs}
    except ValueError as error:  # a corrupt snapshot, an Ultimate run, --dialogue-seeds 0: one line naming it
        print(f"error: {error}", file=sys.stderr)
        return 2
    print("| run | first snapshot with both seats >= 0.995 (frames, wall s) | settled from (frames, wall s) |\n|---|---|---|")
    for name, rows in curves.items():
        shown = [(f"{row[0]:,}, {row[1]:.1f}" if row else "never") for row in (first_reaching(rows), first_reaching(rows, True))]
        print(f"| {name} | {shown[0]} | {shown[1]} |")
    if args.png:
        draw(curves, args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
