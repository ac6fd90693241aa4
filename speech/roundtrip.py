"""Real round trips: text -> TTS voice -> background noise -> recogniser, with CPU time per stage.

Used to measure the recogniser (bench/studies/speech_asr.py) and to fit the channel model (``python -m ncbot.speech.fit``).
TTS audio is cached per (text, voice): noise and decoding vary, the clean speech of a voice does not.
"""
from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ncbot.speech.asr import Heard, Recogniser
from ncbot.speech.noise import add_noise
from ncbot.speech.tts import SpeechCache, Voice, speak


@dataclass(frozen=True)
class Trial:
    """One utterance to speak and hear: ``snr_db`` None is clean (``kind`` then only labels the level)."""

    text: str
    voice: Voice
    kind: str
    snr_db: float | None
    seed: int


@dataclass(frozen=True)
class RoundTrip:
    trial: Trial
    said: tuple[str, ...]
    heard: Heard
    tts_cpu_s: float  # CPU of the TTS, engine subprocess included; 0 when the audio came from the cache
    asr_cpu_s: float


class RoundTripper:
    """Speaks, adds noise and decodes; ``babble_pool`` holds the other talkers' audio for babble noise."""

    def __init__(self, recogniser: Recogniser, babble_pool: Sequence[np.ndarray] = ()) -> None:
        self.recogniser = recogniser
        self.babble_pool = list(babble_pool)
        self.cache = SpeechCache()

    def audio(self, text: str, voice: Voice) -> tuple[np.ndarray, float]:
        """Clean samples of ``voice`` saying ``text`` and the CPU seconds it cost (0 after the first time)."""
        return self.cache.speak(text, voice)

    def run(self, trial: Trial) -> RoundTrip:
        samples, tts_cpu = self.audio(trial.text, trial.voice)
        noisy = add_noise(samples, trial.kind, trial.snr_db, np.random.default_rng(trial.seed), self.babble_pool)
        start = time.process_time()
        heard = self.recogniser.recognise(noisy)
        asr_cpu = time.process_time() - start
        return RoundTrip(trial, tuple(trial.text.split()), heard, tts_cpu, asr_cpu)

    def run_all(self, trials: Iterable[Trial]) -> list[RoundTrip]:
        return [self.run(trial) for trial in trials]


def babble_pool(texts: Iterable[str], voices: Sequence[Voice]) -> list[np.ndarray]:
    """Other talkers for babble noise: each text spoken by the voices in turn."""
    return [speak(text, voices[i % len(voices)]) for i, text in enumerate(texts)]
