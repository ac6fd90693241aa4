"""Whole robot games (SAPIEN) heard through one microphone with every cell confirmed (the hearing before the array)
and through Pepper's array with the dialogue deciding by confidence, under the same conditions and seeds: the
recogniser's word error rate, misrecognised moves and misheard cells, repeated questions, confirmations and tablet
touches, and the enhancement's CPU cost beside the recogniser's.

    python bench/studies/array_games.py --conditions results/array/crowded_atrium.yaml [--games 6] [--seed 31]
        [--arms mono:confirm,array:confidence] [--unseen] [--width 320] [--json F] [--out DIR]

Every game of an arm uses the same game seeds (`--seed` * 1000 + game) as the other arm, so both hear the same
person, room, talkers and noise draws. `--unseen`: the camera never confirms a move (every move asked about aloud,
as bench/studies/where_answers.py). `--out DIR`: each arm's games logged to DIR/EARS-POLICY (MCAP, snapshots,
report.json: read back with `ncbot logs`). Prints one Markdown row per arm.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

KEYS = ("games", "human_moves", "misrecognised_moves", "unseen_moves", "misheard_cells", "asr_word_error_rate",
        "asr_understood_rate", "asked_again", "repeated_questions", "dialogue_repeats", "where_repeats", "cells_accepted",
        "confirmations", "tablet_fallbacks", "answer_fallbacks", "cell_answer_word_error_rate", "unfinished",
        "beam_error_deg", "enhancement_cpu_seconds_per_utterance", "asr_cpu_seconds_per_utterance",
        "enhancement_to_asr_cpu", "cpu_seconds_per_robot_turn")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--conditions", default="atrium")
    parser.add_argument("--games", type=int, default=6)
    parser.add_argument("--seed", type=int, default=31)
    parser.add_argument("--arms", default="mono:confirm,array:confidence")
    parser.add_argument("--enhancement", default="mvdr+vad")
    parser.add_argument("--unseen", action="store_true", help="the camera never confirms a move: every move asked")
    parser.add_argument("--width", type=int, default=320, help="camera width; height is 3/4 of it")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--out", type=Path, help="log each arm's games (MCAP) under this folder")
    args = parser.parse_args()
    import torch

    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.human import HumanConfig
    from ncbot.robot_sim.play import play_robot_games

    torch.set_num_threads(1)
    unseen = {"confirm_frames": 10_000, "max_perception_frames": 1} if args.unseen else {}
    reports = {}
    print("| conditions | ears | settled by | " + " | ".join(KEYS) + " |")
    print("|---|---|---|" + "---|" * len(KEYS))
    for arm in args.arms.split(","):
        ears, answers = arm.split(":")
        config = RobotPlayConfig(game="standard", games=args.games, seed=args.seed, first="alternate",
                                 camera_width=args.width, camera_height=args.width * 3 // 4, speech="real",
                                 conditions=args.conditions, ears=ears, enhancement=args.enhancement, answers=answers,
                                 human=HumanConfig(wait_probability=0.3, nudge_probability=0.3), **unseen)
        started = time.time()
        with torch.no_grad():
            out_dir = None if args.out is None else args.out / f"{ears}-{answers}"
            report = play_robot_games(config, out_dir=out_dir, progress=None)
        reports[arm] = report
        print(f"| {args.conditions} | {ears} | {answers} | " + " | ".join(str(report.get(k)) for k in KEYS)
              + f" |  ({time.time() - started:.0f} s)", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()}, "reports": reports}, indent=1))


if __name__ == "__main__":
    main()
