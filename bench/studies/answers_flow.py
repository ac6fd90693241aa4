"""The answer to "where did you draw?" settled by the dialogue of robot_sim.where, on held-out voices, talkers and
rooms, without the simulator: cells settled wrongly (the robot acting on a word it did not hear), robot turns per
unseen move, repeated questions and tablet touches, for one microphone and Pepper's array, confirming every cell
(the flow before the thresholds) or deciding by confidence (the shipped thresholds).

    python bench/studies/answers_flow.py [--trials 150] [--first 0] [--snr 3,10] [--room-preset atrium]
        [--arms array:confidence,...] [--thresholds F] [--json F]

Each trial is an unseen 3x3 move (25 % of trials 9x9): a random board, the person's cell, the person's voice (one
of the four flite voices at their normal rate) over babble of the held-out talkers at an SNR drawn in --snr, in a
room drawn from the preset (a new one every 10 trials). Upper bounds on the wrong-cell rate: exact (Clopper-Pearson)
one-sided 95 %. `--first` starts at a later move number (fresh held-out moves: seeds `[HELD_OUT_SEED + 50000,
number, ...]`, rooms every 10 moves). The JSON keeps every move's path: each question, what was said and heard, the
answer's meaning and confidence, and how the move was settled (accepted, confirmed, tablet), so a wrong cell is
explained.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.robot_sim.where import ask_where  # noqa: E402
from ncbot.speech import trial_sets  # noqa: E402
from ncbot.speech.acoustic_scene import camera_direction, draw_layout  # noqa: E402
from ncbot.speech.answer_policy import AnswerThresholds, phrase_confidence  # noqa: E402
from ncbot.speech.array import HOME_HEAD  # noqa: E402
from ncbot.speech.asr import Recogniser  # noqa: E402
from ncbot.speech.cell_answers import AnswerEars, answer_sentences, confirm_sentences  # noqa: E402
from ncbot.speech.ears import ArrayEars, MonoEars  # noqa: E402
from ncbot.speech.fit import babble_texts  # noqa: E402
from ncbot.speech.room import Room  # noqa: E402
from ncbot.speech.roundtrip import babble_pool  # noqa: E402
from ncbot.speech.tts import SpeechCache  # noqa: E402
from ncbot.speech.tune_answers import upper_bound_95  # noqa: E402

ARMS = (("mono", "confirm"), ("mono", "confidence"), ("array", "confirm"), ("array", "confidence"))


def step(question: str, utterance) -> dict:
    """One answer of a move's path: the robot's question, what the person said, what was heard and how sure."""
    return {"asked": question, "said": utterance.said, "heard": utterance.heard.text,
            "understood": int(utterance.understood), "sure": round(phrase_confidence(utterance.heard.confidences), 4),
            "word_sure": [round(float(c), 4) for c in utterance.heard.confidences]}


def flow_json(record: dict, moves: list[dict]) -> str:
    """The figures indented, then one move's path a line (small enough to keep beside the figures)."""
    head = json.dumps(record, indent=1)[:-2]
    return head + ',\n "moves": [\n' + ",\n".join(json.dumps(move) for move in moves) + "\n ]\n}\n"


def parse_arms(text: str) -> tuple[tuple[str, str], ...]:
    arms = tuple(tuple(arm.split(":")) for arm in text.split(","))
    if not arms or any(arm not in ARMS for arm in arms):
        print(f"ncbot: error: --arms takes EARS:POLICY pairs of {', '.join(':'.join(a) for a in ARMS)}; got {text!r}",
              file=sys.stderr)
        raise SystemExit(2)
    return arms  # type: ignore[return-value]


def main() -> None:
    from ncbot.robot_sim.conditions import PRESETS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=150)
    parser.add_argument("--snr", default="3,10", help="low,high dB at the array (or in the mix, one microphone)")
    parser.add_argument("--room-preset", default="atrium")
    parser.add_argument("--first", type=int, default=0, help="first move number (fresh held-out moves)")
    parser.add_argument("--arms", default=",".join(":".join(arm) for arm in ARMS))
    parser.add_argument("--thresholds", type=Path, help="answer thresholds file (default: the shipped one)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    arms = parse_arms(args.arms)
    low, high = (float(v) for v in args.snr.split(","))
    seed = trial_sets.HELD_OUT_SEED + 50_000
    pool, cache = babble_pool(babble_texts(), trial_sets.HELD_OUT_BABBLE_VOICES), SpeechCache()
    # each arm its own recognisers: a decoder's running normalisation follows what it heard, so one arm's answers
    # never change another's confidences, and an arm measures the same with or without the others
    recognisers = {arm: {3: Recogniser(answer_sentences(3)), 9: Recogniser(answer_sentences(9)),
                         "confirm": Recogniser(confirm_sentences())} for arm in arms}
    thresholds = AnswerThresholds.load() if args.thresholds is None else AnswerThresholds.load(args.thresholds)
    ranges = PRESETS[args.room_preset].acoustics()
    print(f"{args.trials} unseen moves per arm, babble {low:g}-{high:g} dB, {args.room_preset} rooms; thresholds accept "
          f"{thresholds.accept} confirm {thresholds.confirm} yes {thresholds.yes} asks {thresholds.asks}", flush=True)
    rows, moves, room, started = [], [], None, time.time()
    counts = {arm: {"wrong": 0, "turns": 0, "repeats": 0, "tablet": 0, "looked_again": 0, "accepted": 0,
                    "confirmations": 0} for arm in arms}
    for number in range(args.first, args.first + args.trials):
        if number % 10 == 0 or room is None:
            room = Room(draw_layout(ranges, np.random.default_rng([seed, number]), HOME_HEAD))
        rng = np.random.default_rng([seed, number, 1])
        grid = 9 if rng.random() < 0.25 else 3
        true_cell = int(rng.integers(grid * grid))
        legal = rng.random(grid * grid) > rng.uniform(0.0, 0.7)
        legal[true_cell] = True
        voice = trial_sets.HELD_OUT_VOICES[int(rng.integers(len(trial_sets.HELD_OUT_VOICES)))]
        for arm in arms:
            ears_kind, policy = arm
            ears = (MonoEars("babble", pool) if ears_kind == "mono" else
                    ArrayEars(room, "babble", pool, camera_direction=camera_direction(HOME_HEAD, room.mics, 0.0)))
            hearing = recognisers[arm]
            person = AnswerEars(grid, hearing[grid], hearing["confirm"], voice=voice, snr_db=(low, high),
                                kind="babble", babble_pool=pool, seed=[seed, number, 2], cache=cache, ears=ears)
            said: list[str] = []
            path: list[dict] = []
            settled = ask_where(true_cell, legal, person, said.append, lambda u, q: path.append(step(q, u)),
                                thresholds if policy == "confidence" else None, lambda free: true_cell)
            moves.append({"move": number, "ears": ears_kind, "policy": policy, "grid": grid, "true_cell": true_cell,
                          "voice": str(voice), "settled": settled.cell, "how": settled.how,
                          "wrong": settled.how in ("accepted", "confirmed") and settled.cell != true_cell,
                          "path": path})
            tally = counts[arm]
            tally["wrong"] += int(settled.how in ("accepted", "confirmed") and settled.cell != true_cell)
            tally["turns"] += len(said) + int(settled.cell is None)  # + "let me look again"
            tally["repeats"] += max(settled.asks - 1, 0)
            tally["tablet"] += int(settled.how == "tablet")
            tally["looked_again"] += int(settled.cell is None)
            tally["accepted"] += int(settled.how == "accepted")
            tally["confirmations"] += settled.confirmations
        done = number + 1 - args.first
        if done % 10 == 0:
            rate = done / (time.time() - started)
            print(f"  {done}/{args.trials} moves, {rate:.2f}/s, ETA {(args.trials - done) / rate:.0f} s", flush=True)
    print("| ears | settled by | moves | wrong cells (95 % upper bound) | robot turns per move | repeated questions "
          "per move | accepted as heard | confirmations | tablet touches | left to a second look |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for (ears_kind, policy), tally in counts.items():
        n = args.trials
        row = {"ears": ears_kind, "policy": policy, "moves": n, **tally,
               "wrong_upper_95": upper_bound_95(tally["wrong"], n)}
        rows.append(row)
        print(f"| {ears_kind} | {'confirming every cell' if policy == 'confirm' else 'confidence'} | {n} | "
              f"{tally['wrong']} ({row['wrong_upper_95']:.3f}) | {tally['turns'] / n:.2f} | {tally['repeats'] / n:.2f} | "
              f"{tally['accepted']} | {tally['confirmations']} | {tally['tablet']} | {tally['looked_again']} |", flush=True)
    if args.json:
        record = {"args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
                  "thresholds": {"accept": thresholds.accept, "confirm": thresholds.confirm, "yes": thresholds.yes,
                                 "asks": thresholds.asks}, "rows": rows}
        args.json.write_text(flow_json(record, moves))


if __name__ == "__main__":
    main()
