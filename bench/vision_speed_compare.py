"""Board-reading speed of two source trees on the same photos, interleaved, so a busy machine affects both alike.

    git archive 1c89ae0 vision | tar -x -C /tmp/vision_old      # the reader before issue 15
    python bench/vision_speed_compare.py --old /tmp/vision_old --new . --frames 15 --rounds 3

Writes clean and "harsh" photos (vision.data.conditions) of both grid sizes to a temporary directory, then
runs `--rounds` rounds of (old, new) subprocesses, each timing read_board on every photo (best of
`--repeats`, one thread, CPU time) and printing its median per set. Photos a reader cannot read still count
(the time until it gives up). The ratio new / old per set is what to compare across machines.
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
from vision.classifier import load_classifier
from vision.grid import read_board
folder, repeats = sys.argv[1], int(sys.argv[2])
sets = json.load(open(folder + "/sets.json"))
classifier = load_classifier(folder + "/weights.pt")
out = {}
for name, (grid, files) in sets.items():
    per = []
    for f in files:
        img = cv2.imread(f, cv2.IMREAD_COLOR)
        best = 1e9
        for _ in range(repeats + 1):  # the first call also warms caches
            t = time.process_time()
            try:
                read_board(img, grid, classifier)
            except ValueError:
                pass
            best = min(best, time.process_time() - t)
        per.append(1000 * best)
    out[name] = sorted(per)[len(per) // 2]
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="tree holding the old vision/ package")
    parser.add_argument("--new", type=Path, default=Path("."), help="tree holding the new vision/ package")
    parser.add_argument("--frames", type=int, default=15)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    sys.path.insert(0, str(args.new.resolve()))
    import cv2

    from vision.classifier import DEFAULT_WEIGHTS
    from vision.data import HARSH_TUNING_SEED, TEST_SEED
    from vision.data.frames import make_frame

    with tempfile.TemporaryDirectory() as tmp:
        sets = {}
        for conditions, base in (("clean", TEST_SEED + 70_000), ("harsh", HARSH_TUNING_SEED + 70_000)):
            for grid in (3, 9):
                files = []
                for i in range(args.frames):
                    path = f"{tmp}/{conditions}_{grid}_{i}.png"
                    cv2.imwrite(path, make_frame(grid, base + 1000 * grid + i, conditions=conditions).image)
                    files.append(path)
                sets[f"{grid}x{grid} {conditions}"] = (grid, files)
        Path(tmp, "sets.json").write_text(json.dumps(sets))
        Path(tmp, "weights.pt").write_bytes(Path(DEFAULT_WEIGHTS).read_bytes())  # same classifier for both
        times: dict[str, dict[str, list[float]]] = {"old": {}, "new": {}}
        for _ in range(args.rounds):
            for which, tree in (("old", args.old), ("new", args.new)):
                env = dict(os.environ, PYTHONPATH=str(tree.resolve()))
                done = subprocess.run([sys.executable, "-c", _TIMER, tmp, str(args.repeats)], env=env,
                                      capture_output=True, text=True, check=True)
                for name, ms in json.loads(done.stdout.strip().splitlines()[-1]).items():
                    times[which].setdefault(name, []).append(ms)
    for name in sets:
        old, new = statistics.median(times["old"][name]), statistics.median(times["new"][name])
        print(f"read_board {name}: old {old:.1f} ms, new {new:.1f} ms CPU (median photo, median of "
              f"{args.rounds} rounds), new/old {new / old:.2f}")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
