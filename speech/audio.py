"""Audio as messages and files: ``foxglove.RawAudio`` (pcm-s16, 16 kHz, mono) for the MCAP log of robot games,
and WAV files for people to listen to.

Why RawAudio: it is Foxglove's own audio schema (``foxglove-schemas-protobuf``, already a dependency), so
Foxglove plays the ``/audio/robot`` and ``/audio/user`` channels as they are, and it names the sample rate and
encoding in every message.
"""
from __future__ import annotations

import wave
from pathlib import Path

import numpy as np

from ncbot.fileio.atomic import atomic_path
from ncbot.speech import SAMPLE_RATE

AUDIO_FORMAT = "pcm-s16"  # signed 16-bit little-endian PCM, interleaved (one channel here)
AUDIO_TOPICS = {"robot": "/audio/robot", "user": "/audio/user"}


def raw_audio(samples: np.ndarray):
    """A ``foxglove.RawAudio`` message of 16 kHz mono int16 ``samples`` (the logger stamps its timestamp)."""
    from foxglove_schemas_protobuf.RawAudio_pb2 import RawAudio

    samples = _checked(samples)
    return RawAudio(data=samples.astype("<i2").tobytes(), format=AUDIO_FORMAT, sample_rate=SAMPLE_RATE,
                    number_of_channels=1)


def samples_from_raw_audio(message) -> np.ndarray:
    """The int16 samples of a ``foxglove.RawAudio`` message written by ``raw_audio`` (ValueError otherwise)."""
    if message.format != AUDIO_FORMAT or message.number_of_channels != 1 or message.sample_rate != SAMPLE_RATE:
        raise ValueError(f"expected {AUDIO_FORMAT} mono audio at {SAMPLE_RATE} Hz, got {message.format} with "
                         f"{message.number_of_channels} channel(s) at {message.sample_rate} Hz")
    return np.frombuffer(message.data, dtype="<i2").astype(np.int16)


def write_wav(path: str | Path, samples: np.ndarray) -> Path:
    """Write ``samples`` as a 16 kHz mono 16-bit WAV atomically (temporary file, then renamed)."""
    samples = _checked(samples)

    with atomic_path(path) as temp, wave.open(str(temp), "wb") as writer:
        writer.setnchannels(1)
        writer.setsampwidth(2)
        writer.setframerate(SAMPLE_RATE)
        writer.writeframes(samples.astype("<i2").tobytes())
    return Path(path)


def read_wav(path: str | Path) -> np.ndarray:
    """Samples of a 16 kHz mono 16-bit WAV (ValueError for any other kind)."""
    with wave.open(str(path), "rb") as reader:
        if (reader.getnchannels(), reader.getsampwidth(), reader.getframerate()) != (1, 2, SAMPLE_RATE):
            raise ValueError(f"{path}: expected 16-bit mono WAV at {SAMPLE_RATE} Hz")
        return np.frombuffer(reader.readframes(reader.getnframes()), dtype="<i2").astype(np.int16)


def _checked(samples: np.ndarray) -> np.ndarray:
    samples = np.asarray(samples)
    if samples.dtype != np.int16 or samples.ndim != 1:
        raise ValueError(f"expected 1-D int16 samples at {SAMPLE_RATE} Hz, got {samples.dtype} {samples.shape}")
    return samples
