"""Wall time of the simulated robot: render, sheet texture update, IK, vision, and whole robot turns.

Target: <= 2 s wall per robot turn (policy + speech + drive + draw + return home, with the camera
frames rendered and logged, and the robot's own look at its mark) on this 2-core CPU machine with lavapipe.

    python bench/studies/robot_turn.py [--games 3] [--game standard] [--width 640 --height 480] [--conditions atrium]

Figures are noisy when other jobs share the machine: the load average is printed with them.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from ncbot.pipelines.progress import progress_bar  # noqa: E402


def median_ms(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return 1000.0 * float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", type=int, default=3)
    parser.add_argument("--game", default="standard", choices=["standard", "ultimate"])
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--conditions", default="lab", help="lab, office, atrium, random or a YAML file (robot_sim.conditions)")
    args = parser.parse_args()

    import cv2
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    from ncbot.logs import EpisodeLogger
    from ncbot.robot_sim.ik import PositionIK
    from ncbot.robot_sim.pepper_model import ARM_JOINTS
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy
    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.play import RobotGameRunner
    from ncbot.robot_sim.scene import PepperScene, SceneConfig
    from ncbot.robot_sim.sheet import HUMAN_INK, MarkSpec
    from ncbot.vision.grid import read_page

    from ncbot.robot_sim.conditions import load_conditions

    ranges = load_conditions(args.conditions)
    figures: dict[str, float | int | str | None] = {"load_average_start": round(os.getloadavg()[0], 2),
                                                    "conditions": args.conditions}
    started = time.perf_counter()
    scene = PepperScene(SceneConfig(game=args.game, camera_width=args.width, camera_height=args.height,
                                    conditions=ranges, conditions_seed=args.seed))
    scene.render()
    figures["first_frame_s"] = round(time.perf_counter() - started, 2)

    def render_once() -> None:
        scene.step(0.02)
        scene.render()

    figures[f"render_{args.width}x{args.height}_ms"] = round(median_ms(render_once, 30), 1)
    small = PepperScene(SceneConfig(game=args.game, camera_width=320, camera_height=240, conditions=ranges,
                                    conditions_seed=args.seed))
    small.render()
    figures["render_320x240_ms"] = round(median_ms(lambda: (small.step(0.02), small.render()), 30), 1)

    mark = MarkSpec(4, "nought", 1, HUMAN_INK)
    progress = iter(np.linspace(0.02, 0.98, 1000))
    figures["texture_update_ms"] = round(median_ms(lambda: (scene.canvas.draw(mark, next(progress)), scene.refresh_sheet()), 40), 2)

    ik = PositionIK(scene, "r_tool", ARM_JOINTS["R"])
    rng = np.random.default_rng(0)
    targets = iter([scene.cell_world(int(c)) - np.array([0.02, 0, 0]) for c in rng.integers(0, scene.grid ** 2, 200)])
    base_q = scene.home.copy()

    def solve() -> None:
        target = next(targets)
        q = base_q.copy()
        q[scene.joint_index["base_x"]] = target[0] - 0.28
        q[scene.joint_index["base_y"]] = target[1] + 0.14
        ik.solve(target, q)

    figures["ik_solve_ms"] = round(median_ms(solve, 100), 2)
    frame_bgr = np.ascontiguousarray(scene.render()[:, :, ::-1])
    figures["vision_read_page_ms"] = round(median_ms(lambda: read_page(frame_bgr, scene.grid), 20), 1)

    config = RobotPlayConfig(game=args.game, games=args.games, seed=args.seed, camera_width=args.width,
                             camera_height=args.height, conditions=args.conditions)
    with tempfile.TemporaryDirectory() as tmp, EpisodeLogger(tmp, run_info={"bench": "robot_turn"}) as logger:
        runner = RobotGameRunner(config, LookaheadOnlyPolicy(seed=args.seed), out_dir=None, logger=logger)
        report = runner.run(progress=progress_bar)
    for key in ("games", "wins", "draws", "losses", "misrecognised_moves", "unseen_moves", "robot_moves", "seconds_per_robot_turn",
                "max_seconds_per_robot_turn", "cpu_seconds_per_robot_turn", "seconds_per_dialogue_act", "seconds_per_human_turn", "frames"):
        figures[key] = report[key]
    figures["load_average_end"] = round(os.getloadavg()[0], 2)
    target_met = report["seconds_per_robot_turn"] is not None and report["seconds_per_robot_turn"] <= 2.0
    width = max(len(k) for k in figures)
    for key, value in figures.items():
        print(f"{key:<{width}}  {value}")
    print(f"target <= 2 s per robot turn: {'met' if target_met else 'NOT met'} (2 cores, shared: see load average)")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
