"""Can sessions render at once? Separate SAPIEN scenes rendered from one thread each vs one after another.

Why: `ncbot robot serve` gives every session its own scene and render world on the one warm lavapipe device;
dropping the process-wide simulator lock is only right if rendering those from several threads gives the same
pixels (checked frame by frame against the serial render of the same still scene) and is worth it (speed-up).

    python bench/render_threads.py --scenes 4 --frames 15
"""
from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this tree's packages, not an installed copy


def build_scenes(count: int, width: int = 320, height: int = 240) -> list:
    """`count` scenes, each with its own mark (cell i) so a frame from another scene would show."""
    from ncbot.robot_sim.scene import PepperScene, SceneConfig
    from ncbot.robot_sim.sheet import MARK_OF_PLAYER, MarkSpec

    scenes = []
    for i in range(count):
        scene = PepperScene(SceneConfig(game="standard", camera_width=width, camera_height=height, conditions_seed=i))
        scene.canvas.draw(MarkSpec(i % 9, MARK_OF_PLAYER["x"], i, scene.conditions.ink_bgr), 1.0)
        scenes.append(scene)
    return scenes


def frame_pair(scene) -> tuple[np.ndarray, np.ndarray]:
    return scene.render(), scene.render_overview(480, 360)


def run(scenes: list, frames: int, threaded: bool, reference: list | None = None) -> dict[str, Any]:
    """Render `frames` frame pairs per scene; wall seconds and frames differing from `reference`."""
    mismatched: list[int] = []

    def work(index: int) -> None:
        for _ in range(frames):
            mouth, overview = frame_pair(scenes[index])
            if reference is not None and not (np.array_equal(mouth, reference[index][0])
                                               and np.array_equal(overview, reference[index][1])):
                mismatched.append(index)

    started = time.perf_counter()
    if threaded:
        threads = [threading.Thread(target=work, args=(i,)) for i in range(len(scenes))]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    else:
        for i in range(len(scenes)):
            work(i)
    return {"seconds": round(time.perf_counter() - started, 3), "mismatched": len(mismatched)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=4)
    parser.add_argument("--frames", type=int, default=15, help="frame pairs (mouth + overview) per scene and run")
    args = parser.parse_args()
    scenes = build_scenes(args.scenes)
    reference = [tuple(f.copy() for f in frame_pair(s)) for s in scenes]  # still scenes: every frame must match
    rows = []
    for count in sorted({1, min(2, args.scenes), args.scenes}):
        serial = run(scenes[:count], args.frames, threaded=False, reference=reference)
        threaded = run(scenes[:count], args.frames, threaded=True, reference=reference)
        rows.append({"scenes": count, "frame_pairs": count * args.frames, "serial_s": serial["seconds"],
                     "threads_s": threaded["seconds"], "speedup": round(serial["seconds"] / threaded["seconds"], 2),
                     "mismatched": serial["mismatched"] + threaded["mismatched"]})
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
