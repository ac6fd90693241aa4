"""Choose the answer thresholds (`ncbot.speech.answer_policy`) on tuning voices, talkers and rooms only:
``python -m ncbot.speech.tune_answers [--trials 400] [--out speech/data/answer_thresholds.json]``.

How: each tuning trial is an unseen move: a random board, the person's cell, and the person saying its phrase
three times (fresh noise each time) through Pepper's array (the default enhancement) in a tuning room, over babble
at 0-10 dB at the array (`TUNING_SNR_DB`: the deployment the dialogue must hold in, 3-10 dB babble in reverberant
rooms, with 3 dB to spare below; thresholds safe there are safe in quieter rooms, where answers are surer), with
their confirmation ("yes, that is right" when the cell heard is theirs, "no, that is wrong" otherwise) after
each. Every setting of (accept, confirm, yes, asks) is then replayed on the recorded answers, each trial in the
three orders of its answers (`rotations`: every answer is once the first one heard, so a one-question setting is
judged on every answer, not a third of them).

The selection rule: kept are settings that settle no replayed trial in a wrong cell, and still none with all three
thresholds `MARGIN` lower (room for voices, talkers and rooms the tuning did not hear), and whose yes threshold,
`MARGIN` lower, is above every recorded "no" heard as a yes (`false_yeses`: each confirmation is evidence about
the confirmation's decoder, also one after an answer the flow would not confirm). Chosen among them: the least
cost per move, a spoken question or confirmation counting one and the tablet `TABLET_COST` (the robot's request and
the person stepping up to touch its chest: with the tablet at one, a touch that never fails would always beat
asking aloud, and the robot would never talk a cell through). The file records the exact one-sided 95 % upper
bound of the wrong-cell rate that 0 wrong of the tuning trials allows (`wrong_upper_95`). `--trials-file` keeps
the recorded answers (JSON) and replays them when it exists. The tuning set (``ncbot.speech.trial_sets``) shares no
voice, talker, room or seed with anything the figures are measured on.
"""
from __future__ import annotations

import argparse
import itertools
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ncbot.speech.answer_policy import DEFAULT_THRESHOLDS, AnswerThresholds, phrase_confidence

ANSWERS_PER_TRIAL = 3
MARGIN = 0.05
TABLET_COST = 2.0
GRID = np.round(np.arange(0.0, 1.0001, 0.05), 2).tolist() + [1.01]  # 1.01: never
#: The deployment the dialogue must hold in (babble at 3-10 dB at the array in reverberant rooms), 3 dB to spare below.
TUNING_SNR_DB = (0.0, 10.0)
TUNING_NOISE = "babble"
ULTIMATE_SHARE = 0.25  # of the trials, on the 9x9 board


@dataclass(frozen=True)
class Answer:
    """One spoken answer: the cell heard (-1 none, or a taken cell: not free), its confidence, and the
    confirmation's yes (True/False/None) and confidence."""

    cell: int
    free: bool
    sure: float
    yes: bool | None
    yes_sure: float


@dataclass(frozen=True)
class Trial:
    true_cell: int
    answers: tuple[Answer, ...]


class Replays:
    """The trials as arrays (trial, answer) for replaying many settings quickly."""

    def __init__(self, trials: Sequence[Trial]) -> None:
        self.true_cell = np.array([t.true_cell for t in trials])
        answers = [t.answers for t in trials]
        self.cell = np.array([[a.cell for a in row] for row in answers])
        self.usable = np.array([[a.cell >= 0 and a.free for a in row] for row in answers])
        self.sure = np.array([[a.sure for a in row] for row in answers])
        self.yes = np.array([[a.yes is True for a in row] for row in answers])
        self.yes_sure = np.array([[a.yes_sure for a in row] for row in answers])
        # every recorded "no" (the cell heard was not theirs, or nothing was heard) heard as a yes: the confirmation's
        # decoder errs the same whichever cell was asked about, so each one is evidence for the yes threshold
        said_no = self.cell != self.true_cell[:, None]
        self.no_heard_yes_sure = np.sort(self.yes_sure[said_no & self.yes])

    def replay(self, t: AnswerThresholds) -> tuple[np.ndarray, np.ndarray]:
        """Per trial, the cell `robot_sim.where.ask_where`'s confidence flow settles from the answers (-1: the
        tablet) and the robot turns it takes (questions, confirmations, the tablet request)."""
        settled = np.full(self.true_cell.shape, -1)
        turns = np.zeros(self.true_cell.shape, dtype=np.int64)
        open_ = np.ones(self.true_cell.shape, dtype=bool)
        for k in range(min(t.asks, self.cell.shape[1])):
            turns += open_
            heard = open_ & self.usable[:, k] & (self.sure[:, k] >= t.confirm)
            accepted = heard & (self.sure[:, k] >= t.accept)
            confirmed = heard & ~accepted & self.yes[:, k] & (self.yes_sure[:, k] >= t.yes)
            turns += heard & ~accepted
            done = accepted | confirmed
            settled[done] = self.cell[done, k]
            open_ &= ~done
        turns += open_  # the tablet request
        return settled, turns


def rotations(trials: Sequence[Trial]) -> list[Trial]:
    """Each trial in the cyclic orders of its answers: every recorded answer is once the first one heard."""
    return [Trial(t.true_cell, t.answers[k:] + t.answers[:k]) for t in trials for k in range(len(t.answers))]


def upper_bound_95(failures: int, trials: int) -> float:
    """Exact (Clopper-Pearson) one-sided 95 % upper bound of a rate with `failures` in `trials`."""
    from scipy.stats import beta

    return 1.0 if failures >= trials else float(beta.ppf(0.95, failures + 1, trials - failures))


def false_yeses(replays: Replays, t: AnswerThresholds) -> int:
    """Recorded "no"s heard as a yes at least `t.yes` sure (on any answer, also one the flow never confirms)."""
    return int(np.sum(replays.no_heard_yes_sure >= t.yes))


def evaluate(replays: Replays, t: AnswerThresholds) -> tuple[int, float, float]:
    """(wrong cells settled, robot turns per move, share settled by the tablet)."""
    settled, turns = replays.replay(t)
    wrong = int(np.sum((settled >= 0) & (settled != replays.true_cell)))
    return wrong, float(turns.mean()), float(np.mean(settled < 0))


def cost(turns: float, tablet: float) -> float:
    """Cost per move: every robot turn one, the tablet request `TABLET_COST` in all."""
    return turns + (TABLET_COST - 1.0) * tablet


def choose(trials: Sequence[Trial]) -> tuple[AnswerThresholds, dict]:
    """The safe setting (no wrong cell in any rotation of the trials and no recorded "no" heard as a sure yes, even
    with the thresholds `MARGIN` lower) with the least cost per move."""
    replays, best = Replays(rotations(trials)), None
    recorded = {"wrong_upper_95": upper_bound_95(0, len(trials)),
                "no_heard_as_yes": Replays(trials).no_heard_yes_sure.round(4).tolist()}
    for accept, confirm, yes, asks in itertools.product(GRID, GRID, GRID, (1, 2, 3)):
        if confirm > accept:
            continue
        setting = AnswerThresholds(accept, confirm, yes, asks)
        lower = AnswerThresholds(max(accept - MARGIN, 0.0), max(confirm - MARGIN, 0.0), max(yes - MARGIN, 0.0), asks)
        wrong, turns, tablet = evaluate(replays, setting)
        if wrong or evaluate(replays, lower)[0] or false_yeses(replays, lower):
            continue
        key = (round(cost(turns, tablet), 6), tablet, -accept, -yes)
        if best is None or key < best[0]:
            best = (key, setting, {"turns_per_move": turns, "tablet_share": tablet, "cost_per_move": key[0],
                                   **recorded})
    if best is None:
        raise ValueError("no threshold setting settles every tuning trial safely")
    return best[1], best[2]


def record_trials(count: int, seed: int) -> list[Trial]:
    """`count` tuning trials heard through Pepper's array (mvdr+vad) in tuning rooms (a new room every 10)."""
    from ncbot.speech import trial_sets
    from ncbot.speech.acoustic_scene import camera_direction, draw_layout
    from ncbot.speech.array import HOME_HEAD
    from ncbot.speech.asr import Recogniser
    from ncbot.speech.cell_answers import (CONFIRM_NO, CONFIRM_YES, AnswerEars, answer_sentences, cell_phrase,
                                           confirm_sentences)
    from ncbot.speech.ears import ArrayEars
    from ncbot.speech.fit import babble_texts
    from ncbot.speech.room import Room
    from ncbot.speech.roundtrip import babble_pool
    from ncbot.speech.tts import SpeechCache

    pool, cache = babble_pool(babble_texts(), trial_sets.TUNING_BABBLE_VOICES), SpeechCache()
    recognisers = {3: Recogniser(answer_sentences(3)), 9: Recogniser(answer_sentences(9)),
                   "confirm": Recogniser(confirm_sentences())}
    rng, trials, started, room = np.random.default_rng(seed), [], time.time(), None
    for number in range(count):
        if number % 10 == 0:
            room = Room(draw_layout(trial_sets.TUNING_ROOMS, np.random.default_rng([seed, number]), HOME_HEAD))
        grid, kind = 9 if rng.random() < ULTIMATE_SHARE else 3, TUNING_NOISE
        ears = ArrayEars(room, kind, pool, camera_direction=camera_direction(HOME_HEAD, room.mics, 0.0))
        voice = trial_sets.TUNING_VOICES[int(rng.integers(len(trial_sets.TUNING_VOICES)))]
        person = AnswerEars(grid, recognisers[grid], recognisers["confirm"], voice=voice, snr_db=TUNING_SNR_DB,
                            kind=kind, babble_pool=pool, seed=[seed, number, 1], cache=cache, ears=ears)
        true_cell = int(rng.integers(grid * grid))
        free = rng.random(grid * grid) > rng.uniform(0.0, 0.7)
        free[true_cell] = True
        answers = []
        for _ in range(ANSWERS_PER_TRIAL):
            heard = person.hear_cell(cell_phrase(true_cell, grid))
            reply = person.hear_confirm(CONFIRM_YES if heard.understood == true_cell else CONFIRM_NO)
            yes = {1: True, 0: False}.get(reply.understood)
            answers.append(Answer(heard.understood, bool(heard.understood >= 0 and free[heard.understood]),
                                  phrase_confidence(heard.heard.confidences), yes,
                                  phrase_confidence(reply.heard.confidences)))
        trials.append(Trial(true_cell, tuple(answers)))
        if (number + 1) % 25 == 0:
            rate = (number + 1) / (time.time() - started)
            print(f"  {number + 1}/{count} trials, {rate:.2f}/s, ETA {(count - number - 1) / rate:.0f} s", flush=True)
    return trials


def save_trials(trials: Sequence[Trial], path: Path) -> None:
    import json
    from dataclasses import asdict

    from ncbot.fileio.atomic import atomic_write_text

    atomic_write_text(json.dumps([asdict(t) for t in trials]), path)


def load_trials(path: Path) -> list[Trial]:
    import json

    return [Trial(t["true_cell"], tuple(Answer(**a) for a in t["answers"])) for t in json.loads(path.read_text())]


def main(argv: list[str] | None = None) -> None:
    from ncbot.speech import trial_sets

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=400)
    parser.add_argument("--out", type=Path, default=DEFAULT_THRESHOLDS)
    parser.add_argument("--trials-file", type=Path, help="recorded answers: replayed if the file exists, else written")
    args = parser.parse_args(argv)
    if args.trials_file is not None and args.trials_file.is_file():
        trials = load_trials(args.trials_file)
    else:
        trials = record_trials(args.trials, trial_sets.TUNING_SEED)
        if args.trials_file is not None:
            save_trials(trials, args.trials_file)
    chosen, figures = choose(trials)
    confirm_all = evaluate(Replays(rotations(trials)), AnswerThresholds(1.01, 0.0, 0.0, 3))
    meta = {"command": f"python -m ncbot.speech.tune_answers --trials {args.trials}", "trials": len(trials),
            "date": time.strftime("%Y-%m-%d"),
            "tablet_cost": TABLET_COST,
            "set": "tuning: flite voices at rate 0.85/1.15, espeak-ng talkers en-us+m3 en-gb+f2 en+m1, "
                   f"rooms of trial_sets.TUNING_ROOMS, seeds from {trial_sets.TUNING_SEED}",
            "snr_db": list(TUNING_SNR_DB), "noise": TUNING_NOISE, "ears": "array mvdr+vad",
            "rule": "no wrong cell in any rotation of the trials, none with every threshold margin lower, yes "
                    "(margin lower) above every recorded no heard as a yes; least cost per move", "margin": MARGIN,
            **figures,
            "confirm_every_cell": {"wrong": confirm_all[0], "turns_per_move": confirm_all[1],
                                   "left_unsettled": confirm_all[2]}}
    chosen = AnswerThresholds(chosen.accept, chosen.confirm, chosen.yes, chosen.asks, meta)
    chosen.save(args.out)
    print(f"chose accept {chosen.accept}, confirm {chosen.confirm}, yes {chosen.yes}, asks {chosen.asks}: "
          f"{figures['turns_per_move']:.2f} robot turns per move, tablet {figures['tablet_share']:.2f} "
          f"(confirming every cell, 3 asks: {confirm_all[1]:.2f} turns, {confirm_all[0]} wrong); wrong-cell rate "
          f"<= {figures['wrong_upper_95']:.4f} (95 %, {len(trials)} trials); wrote {args.out}")


if __name__ == "__main__":
    main()
