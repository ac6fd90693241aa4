"""The spoken answer to "where did you draw?" in whole robot games, per preset: a camera that never confirms a
move (`confirm_frames` beyond reach, one still frame), so every human move is asked about aloud and heard over
the preset's noise. Prints, per preset, the moves asked about, settled by an answer, misheard, and left to the
second look, the answers' word error rate and the CPU seconds per answer's decode.

    python bench/studies/where_answers.py [--games 6] [--seed 21] [--presets lab,office,atrium,random] [--width 160]

Small frames (default 160x120; the random preset needs 320x240 for the robot to find some sheets at all): only
the speech matters here, the camera's verdict is forced to "unseen".
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", type=int, default=6)
    parser.add_argument("--seed", type=int, default=21)
    parser.add_argument("--presets", default="lab,office,atrium,random")
    parser.add_argument("--width", type=int, default=160, help="camera width; height is 3/4 of it")
    args = parser.parse_args()
    import torch

    from ncbot.robot_sim.game_config import RobotPlayConfig
    from ncbot.robot_sim.play import play_robot_games

    torch.set_num_threads(1)
    print("| preset | games | moves asked about | settled by an answer | misheard cells | looked again | answers spoken | "
          "answer WER | unfinished |")
    print("|---|---|---|---|---|---|---|---|---|")
    for preset in args.presets.split(","):
        config = RobotPlayConfig(game="standard", games=args.games, seed=args.seed, first="alternate",
                                 camera_width=args.width, camera_height=args.width * 3 // 4, speech="real", conditions=preset,
                                 confirm_frames=10_000, max_perception_frames=1)
        with torch.no_grad():
            r = play_robot_games(config, progress=None)
        print(f"| {preset} | {r['games']} | {r['unseen_moves']} | {r['cells_from_answers']} | {r['misheard_cells']} | "
              f"{r['answer_fallbacks']} | {r['cell_answers']} | {r['cell_answer_word_error_rate']} | {r['unfinished']} |",
              flush=True)


if __name__ == "__main__":
    main()
