"""The dialogue env's ears, batched: which of the env's words the robot hears for each game's user utterance,
with what confidence, and which example utterance it understands them as.

Why here and not in ``envs``: ``speech`` sits above ``envs`` (it reads the example dialogues), so the env takes a
hearing object from the caller (pipelines builds it from the config), as it takes an opponent object. Both kinds
answer ``hear(utterance ids (B,), generator) -> (env word columns (B, H), confidences (B, H), understood (B,))``:
``ChannelHearing`` samples the fitted channel model (training, microseconds); ``RecogniserHearing`` speaks the
utterance with the person's voice, adds noise and runs the real recogniser (the robot's game loop, ~0.1 s).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from ncbot.speech.align import word_errors
from ncbot.speech.asr import Heard, Recogniser
from ncbot.speech.channel import ChannelModel
from ncbot.speech.ears import EarTake, MonoEars
from ncbot.speech.tts import PERSON_VOICE, SpeechCache, Voice
from ncbot.speech.understand import closest_utterance, utterance_table


class ChannelHearing:
    """Hears a batch of the env's utterance ids through ``model`` at an SNR drawn per utterance, uniformly in
    ``snr_db`` (low, high) dB (None = clean), in ``kind`` noise."""

    def __init__(
        self, model: ChannelModel, utterance_texts: Sequence[str], env_words: Sequence[str],
        snr_db: tuple[float, float] | None = (10.0, 30.0), kind: str = "babble",
    ) -> None:
        from ncbot.envs.dialogue import tokenize

        if kind not in model.kinds:
            raise ValueError(f"noise kind {kind!r} is not in the channel model; kinds: {', '.join(model.kinds)}")
        if snr_db is not None and not (len(snr_db) == 2 and snr_db[0] <= snr_db[1]):
            raise ValueError(f"snr_db must be (low, high) with low <= high, or None for clean; got {snr_db!r}")
        self.model, self.kind, self.snr_db = model, kind, snr_db
        texts = [" ".join(tokenize(t)) for t in utterance_texts]
        # said word ids per env utterance; one more row (all padding) for silence, the env's utterance id U
        if not texts:
            raise ValueError("the env has no user utterances to hear")
        said = model.encode(texts)
        self._said = torch.cat([said, torch.full((1, said.shape[1]), len(model.words))])
        column = {w: i for i, w in enumerate(env_words)}
        # channel word id -> env word column (len(env_words) = not an env word, or nothing heard)
        self._column = torch.tensor([column.get(w, len(env_words)) for w in model.words] + [len(env_words)])
        self._table = utterance_table(texts, env_words)
        self.n_env_words = len(env_words)

    def hear(
        self, utterance: torch.Tensor, generator: torch.Generator | None = None, snr_db: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """For utterance ids (B,) (U = silence): env word columns (B, H) (``n_env_words`` = nothing), their
        confidences (B, H) float32 (0 for nothing) and the utterance understood (B,) (-1 = heard as silence)."""
        said = self._said.index_select(0, utterance)
        if snr_db is None:
            if self.snr_db is None:
                snr_db = torch.full(utterance.shape, float("inf"))
            else:
                low, high = self.snr_db
                snr_db = low + (high - low) * torch.rand(utterance.shape, generator=generator)
        heard, confidence = self.model.sample(said, snr_db, self.kind, generator)
        columns = self._column.index_select(0, heard.reshape(-1)).reshape(heard.shape)
        confidence = torch.where(columns < self.n_env_words, confidence, torch.zeros(()))
        return columns, confidence, closest_utterance(columns, confidence, self._table)


def heard_tensors(heard: Heard, utterance_texts: Sequence[str], env_words: Sequence[str]) -> tuple[
        torch.Tensor, torch.Tensor, torch.Tensor]:
    """The real recogniser's result for one game as ``ChannelHearing.hear``'s (1, H), (1, H), (1,) tensors."""
    from ncbot.envs.dialogue import tokenize

    column = {w: i for i, w in enumerate(env_words)}
    columns = torch.tensor([[column.get(w, len(env_words)) for w in heard.words] or [len(env_words)]])
    confidence = torch.tensor([list(heard.confidences) or [0.0]], dtype=torch.float32)
    confidence = torch.where(columns < len(env_words), confidence, torch.zeros(()))
    table = utterance_table([" ".join(tokenize(t)) for t in utterance_texts], env_words)
    return columns, confidence, closest_utterance(columns, confidence, table)


@dataclass(frozen=True)
class HeardUtterance:
    """One utterance the robot heard for real: what was said, the audio it heard, and what came out."""

    said: str
    samples: np.ndarray  # int16, 16 kHz mono, noise included: what the recogniser decoded
    heard: Heard
    understood: int  # utterance id, -1 silence
    snr_db: float | None  # None: clean
    tts_cpu_s: float  # 0 when the clean speech came from the cache
    asr_cpu_s: float
    tts_wall_s: float
    asr_wall_s: float
    #: what the microphones took in, (C, n) int16 (one microphone: the samples themselves) and, for the array, the
    #: enhancement's work (`ncbot.speech.enhance.Enhanced`)
    take: EarTake | None = None

    @property
    def channels(self) -> np.ndarray:
        return self.samples[None, :] if self.take is None else self.take.channels


SnrSpec = float | tuple[float, float] | None


def say_in_noise_and_hear(text: str, recogniser: Recogniser, voice: Voice, cache: SpeechCache, ears,
                          snr_db: SnrSpec, rng: np.random.Generator, meaning: Callable[[Heard], int],
                          said: str | None = None) -> HeardUtterance:
    """`voice` says `text` (from `cache`), `ears` (`ncbot.speech.ears`: one microphone or the array) take it in
    over their noise at `snr_db` (a (low, high) range: a level drawn from `rng` first, then the noise),
    `recogniser` decodes what they pass on; ``understood`` = `meaning(heard)`, ``said`` = the words logged as
    said (default `text`; its punctuation is spoken as pauses). One path for every reply the robot hears, so
    dialogue replies and cell answers are spoken, noised, timed and logged alike."""
    wall = time.perf_counter()
    samples, tts_cpu = cache.speak(text, voice)
    level = float(rng.uniform(*snr_db)) if isinstance(snr_db, tuple) else snr_db
    take = ears.take(samples, level, rng)
    tts_wall = time.perf_counter() - wall
    wall, started = time.perf_counter(), time.process_time()
    heard = recogniser.recognise(take.samples)
    asr_cpu, asr_wall = time.process_time() - started, time.perf_counter() - wall
    return HeardUtterance(text if said is None else said, take.samples, heard, meaning(heard), level, tts_cpu,
                          asr_cpu, tts_wall, asr_wall, take)


class RecogniserHearing:
    """Real ears for the robot's game loop: speaks each utterance with ``voice``, adds ``kind`` noise at
    ``snr_db`` (a level, a (low, high) range drawn uniformly per utterance, or None = clean) and decodes it;
    every utterance heard is kept in ``log`` (audio for the MCAP log, words for the game report's ASR figures).
    ``seed`` seeds the noise; ``cache`` (shared with the robot's voice) keeps each clean utterance's speech.
    ``ears``: what takes the reply in (``ncbot.speech.ears``; default one microphone with ``kind`` noise from
    ``babble_pool``, Pepper's array in a room otherwise)."""

    def __init__(
        self, utterance_texts: Sequence[str], env_words: Sequence[str], recogniser: Recogniser | None = None,
        voice: Voice = PERSON_VOICE, snr_db: SnrSpec = None, kind: str = "babble",
        babble_pool: Sequence[np.ndarray] = (), seed: int | Sequence[int] = 0, cache: SpeechCache | None = None,
        ears=None,
    ) -> None:
        from ncbot.envs.dialogue import tokenize

        if isinstance(snr_db, tuple) and not (len(snr_db) == 2 and snr_db[0] <= snr_db[1]):
            raise ValueError(f"snr_db must be a level, (low, high) with low <= high, or None for clean; got {snr_db!r}")
        if kind == "babble" and snr_db is not None and not babble_pool:
            raise ValueError("babble noise needs a babble_pool of other utterances (e.g. the robot's templates)")
        self.ears = ears if ears is not None else MonoEars(kind, babble_pool)
        self.texts = [" ".join(tokenize(t)) for t in utterance_texts]
        self.env_words = list(env_words)
        self.recogniser = recogniser if recogniser is not None else Recogniser()
        self.voice, self.snr_db, self.kind, self.babble_pool = voice, snr_db, kind, list(babble_pool)
        self.cache = cache if cache is not None else SpeechCache()
        self.rng = np.random.default_rng(seed)
        self.log: list[HeardUtterance] = []

    def hear(self, utterance: torch.Tensor, generator: torch.Generator | None = None) -> tuple[
            torch.Tensor, torch.Tensor, torch.Tensor]:
        """Same contract as ``ChannelHearing.hear``; ``generator`` is unused (the noise has its own seed)."""
        rows = [self._hear_one(int(u)) for u in utterance.reshape(-1)]
        width = max(r[0].shape[1] for r in rows)
        pad = len(self.env_words)
        columns = torch.stack([torch.nn.functional.pad(r[0][0], (0, width - r[0].shape[1]), value=pad) for r in rows])
        confidence = torch.stack([torch.nn.functional.pad(r[1][0], (0, width - r[1].shape[1])) for r in rows])
        return columns, confidence, torch.cat([r[2] for r in rows])

    def _hear_one(self, utterance: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        if not 0 <= utterance < len(self.texts):  # silence: nothing to hear
            return heard_tensors(Heard((), ()), self.texts, self.env_words)
        results = []

        def meaning(heard: Heard) -> int:
            results.append(heard_tensors(heard, self.texts, self.env_words))
            return int(results[0][2][0])

        self.log.append(say_in_noise_and_hear(self.texts[utterance], self.recogniser, self.voice, self.cache,
                                              self.ears, self.snr_db, self.rng, meaning))
        return results[0]

    def word_error_rate(self) -> float | None:
        """Word error rate over every utterance heard so far (None before the first)."""
        return word_error_rate(self.log)

    def mean_confidence(self) -> float | None:
        """Mean confidence of every word heard so far (None if nothing was heard)."""
        return mean_confidence(self.log)


def word_error_rate(log: Sequence[HeardUtterance]) -> float | None:
    """Word errors over words said, over ``log`` (None when nothing was said)."""
    words = sum(len(h.said.split()) for h in log)
    return sum(word_errors(h.said.split(), h.heard.words) for h in log) / words if words else None


def mean_confidence(log: Sequence[HeardUtterance]) -> float | None:
    """Mean confidence of the words heard over ``log`` (None when no word was heard)."""
    confidences = [c for h in log for c in h.heard.confidences]
    return float(np.mean(confidences)) if confidences else None
