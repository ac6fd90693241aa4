"""What Pepper's four microphones take in while the robot listens for one reply: the person's voice through the
room, babble talkers at their places or a diffuse noise field, at a chosen SNR at the array.

The robot opens its ears when it stops speaking and closes them a little after the person stops: the window
holds a turn-taking gap before the reply (0.3-0.9 s, drawn) and a tail after it (0.3-0.6 s), so the robot's own
voice activity detection, not the simulation, decides where the reply is (`ncbot.speech.vad`).
SNR at the array: mean power of the person's speech as the four microphones hear it (reverberation included),
over the reply's own duration, against the mean power of the noise over the same samples.
Noise kinds (`ncbot.speech.noise.NOISE_KINDS`): babble = every talker of the room says other utterances of the
pool (each at the same level at its mouth, pauses between utterances), heard through the room; white = a
spherically diffuse white noise field (the hum of a hall: the same power at every microphone, with the
sin(x)/x coherence between two microphones that a diffuse field has).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ncbot.speech import SAMPLE_RATE
from ncbot.speech.array import SPEED_OF_SOUND
from ncbot.speech.room import Room

GAP_SECONDS = (0.3, 0.9)
TAIL_SECONDS = (0.3, 0.6)
FULL_SCALE = 0.5  # the window's loudest sample after the microphones' gain (of int16 full scale)
DIFFUSE_NFFT = 512


@dataclass(frozen=True)
class ArrayTake:
    """One listening window: int16 (M, n) microphone signals, where the reply lies in it (samples; truth for
    benches only, the robot never reads it) and the SNR at the array (None: no noise)."""

    channels: np.ndarray
    speech_span: tuple[int, int]
    snr_db: float | None


class ArrayRecorder:
    """Records `Room` windows: the person (source 0) says a reply over `kind` noise; babble comes from the room's
    talkers saying utterances of `babble_pool`."""

    def __init__(self, room: Room, kind: str, babble_pool: Sequence[np.ndarray] = ()) -> None:
        from ncbot.speech.noise import NOISE_KINDS

        if kind not in NOISE_KINDS:
            raise ValueError(f"unknown noise kind {kind!r}; kinds: {', '.join(NOISE_KINDS)}")
        self.room, self.kind = room, kind
        self.babble_pool = [np.asarray(p, dtype=np.float64) for p in babble_pool if np.asarray(p).size]

    def record(self, samples: np.ndarray, snr_db: float | None, rng: np.random.Generator) -> ArrayTake:
        """The window in which the person says `samples` (int16 16 kHz mono, clean) with noise at `snr_db`."""
        speech, noise, span = self.parts(samples, snr_db, rng)
        signals = speech + noise
        peak = float(np.max(np.abs(signals))) or 1.0
        channels = np.round(signals * (FULL_SCALE * 32767.0 / peak)).astype(np.int16)
        return ArrayTake(channels, span, snr_db)

    def parts(self, samples: np.ndarray, snr_db: float | None, rng: np.random.Generator) -> tuple[
            np.ndarray, np.ndarray, tuple[int, int]]:
        """The window's two parts as float (M, n) arrays, the person's speech and the noise scaled to `snr_db`
        over the reply (zeros without noise), and the reply's span in samples."""
        gap = int(rng.uniform(*GAP_SECONDS) * SAMPLE_RATE)
        tail = int(rng.uniform(*TAIL_SECONDS) * SAMPLE_RATE)
        voice = self.room.at_microphones(samples, 0)
        length = gap + voice.shape[1] + tail
        speech = np.zeros((voice.shape[0], length))
        speech[:, gap:gap + voice.shape[1]] = voice
        span = (gap, gap + int(np.asarray(samples).size))
        noise = np.zeros_like(speech)
        if snr_db is not None and span[1] > span[0]:
            noise = self._noise(length, rng)
            speech_power = float(np.mean(speech[:, span[0]:span[1]] ** 2))
            noise_power = float(np.mean(noise[:, span[0]:span[1]] ** 2))
            if speech_power > 0.0 and noise_power > 0.0:
                noise = noise * np.sqrt(speech_power / (noise_power * 10.0 ** (snr_db / 10.0)))
        return speech, noise, span

    def _noise(self, length: int, rng: np.random.Generator) -> np.ndarray:
        if self.kind == "white":
            return diffuse_noise(self.room.mics, length, rng)
        if not self.room.layout.talkers:
            raise ValueError("babble noise in a room needs at least one talker (conditions: speech_talkers)")
        if not self.babble_pool:
            raise ValueError("babble noise needs a babble_pool of other utterances (e.g. the robot's templates)")
        talkers = range(1, len(self.room.layout.talkers) + 1)
        return self.room.heard_together({talker: self._talk(length, rng) for talker in talkers})[:, :length]

    def _talk(self, length: int, rng: np.random.Generator) -> np.ndarray:
        """One talker's stream: pool utterances at one level with pauses of 0.05-0.25 s, from a random offset."""
        parts, total = [], 0
        while total < 2 * length:
            utterance = self.babble_pool[int(rng.integers(len(self.babble_pool)))]
            parts += [utterance / max(np.sqrt(np.mean(utterance ** 2)), 1e-9),
                      np.zeros(int(rng.uniform(0.05, 0.25) * SAMPLE_RATE))]
            total += parts[-2].size + parts[-1].size
        stream = np.concatenate(parts)
        start = int(rng.integers(stream.size - length + 1))
        return stream[start:start + length]


def diffuse_noise(mics: np.ndarray, length: int, rng: np.random.Generator) -> np.ndarray:
    """(M, length) spherically diffuse white noise at microphones `mics` (3, M): per frequency, independent
    Gaussian noise mixed through the Cholesky factor of the diffuse coherence sin(kd)/(kd)."""
    from scipy.signal import istft

    frequencies = np.fft.rfftfreq(DIFFUSE_NFFT, 1.0 / SAMPLE_RATE)
    distance = np.linalg.norm(mics[:, :, None] - mics[:, None, :], axis=0)
    coherence = np.sinc(2.0 * frequencies[:, None, None] * distance[None] / SPEED_OF_SOUND)
    mixing = np.linalg.cholesky(coherence + 1e-6 * np.eye(mics.shape[1]))
    frames = length // (DIFFUSE_NFFT // 2) + 4
    shape = (mics.shape[1], frequencies.size, frames)
    independent = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2.0)
    spectra = np.einsum("fmn,nft->mft", mixing, independent)
    _, signals = istft(spectra, fs=SAMPLE_RATE, nperseg=DIFFUSE_NFFT)
    return signals[:, :length]
