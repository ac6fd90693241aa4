"""Text to 16 kHz mono int16 samples with a named voice, through the Debian TTS engines (flite, espeak-ng).

Why subprocesses: both engines are small Debian packages with no maintained Python binding; one call costs a
few tens of ms of CPU, well under a robot turn. The robot speaks with espeak-ng (a robotic voice, never
recognised); the simulated person with flite voices (the recogniser decodes them well, see docs/speech.md).
"""
from __future__ import annotations

import io
import resource
import shutil
import subprocess
import wave
import zlib
from dataclasses import dataclass

import numpy as np

from ncbot.speech import SAMPLE_RATE
from ncbot.speech.noise import white_noise_at

ENGINES = ("flite", "espeak-ng")
FLITE_VOICES = ("slt", "rms", "awb", "kal16")
ESPEAK_FLOOR_DB = 35.0  # SNR of the noise floor added to espeak-ng output: its exact-zero runs confuse the decoder


@dataclass(frozen=True)
class Voice:
    """A TTS voice: ``engine`` flite|espeak-ng, ``name`` (flite voice or espeak-ng voice like ``en-us+m3``),
    ``rate`` (speaking-rate factor, 1 = engine default) and ``pitch`` (flite: f0 mean in Hz, 0 = voice default;
    espeak-ng: 0-99, 0 = default 50)."""

    engine: str
    name: str
    rate: float = 1.0
    pitch: float = 0.0

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise ValueError(f"unknown TTS engine {self.engine!r}; engines: {', '.join(ENGINES)}")
        if self.engine == "flite" and self.name not in FLITE_VOICES:
            raise ValueError(f"unknown flite voice {self.name!r}; voices: {', '.join(FLITE_VOICES)}")
        if not 0.3 <= self.rate <= 3.0:
            raise ValueError(f"voice rate must be in [0.3, 3], got {self.rate}")

    @property
    def spec(self) -> str:
        """``engine:name@rate`` (``parse_voice``'s input), for configs and logs."""
        return f"{self.engine}:{self.name}@{self.rate:g}"


def parse_voice(spec: str) -> Voice:
    """A voice from ``engine:name[@rate]``, e.g. ``flite:slt``, ``espeak-ng:en-us+f3@1.1`` (ValueError if not)."""
    engine, _, rest = spec.partition(":")
    name, _, rate = rest.partition("@")
    if not engine or not name:
        raise ValueError(f"voice {spec!r} is not engine:name[@rate], e.g. flite:slt or espeak-ng:en-us")
    try:
        return Voice(engine, name, float(rate) if rate else 1.0)
    except ValueError as error:
        raise ValueError(f"voice {spec!r}: {error}") from None


ROBOT_VOICE = Voice("espeak-ng", "en-us")
PERSON_VOICE = Voice("flite", "slt")


def speak(text: str, voice: Voice = PERSON_VOICE) -> np.ndarray:
    """Samples (int16, 16 kHz mono) of ``voice`` saying ``text``; empty text gives an empty array."""
    if not text.strip():
        return np.zeros(0, dtype=np.int16)
    if voice.engine == "flite":
        command = [_engine("flite"), "-voice", voice.name, "--setf", f"duration_stretch={1.0 / voice.rate:.4f}"]
        if voice.pitch:
            command += ["--setf", f"int_f0_target_mean={voice.pitch:.1f}"]
        command += ["-t", text, "-o", "/dev/stdout"]
    else:
        command = [_engine("espeak-ng"), "-v", voice.name, "-s", str(round(175 * voice.rate)), "--stdout"]
        if voice.pitch:
            command += ["-p", str(int(voice.pitch))]
        command += ["--", text]
    result = subprocess.run(command, capture_output=True, check=False)
    if result.returncode != 0 or len(result.stdout) < 44:
        raise ValueError(f"{voice.engine} could not speak {text!r}: {result.stderr.decode(errors='replace').strip()}")
    samples, rate = _read_wav(result.stdout)
    samples = resample(samples, rate, SAMPLE_RATE)
    if voice.engine == "espeak-ng":
        rng = np.random.default_rng(zlib.crc32(f"{voice}|{text}".encode()))
        samples = white_noise_at(samples, ESPEAK_FLOOR_DB, rng)
    return samples


def speak_timed(text: str, voice: Voice = PERSON_VOICE) -> tuple[np.ndarray, float]:
    """``speak`` and the CPU seconds it cost, the engine's subprocess included."""
    def cpu() -> float:
        own, child = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + child.ru_utime + child.ru_stime

    before = cpu()
    samples = speak(text, voice)
    return samples, cpu() - before


class SpeechCache:
    """Clean TTS samples per (text, voice): a voice says a text the same way every time, so each is synthesised
    once (the robot repeats its templates, the person its replies; noise and decoding vary, the speech does not)."""

    def __init__(self) -> None:
        self._audio: dict[tuple[str, Voice], np.ndarray] = {}

    def speak(self, text: str, voice: Voice) -> tuple[np.ndarray, float]:
        """Samples of ``voice`` saying ``text`` and the CPU seconds it cost (0 when it came from the cache)."""
        key = (text, voice)
        if key in self._audio:
            return self._audio[key], 0.0
        samples, cpu = speak_timed(text, voice)
        samples.setflags(write=False)  # shared by every caller: nobody may change it in place
        self._audio[key] = samples
        return samples, cpu

    def __len__(self) -> int:
        return len(self._audio)


def resample(samples: np.ndarray, rate: int, target: int) -> np.ndarray:
    """Band-limited resampling of int16 samples by FFT (one utterance at a time, so the cost is tiny)."""
    if rate == target or samples.size == 0:
        return samples.astype(np.int16, copy=False)
    n_out = int(round(samples.size * target / rate))
    spectrum = np.fft.rfft(samples.astype(np.float64))[: n_out // 2 + 1]
    out = np.fft.irfft(spectrum, n_out) * (n_out / samples.size)
    return np.clip(np.round(out), -32768, 32767).astype(np.int16)


def _read_wav(data: bytes) -> tuple[np.ndarray, int]:
    """Samples and rate of a 16-bit mono WAV held in memory (espeak-ng's streamed header has no true length)."""
    with wave.open(io.BytesIO(data)) as reader:
        if reader.getsampwidth() != 2 or reader.getnchannels() != 1:
            raise ValueError("TTS engine output is not 16-bit mono WAV")
        rate = reader.getframerate()
    # the data chunk runs to the end of the stream: read it directly, whatever the header's length says
    start = data.find(b"data") + 8
    body = data[start : start + (len(data) - start) // 2 * 2]
    return np.frombuffer(body, dtype="<i2").astype(np.int16), rate


def _engine(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise FileNotFoundError(f"TTS engine {name} not found: run scripts/setup.sh (apt-get install {name})")
    return path
