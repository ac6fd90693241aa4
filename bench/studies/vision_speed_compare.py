"""Board reading of two source trees on the same photos: speed (interleaved runs, so a busy machine affects
both alike) and what each reads.

    git archive 1c89ae0 vision | tar -x -C /tmp/vision_old      # an older reader
    python bench/studies/vision_speed_compare.py --old /tmp/vision_old --frames 15 --rounds 3           # speed
    python bench/studies/vision_speed_compare.py --old /tmp/vision_old --split heldout --frames 100 \
        --repeats 0 --rounds 1                                                                  # accuracy
    python bench/studies/vision_speed_compare.py --old /tmp/vision_old --own-weights                    # new weights too

The photos are made by the new tree's generator and saved as PNG (lossless), so the old reader, which has
no "harsh" conditions, reads exactly the same pixels. Split "tuning": clean photos (TEST_SEED + 70,000) and
harsh tuning photos, pen marks. Split "heldout": the harsh held-out sets of `ncbot vision eval --what harsh`
(same seeds and styles). Each round runs the old then the new tree in a subprocess, timing read_board on
every photo (best of `--repeats` + 1, one thread, CPU time); photos a reader cannot read still count (the
time until it gives up) and count as all cells wrong. The ratio new / old per set is what to compare.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

_TIMER = r"""
import json, sys, time
import cv2, torch
torch.set_num_threads(1); cv2.setNumThreads(1)
from ncbot.vision.classifier import load_classifier
from ncbot.vision.grid import read_board
folder, repeats, weights = sys.argv[1], int(sys.argv[2]), sys.argv[3]
sets = json.load(open(folder + "/sets.json"))
classifier = load_classifier(weights)
out = {}
for name, (grid, files, boards) in sets.items():
    per, right, whole, failed = [], 0, 0, 0
    for f, board in zip(files, boards):
        img = cv2.imread(f, cv2.IMREAD_COLOR)
        best = 1e9
        for _ in range(repeats + 1):  # the first call also warms caches
            t = time.process_time()
            try:
                cells = read_board(img, grid, classifier)
            except ValueError:
                cells = None
            best = min(best, time.process_time() - t)
        per.append(1000 * best)
        hits = 0 if cells is None else sum(a == b for a, b in zip(cells, board))
        right, whole, failed = right + hits, whole + (hits == grid * grid), failed + (cells is None)
    out[name] = [sorted(per)[len(per) // 2], right / (len(files) * grid * grid), whole / len(files), failed]
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="tree holding the old vision/ package")
    parser.add_argument("--new", type=Path, default=Path("."), help="tree holding the new vision/ package")
    parser.add_argument("--frames", type=int, default=15)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--split", choices=("tuning", "heldout"), default="tuning")
    parser.add_argument("--own-weights", action="store_true",
                        help="each tree reads with its own vision/weights/cell_cnn.pt (default: both the new tree's)")
    args = parser.parse_args()
    args.old, args.new = args.old.resolve(), args.new.resolve()  # each reader runs from its own tree
    sys.path.insert(0, str(args.new.resolve()))
    import cv2

    from ncbot.vision.classifier import DEFAULT_WEIGHTS
    from ncbot.vision.data import HARSH_HELDOUT_SEED, HARSH_TUNING_SEED, TEST_SEED
    from ncbot.vision.data.frames import make_frame

    if args.split == "tuning":
        specs = [(f"{grid}x{grid} {conditions}", grid, seed + 1000 * grid, ("pen",), conditions)
                 for conditions, seed in (("clean", TEST_SEED + 70_000), ("harsh", HARSH_TUNING_SEED + 70_000))
                 for grid in (3, 9)]
    else:  # the sets of vision.experiments.harsh_reading(split="heldout")
        specs = [(f"{grid}x{grid} harsh held-out {'+'.join(styles)}", grid,
                  HARSH_HELDOUT_SEED + 100_000 * grid + offset, styles, "harsh")
                 for grid in (3, 9) for offset, styles in ((0, ("sketch", "hershey")), (50_000, ("pen",)))]
    with tempfile.TemporaryDirectory() as tmp:
        sets = {}
        for name, grid, seed, styles, conditions in specs:
            files, boards = [], []
            for i in range(args.frames):
                frame = make_frame(grid, seed + i, styles=styles, conditions=conditions)
                files.append(f"{tmp}/{len(sets)}_{i}.png")
                cv2.imwrite(files[-1], frame.image)
                boards.append(frame.board)
            sets[name] = (grid, files, boards)
        Path(tmp, "sets.json").write_text(json.dumps(sets))
        Path(tmp, "weights.pt").write_bytes(Path(DEFAULT_WEIGHTS).read_bytes())  # same classifier for both
        times: dict[str, dict[str, list[float]]] = {"old": {}, "new": {}}
        reads: dict[str, dict[str, list]] = {"old": {}, "new": {}}
        for _ in range(args.rounds):
            for which, tree in (("old", args.old), ("new", args.new)):
                env = dict(os.environ, PYTHONPATH=str(tree.resolve()))
                weights = tree / "vision/weights/cell_cnn.pt" if args.own_weights else Path(tmp, "weights.pt")
                done = subprocess.run([sys.executable, "-c", _TIMER, tmp, str(args.repeats), str(weights)], env=env, cwd=tree,
                                      capture_output=True, text=True, check=True)
                for name, (ms, *read) in json.loads(done.stdout.strip().splitlines()[-1]).items():
                    times[which].setdefault(name, []).append(ms)
                    reads[which][name] = read
    for name in sets:
        old, new = statistics.median(times["old"][name]), statistics.median(times["new"][name])
        (oc, ob, of), (nc, nb, nf) = reads["old"][name], reads["new"][name]
        print(f"{name} ({args.frames} photos): cells right old {100 * oc:.2f}% new {100 * nc:.2f}%; boards right "
              f"old {100 * ob:.1f}% new {100 * nb:.1f}%; unread old {of} new {nf}; read_board CPU median old "
              f"{old:.1f} ms new {new:.1f} ms (median of {args.rounds} rounds), new/old {new / old:.2f}")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
