"""The answers to "where did you draw?" and "did you say ...?" through the real recogniser, per noise condition:
how often the cell phrase is heard as its cell, as no cell, or as another cell, and the same for the
confirmation; with `--lone-words` also a lone "yes" / "no" heard through the cell phrases' LM (the design this
replaced: why the confirmation is a whole sentence with its own LM, speech/cell_answers.py).

    python bench/studies/cell_answers.py [--repeats 2] [--seed 12345] [--lone-words]

The person's voices are the four flite voices at their normal rate (robot play's), babble talkers the report set
of speech/fit.py; every 3x3 cell phrase `--repeats` times per voice, each confirmation 4 times per voice.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.speech.asr import Recogniser  # noqa: E402
from ncbot.speech.cell_answers import (CONFIRM_NO, CONFIRM_YES, answer_sentences, cell_of, cell_phrase,  # noqa: E402
                                 confirm_sentences, yes_or_no)
from ncbot.speech.fit import REPORT_BABBLE_VOICES, REPORT_VOICES, babble_texts  # noqa: E402
from ncbot.speech.noise import add_noise  # noqa: E402
from ncbot.speech.roundtrip import babble_pool  # noqa: E402
from ncbot.speech.tts import SpeechCache  # noqa: E402

CONDITIONS = (("white", None), ("babble", 20.0), ("babble", 15.0), ("babble", 10.0), ("white", 10.0), ("white", 5.0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--lone-words", action="store_true")
    args = parser.parse_args()
    cache, pool = SpeechCache(), babble_pool(babble_texts(), REPORT_BABBLE_VOICES)
    cells, confirm = Recogniser(answer_sentences(3)), Recogniser(confirm_sentences())
    lone = Recogniser(answer_sentences(3) + ["yes", "no"]) if args.lone_words else None
    rng = np.random.default_rng(args.seed)
    print("| noise | SNR dB | cell phrases: right / none / other cell | confirmations: right / none / swapped |"
          + (" lone yes/no: right / none / swapped |" if lone else ""))
    print("|---|---|---|---|" + ("---|" if lone else ""))
    for kind, snr in CONDITIONS:
        counts = {"cell": [0, 0, 0], "confirm": [0, 0, 0], "lone": [0, 0, 0]}

        def heard(text: str, recogniser: Recogniser) -> tuple[str, ...]:
            return recogniser.recognise(add_noise(cache.speak(text, voice)[0], kind, snr, rng, pool)).words

        for voice in REPORT_VOICES:
            for _ in range(args.repeats):
                for cell in range(9):
                    got = cell_of(heard(cell_phrase(cell, 3), cells), 3)
                    counts["cell"][0 if got == cell else (1 if got is None else 2)] += 1
            for text, truth in ((CONFIRM_YES, True), (CONFIRM_NO, False)) * 4:
                got = yes_or_no(heard(text, confirm))
                counts["confirm"][0 if got is truth else (1 if got is None else 2)] += 1
                if lone is not None:
                    words = heard("yes" if truth else "no", lone)
                    got = {("yes",): True, ("no",): False}.get(tuple(words))
                    counts["lone"][0 if got is truth else (1 if got is None else 2)] += 1
        row = f"| {kind if snr is not None else '-'} | {'clean' if snr is None else f'{snr:g}'} | " + \
              " / ".join(map(str, counts["cell"])) + " | " + " / ".join(map(str, counts["confirm"])) + " |"
        print(row + (" " + " / ".join(map(str, counts["lone"])) + " |" if lone else ""), flush=True)


if __name__ == "__main__":
    main()
