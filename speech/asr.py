"""A pocketsphinx 5 recogniser for the game's closed vocabulary: a small language model built from the example
dialogues' user utterances and a dictionary cut to their words.

Why this mode (measured on this machine, docs/speech.md): the small LM decodes the game's sentences with a low
word error rate in ~0.06 CPU s, and its per-word posteriors fall with noise. The default 27 MB LM is slower and
far less accurate; keyword-list mode gives near-constant confidences, so it is never used here.
Per-word confidence is ``Segment.prob``: already a linear posterior in [0, 1] in pocketsphinx 5.1.x.
"""
from __future__ import annotations

import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ncbot.speech import SAMPLE_RATE

GAMES = ("standard", "ultimate")


@dataclass(frozen=True)
class Heard:
    """What the recogniser heard: words (lower case, may be empty) and each word's posterior in [0, 1]."""

    words: tuple[str, ...]
    confidences: tuple[float, ...]

    @property
    def text(self) -> str:
        return " ".join(self.words)


def dialogue_sentences(games: Sequence[str] = GAMES) -> list[str]:
    """Every user utterance of the example dialogues of ``games`` (with repeats: the LM learns their frequency)."""
    from ncbot.envs.dialogue import load_dialogues, tokenize

    return [
        " ".join(tokenize(turn["says"]))
        for game in games
        for dialogue in load_dialogues(game)
        for turn in dialogue.get("turns", [])
        if turn.get("says")
    ]


class Recogniser:
    """pocketsphinx decoder over the vocabulary of ``sentences`` (default: the example dialogues' user utterances)."""

    def __init__(self, sentences: Iterable[str] | None = None) -> None:
        corpus = [s.strip().lower() for s in (dialogue_sentences() if sentences is None else sentences) if s.strip()]
        if not corpus:
            raise ValueError("the recogniser needs at least one non-empty sentence to build its language model")
        self.vocabulary = tuple(sorted({w for s in corpus for w in s.split()}))
        with tempfile.TemporaryDirectory(prefix="ncbot-asr-") as folder:
            lm_path = Path(folder) / "game.lm"
            _write_language_model(corpus, lm_path)
            self._lm_text = lm_path.read_text()
        self._dict_text = _cut_dictionary(self.vocabulary)
        self.reset()

    def reset(self) -> None:
        """A fresh decoder (~0.05 s). pocketsphinx adapts its cepstral mean from utterance to utterance (as a
        robot's ears adapt to a room), so what it hears depends on what it heard before; resetting at the start
        of each game makes a game's hearing depend on that game alone (and its seed)."""
        from pocketsphinx import Decoder

        with tempfile.TemporaryDirectory(prefix="ncbot-asr-") as folder:
            lm_path, dict_path = Path(folder) / "game.lm", Path(folder) / "game.dict"
            lm_path.write_text(self._lm_text)
            dict_path.write_text(self._dict_text)
            # the decoder reads both files at construction: the folder may go afterwards
            self._decoder = Decoder(lm=str(lm_path), dict=str(dict_path), samprate=SAMPLE_RATE, loglevel="FATAL")

    def recognise(self, samples: np.ndarray) -> Heard:
        """Decode one utterance (int16, 16 kHz mono). Nothing heard is a valid result: empty words."""
        samples = np.asarray(samples)
        if samples.dtype != np.int16 or samples.ndim != 1:
            raise ValueError(f"expected 1-D int16 samples at {SAMPLE_RATE} Hz, got {samples.dtype} {samples.shape}")
        decoder = self._decoder
        decoder.start_utt()
        if samples.size:
            decoder.process_raw(samples.tobytes(), full_utt=True)
        decoder.end_utt()
        words, confidences = [], []
        for segment in decoder.seg() or []:
            if segment.word.startswith(("<", "[", "++")):
                continue  # silence, noise and filler segments
            words.append(segment.word.split("(")[0])  # "a(2)" is the second pronunciation of "a"
            confidences.append(float(min(max(segment.prob, 0.0), 1.0)))
        return Heard(tuple(words), tuple(confidences))


def _write_language_model(corpus: list[str], path: Path) -> None:
    from pocketsphinx.lm import ArpaBoLM

    model = ArpaBoLM(text="\n".join(corpus) + "\n", add_start=True)
    model.compute()
    model.write_file(str(path))


def _cut_dictionary(vocabulary: Sequence[str]) -> str:
    """The cmudict lines (all pronunciations) of ``vocabulary``; ValueError names words it does not know."""
    from pocketsphinx import get_model_path

    wanted = set(vocabulary)
    lines = []
    with open(Path(get_model_path()) / "en-us" / "cmudict-en-us.dict", encoding="utf-8") as handle:
        for line in handle:
            word = line.split(" ", 1)[0]
            if word.split("(")[0] in wanted:
                lines.append(line)
    missing = wanted - {line.split(" ", 1)[0].split("(")[0] for line in lines}
    if missing:
        raise ValueError(f"words not in the pocketsphinx dictionary: {', '.join(sorted(missing))}")
    return "".join(lines)
