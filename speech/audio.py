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

AUDIO_FORMAT = "pcm-s16"  # signed 16-bit little-endian PCM, channels interleaved
#: what the robot says; what its microphones took in while the person answered (one channel, or Pepper's four);
#: with the array, what of it reached the recogniser (the enhanced mono)
AUDIO_TOPICS = {"robot": "/audio/robot", "user": "/audio/user", "enhanced": "/audio/user/enhanced"}


def raw_audio(samples: np.ndarray):
    """A ``foxglove.RawAudio`` message of 16 kHz int16 ``samples``: 1-D mono, or (channels, n) interleaved (the
    logger stamps its timestamp)."""
    from foxglove_schemas_protobuf.RawAudio_pb2 import RawAudio

    samples = np.asarray(samples)
    channels = _checked(samples[None, :] if samples.ndim == 1 else samples, multi=True)
    return RawAudio(data=channels.T.astype("<i2").tobytes(), format=AUDIO_FORMAT, sample_rate=SAMPLE_RATE,
                    number_of_channels=channels.shape[0])


def samples_from_raw_audio(message) -> np.ndarray:
    """The int16 samples of a mono ``foxglove.RawAudio`` message written by ``raw_audio`` (ValueError otherwise)."""
    if message.number_of_channels != 1:
        raise ValueError(f"expected mono audio, got {message.number_of_channels} channels (channels_from_raw_audio)")
    return channels_from_raw_audio(message)[0]


def channels_from_raw_audio(message) -> np.ndarray:
    """(channels, n) int16 samples of a ``foxglove.RawAudio`` message written by ``raw_audio`` (ValueError otherwise)."""
    if message.format != AUDIO_FORMAT or message.number_of_channels < 1 or message.sample_rate != SAMPLE_RATE:
        raise ValueError(f"expected {AUDIO_FORMAT} audio at {SAMPLE_RATE} Hz, got {message.format} with "
                         f"{message.number_of_channels} channel(s) at {message.sample_rate} Hz")
    interleaved = np.frombuffer(message.data, dtype="<i2").astype(np.int16)
    return interleaved.reshape(-1, message.number_of_channels).T.copy()


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


def _checked(samples: np.ndarray, multi: bool = False) -> np.ndarray:
    samples = np.asarray(samples)
    if samples.dtype != np.int16 or samples.ndim != (2 if multi else 1):
        what = "(channels, n)" if multi else "1-D"
        raise ValueError(f"expected {what} int16 samples at {SAMPLE_RATE} Hz, got {samples.dtype} {samples.shape}")
    return samples
