"""Background noise at a chosen signal-to-noise ratio: white noise, and babble made from other utterances.

Why both: white noise is the simplest, reproducible stress; babble (several other talkers at once) is what an
atrium sounds like and the harder case for a recogniser, because it is speech-shaped.
SNR is measured on the whole utterance (mean power of the clean samples over mean power of the noise).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

NOISE_KINDS = ("white", "babble")


def white_noise_at(samples: np.ndarray, snr_db: float, rng: np.random.Generator) -> np.ndarray:
    """``samples`` with Gaussian white noise added at ``snr_db`` (int16 out, clipped)."""
    return mix_at(samples, rng.standard_normal(samples.size), snr_db)


def babble_noise_at(
    samples: np.ndarray, snr_db: float, pool: Sequence[np.ndarray], rng: np.random.Generator, talkers: int = 4
) -> np.ndarray:
    """``samples`` with ``talkers`` other utterances from ``pool`` (looped, random offsets) added at ``snr_db``."""
    pool = [p for p in pool if p.size]
    if not pool:
        raise ValueError("babble noise needs a pool of at least one non-empty utterance")
    babble = np.zeros(samples.size, dtype=np.float64)
    for _ in range(talkers):
        talker = pool[int(rng.integers(len(pool)))].astype(np.float64)
        talker = talker / max(np.sqrt(np.mean(talker**2)), 1e-9)  # each talker at the same level
        looped = np.tile(talker, samples.size // talker.size + 2)
        start = int(rng.integers(talker.size))
        babble += looped[start : start + samples.size]
    return mix_at(samples, babble, snr_db)


def add_noise(
    samples: np.ndarray, kind: str, snr_db: float | None, rng: np.random.Generator, pool: Sequence[np.ndarray] = ()
) -> np.ndarray:
    """Noise of ``kind`` (white|babble) at ``snr_db``; ``None`` (clean) returns the samples unchanged."""
    if kind not in NOISE_KINDS:
        raise ValueError(f"unknown noise kind {kind!r}; kinds: {', '.join(NOISE_KINDS)}")
    if snr_db is None:
        return samples
    return white_noise_at(samples, snr_db, rng) if kind == "white" else babble_noise_at(samples, snr_db, pool, rng)


def mix_at(samples: np.ndarray, noise: np.ndarray, snr_db: float) -> np.ndarray:
    """``samples`` plus ``noise`` scaled so that signal power / noise power is ``snr_db`` (int16 out)."""
    if noise.shape != samples.shape:
        raise ValueError(f"noise has shape {noise.shape}, expected the samples' {samples.shape}")
    if samples.size == 0:
        return samples.astype(np.int16)
    signal = samples.astype(np.float64)
    signal_power = float(np.mean(signal**2))
    noise_power = float(np.mean(np.asarray(noise, dtype=np.float64) ** 2))
    if signal_power == 0.0 or noise_power == 0.0:
        return samples.astype(np.int16)
    scale = np.sqrt(signal_power / (noise_power * 10.0 ** (snr_db / 10.0)))
    return np.clip(np.round(signal + scale * noise), -32768, 32767).astype(np.int16)
