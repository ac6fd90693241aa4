"""Fit the ASR channel model from real round trips: ``python -m ncbot.speech.fit [--out PATH] [--seeds N]``
(``--show`` prints the per-level figures of an existing model instead).

The voices, noise seeds and babble talkers used here are kept apart from those bench/studies/speech_asr.py reports on
(``REPORT_*`` below): the fit hears the person's flite voices slowed and sped up (rate 0.85 / 1.15) with seeds
from ``FIT_SEED``; the report hears them at their normal rate (1.0, the voices ``ncbot robot play`` uses) with
seeds from ``REPORT_SEED``, in babble of other talkers. The texts are the same closed set of 25 user sentences:
the channel must know every word the simulated user can say.
"""
from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

from ncbot.speech.asr import Recogniser, dialogue_sentences
from ncbot.speech.channel import DEFAULT_CHANNEL, ChannelModel
from ncbot.speech.noise import NOISE_KINDS
from ncbot.speech.roundtrip import RoundTripper, Trial, babble_pool
from ncbot.speech.tts import FLITE_VOICES, Voice

SNR_LEVELS: tuple[float | None, ...] = (None, 30.0, 20.0, 15.0, 10.0, 5.0)
FIT_VOICES = tuple(Voice("flite", name, rate) for name in FLITE_VOICES for rate in (0.85, 1.15))
REPORT_VOICES = tuple(Voice("flite", name) for name in FLITE_VOICES)
FIT_BABBLE_VOICES = tuple(Voice("espeak-ng", name) for name in ("en-us+m3", "en-gb+f2", "en+m1"))
REPORT_BABBLE_VOICES = tuple(Voice("espeak-ng", name) for name in ("en-us+f3", "en-gb-scotland+m2", "en+f4"))
FIT_SEED, REPORT_SEED = 1_000_000, 0


def babble_texts() -> list[str]:
    """What the other talkers say: the robot's templates and the user sentences."""
    from ncbot.envs.dialogue import TEMPLATES

    return list(TEMPLATES) + sorted(set(dialogue_sentences()))


def fit_trials(seeds: int) -> list[Trial]:
    """Every user sentence x fit voice, clean once and at each noisy level and kind ``seeds`` times."""
    trials, seed = [], FIT_SEED
    for text in sorted(set(dialogue_sentences())):
        for voice in FIT_VOICES:
            for snr in SNR_LEVELS:
                for kind in (NOISE_KINDS[:1] if snr is None else NOISE_KINDS):
                    for _ in range(1 if snr is None else seeds):
                        trials.append(Trial(text, voice, kind, snr, seed))
                        seed += 1
    return trials


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_CHANNEL)
    parser.add_argument("--seeds", type=int, default=2, help="noise draws per sentence, voice and noisy level")
    parser.add_argument("--show", action="store_true", help="print the figures of the model at --out, fit nothing")
    args = parser.parse_args(argv)
    if args.show:
        print_summary(ChannelModel.load(args.out))
        return
    start = time.time()
    recogniser = Recogniser()
    tripper = RoundTripper(recogniser, babble_pool(babble_texts(), FIT_BABBLE_VOICES))
    trials = fit_trials(args.seeds)
    trips = tripper.run_all(trials)
    model = ChannelModel.fit(
        ((t.trial.kind, t.trial.snr_db, t.said, t.heard) for t in trips),
        recogniser.vocabulary, SNR_LEVELS, NOISE_KINDS,
        meta={
            "command": f"python -m ncbot.speech.fit --seeds {args.seeds}",
            "round_trips": len(trips),
            "voices": [v.spec for v in FIT_VOICES],
            "babble_voices": [v.spec for v in FIT_BABBLE_VOICES],
            "first_seed": FIT_SEED,
            "texts": len({t.text for t in trials}),
        },
    )
    model.save(args.out)
    levels = Counter((t.trial.kind if t.trial.snr_db is not None else "clean", t.trial.snr_db) for t in trips)
    print(f"fitted {args.out} from {len(trips)} round trips ({dict(levels)}) in {time.time() - start:.0f} s")
    print_summary(model)


def print_summary(model: ChannelModel) -> None:
    print(f"{'kind':<8}{'SNR dB':>7}{'trips':>7}{'words':>7}{'WER':>7}{'del':>7}{'ins':>7}{'conf ok':>9}")
    for row in model.summary():
        if row["snr_db"] is None and row["kind"] != model.kinds[0]:
            continue  # the clean level is the same round trips in every kind
        snr = "clean" if row["snr_db"] is None else f"{row['snr_db']:g}"
        print(f"{row['kind'] if row['snr_db'] is not None else '-':<8}{snr:>7}{row['round_trips']:>7}{row['words']:>7}"
              f"{row['word_error_rate']:7.3f}{row['deleted']:7.3f}{row['inserted']:7.3f}{row['correct_confidence']:9.3f}")


if __name__ == "__main__":
    main()
