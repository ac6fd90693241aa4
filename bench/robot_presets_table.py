"""The per-preset table of docs/robot.md from `ncbot robot play --out` folders (report.json + the MCAP log).

    python bench/robot_presets_table.py runs/conditions/lab-s11,runs/conditions/lab-s12 runs/conditions/office-s11,...

One argument per preset: its run folders, comma-separated (e.g. the 15 games of seed 11 and the 4 of seed 12).
Counts are summed; the ASR word error rate is word errors over words said (episode summaries), the mean
confidence is over every word heard (the `/dialogue` notes); seconds are robot-move-weighted means.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def preset_row(folders: list[Path]) -> dict:
    from logs import LogReader, read_episodes

    reports = [json.loads((folder / "report.json").read_text()) for folder in folders]
    total = {key: sum(r[key] for r in reports) for key in ("games", "wins", "draws", "losses", "human_moves",
                                                           "robot_moves", "misrecognised_moves", "unseen_moves")}
    moves = total["robot_moves"]

    def weighted(key: str) -> float | None:
        if any(r.get(key) is None for r in reports):
            return None
        return sum(r[key] * r["robot_moves"] for r in reports) / moves

    words = errors = 0
    confidences: list[float] = []
    understood = replies = 0
    for folder in folders:
        for episode in read_episodes(folder):
            words += episode["extra"].get("asr_words", 0)
            errors += episode["extra"].get("asr_word_errors", 0)
        for message in LogReader(folder).messages(["/dialogue"]):
            confidences += [c for _, c in message.data.get("heard_words", [])]
    for r in reports:
        if r.get("asr_understood_rate") is not None:
            understood += r["asr_understood_rate"] * r["asr_utterances"]
            replies += r["asr_utterances"]
    return {**total, "preset": reports[0]["conditions"],
            "asr_word_error_rate": errors / words if words else None,
            "asr_mean_confidence": sum(confidences) / len(confidences) if confidences else None,
            "asr_utterances": replies, "asr_understood_rate": understood / replies if replies else None,
            "seconds_per_robot_turn": weighted("seconds_per_robot_turn"),
            "max_seconds_per_robot_turn": max(r["max_seconds_per_robot_turn"] for r in reports),
            "cpu_seconds_per_robot_turn": weighted("cpu_seconds_per_robot_turn"),
            "render_seconds_per_robot_turn": weighted("render_seconds_per_robot_turn"),
            "tts_seconds_per_robot_turn": weighted("tts_seconds_per_robot_turn"),
            "asr_seconds_per_utterance": sum(r["asr_seconds_per_utterance"] * r["asr_utterances"] for r in reports) / replies if replies else None,
            "person_tts_seconds_per_utterance": sum(r["person_tts_seconds_per_utterance"] * r["asr_utterances"] for r in reports) / replies if replies else None,
            "load_average": [r["load_average"] for r in reports]}


def main() -> None:
    rows = [preset_row([Path(p) for p in arg.split(",")]) for arg in sys.argv[1:]]
    print(json.dumps(rows, indent=1))
    print("| preset | games (W/D/L) | human moves | misrecognised | unseen | ASR WER | mean confidence | replies "
          "(understood) | wall s per robot turn (max) | CPU s | render s | robot TTS s | person TTS + noise s / reply | ASR s / reply |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['preset']} | {r['games']} ({r['wins']}/{r['draws']}/{r['losses']}) | {r['human_moves']} | "
              f"**{r['misrecognised_moves']}** | {r['unseen_moves']} | {r['asr_word_error_rate']:.3f} | "
              f"{r['asr_mean_confidence']:.3f} | {r['asr_utterances']} ({r['asr_understood_rate']:.2f}) | "
              f"{r['seconds_per_robot_turn']:.2f} ({r['max_seconds_per_robot_turn']:.2f}) | "
              f"{r['cpu_seconds_per_robot_turn']:.2f} | {r['render_seconds_per_robot_turn']:.2f} | "
              f"{r['tts_seconds_per_robot_turn']:.3f} | {r['person_tts_seconds_per_utterance']:.3f} | "
              f"{r['asr_seconds_per_utterance']:.3f} |")


if __name__ == "__main__":
    main()
