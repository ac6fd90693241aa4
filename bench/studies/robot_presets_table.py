"""The per-preset table of docs/robot.md from `ncbot robot play --out` folders (report.json + the MCAP log).

    python bench/studies/robot_presets_table.py runs/conditions/lab-s11,runs/conditions/lab-s12 runs/conditions/office-s11,...

One argument per preset: its run folders, comma-separated (e.g. the 15 games of seed 11 and the 4 of seed 12).
Counts are summed; the ASR word error rate is word errors over words said (episode summaries), the mean
confidence is over every word heard (the `/dialogue` notes); seconds are robot-move-weighted means.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def preset_row(folders: list[Path]) -> dict:
    """Counts from the finished games' `/episode` summaries (so a run cut short still counts the games it
    finished); the time split from report.json where the run finished (None otherwise)."""
    from ncbot.logs import LogReader, read_episodes

    episodes = [e for folder in folders for e in read_episodes(folder) if e.get("phase") == "robot"]
    extras = [e["extra"] for e in episodes]
    outcomes = [x["true_outcome"] for x in extras]
    robot_seconds = [s for x in extras for s in x["robot_move_seconds"]]
    confidences: list[float] = []
    replies = understood = 0
    for folder in folders:
        for message in LogReader(folder).messages(["/dialogue"]):
            turn = message.data
            if "heard_words" in turn:
                confidences += [c for _, c in turn["heard_words"]]
    reports = [json.loads((f / "report.json").read_text()) for f in folders if (f / "report.json").is_file()]
    finished = len(reports) == len(folders)
    for r in reports:
        replies += r["asr_utterances"] or 0
        understood += (r["asr_understood_rate"] or 0) * (r["asr_utterances"] or 0)

    def weighted(key: str, weight: str = "robot_moves") -> float | None:
        if not finished or any(r.get(key) is None for r in reports):
            return None
        return sum(r[key] * r[weight] for r in reports) / max(sum(r[weight] for r in reports), 1)

    words = sum(x.get("asr_words", 0) for x in extras)
    return {"preset": (extras[0]["conditions"]["preset"] if extras else "?"), "games": len(extras),
            "wins": outcomes.count("win"), "draws": outcomes.count("draw"), "losses": outcomes.count("loss"),
            "unfinished": outcomes.count("unfinished"),
            "human_moves": sum(len(x["human_turn_seconds"]) for x in extras),
            "robot_moves": len(robot_seconds),
            "misrecognised_moves": sum(x["misrecognised_moves"] for x in extras),
            "unseen_moves": sum(x["unseen_moves"] for x in extras),
            "asr_word_error_rate": sum(x.get("asr_word_errors", 0) for x in extras) / words if words else None,
            "asr_mean_confidence": sum(confidences) / len(confidences) if confidences else None,
            "asr_replies": sum(x.get("utterances", {}).get("user", 0) for x in extras),
            "asr_understood_rate": understood / replies if finished and replies else None,
            "seconds_per_robot_turn": sum(robot_seconds) / len(robot_seconds) if robot_seconds else None,
            "max_seconds_per_robot_turn": max(robot_seconds, default=None),
            "cpu_seconds_per_robot_turn": weighted("cpu_seconds_per_robot_turn"),
            "render_seconds_per_robot_turn": weighted("render_seconds_per_robot_turn"),
            "tts_seconds_per_robot_turn": weighted("tts_seconds_per_robot_turn"),
            "person_tts_seconds_per_utterance": weighted("person_tts_seconds_per_utterance", "asr_utterances"),
            "asr_seconds_per_utterance": weighted("asr_seconds_per_utterance", "asr_utterances"),
            "finished_runs": f"{len(reports)}/{len(folders)}", "load_average": [r["load_average"] for r in reports]}


def _f(value, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def main() -> None:
    rows = [preset_row([Path(p) for p in arg.split(",")]) for arg in sys.argv[1:]]
    print(json.dumps(rows, indent=1))
    print("| preset | games (W/D/L) | human moves | misrecognised | unseen | ASR WER | mean confidence | replies "
          "(understood) | wall s per robot turn (max) | CPU s | render s | robot TTS s | person TTS + noise s / reply | ASR s / reply |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['preset']} | {r['games']} ({r['wins']}/{r['draws']}/{r['losses']}) | {r['human_moves']} | "
              f"**{r['misrecognised_moves']}** | {r['unseen_moves']} | {_f(r['asr_word_error_rate'], 3)} | "
              f"{_f(r['asr_mean_confidence'], 3)} | {r['asr_replies']} ({_f(r['asr_understood_rate'])}) | "
              f"{_f(r['seconds_per_robot_turn'])} ({_f(r['max_seconds_per_robot_turn'])}) | "
              f"{_f(r['cpu_seconds_per_robot_turn'])} | {_f(r['render_seconds_per_robot_turn'])} | "
              f"{_f(r['tts_seconds_per_robot_turn'], 3)} | {_f(r['person_tts_seconds_per_utterance'], 3)} | "
              f"{_f(r['asr_seconds_per_utterance'], 3)} |")


if __name__ == "__main__":
    main()
