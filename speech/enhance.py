"""Enhancement between Pepper's four microphones and the recogniser: a beam towards the person, voice activity
detection that cuts the reply out of the listening window, and an optional single-channel post-filter.

Each part is a config option (`Enhancement`, written like ``mvdr+vad``) so its effect can be measured:
- beamformer ``none`` (the front-left microphone alone), ``ds`` (delay-and-sum: the four signals aligned on the
  person's direction and averaged) or ``mvdr`` (minimum variance distortionless response: per frequency, the
  weights that pass the person's direction unchanged and let the least noise through, from the noise's
  covariance between the microphones). MVDR learns the noise from the window's frames outside the reply (the
  voice activity detection run on the delay-and-sum beam: the turn-taking gap before the reply and the tail
  after it), `NOISE_MARGIN_S` away from it; with too few such frames, from the frames where the beam's direction
  holds the smallest share of the sound (`NOISE_SHARE`). (Chosen on the tuning set: the frames outside the reply
  hold no speech of the person's, so the beam never learns to cancel it.)
- steering ``camera`` (default): the beam aims where the robot's camera puts the person; when the robot has no
  such direction it falls back to the array's own estimate (``ncbot.speech.doa``, SRP-PHAT). ``doa`` always
  uses the array's estimate.
- ``vad``: only the reply (``ncbot.speech.vad``) reaches the recogniser; without it the whole window does.
- ``postfilter``: a Wiener gain per frequency from the noise frames' spectrum (floor `POSTFILTER_FLOOR`).
The recogniser gets int16 16 kHz mono, its loudest sample at half full scale (an automatic gain).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ncbot.speech import SAMPLE_RATE
from ncbot.speech.array import steering_vectors

BEAMFORMERS = ("none", "ds", "mvdr")
STEERINGS = ("camera", "doa")
#: 128 ms frames: long enough for a reverberant room's early reflections to stay within one frame (chosen on the
#: tuning set: 2048 heard fewer word errors than 1024 and 512 in babble at 3-10 dB)
NFFT, HOP = 2048, 1024
NOISE_SHARE = 0.4  # MVDR fallback: the share of frames, those least from the beam's direction, taken as noise
NOISE_MARGIN_S = 0.1  # MVDR: noise frames stay this far from the reply the VAD found
MIN_NOISE_FRAMES = 2
PRESENCE_BAND = (300.0, 3000.0)
LOADING = 1e-3  # diagonal loading of the noise covariance, relative to its mean power per frequency
POSTFILTER_FLOOR = 0.3  # the post-filter's smallest amplitude gain (-10 dB)


@dataclass(frozen=True)
class Enhancement:
    """What runs between the microphones and the recogniser (spec: ``beamformer[+vad][+postfilter][+doa]``)."""

    beamformer: str = "mvdr"
    vad: bool = True
    postfilter: bool = False
    steering: str = "camera"

    def __post_init__(self) -> None:
        if self.beamformer not in BEAMFORMERS:
            raise ValueError(f"beamformer must be one of {', '.join(BEAMFORMERS)}; got {self.beamformer!r}")
        if self.steering not in STEERINGS:
            raise ValueError(f"steering must be one of {', '.join(STEERINGS)}; got {self.steering!r}")

    @property
    def spec(self) -> str:
        parts = [self.beamformer] + ["vad"] * self.vad + ["postfilter"] * self.postfilter
        return "+".join(parts + (["doa"] if self.steering == "doa" else []))

    @classmethod
    def parse(cls, spec: str) -> Enhancement:
        """``mvdr+vad``, ``ds``, ``none+vad``, ``mvdr+vad+postfilter``, ``mvdr+vad+doa`` ... (ValueError if not)."""
        beamformer, *options = str(spec).strip().lower().split("+")
        unknown = sorted(set(options) - {"vad", "postfilter", "doa"})
        if beamformer not in BEAMFORMERS or unknown or len(set(options)) != len(options):
            raise ValueError(f"enhancement {spec!r} is not beamformer[+vad][+postfilter][+doa] with beamformer one "
                             f"of {', '.join(BEAMFORMERS)}, e.g. mvdr+vad")
        return cls(beamformer, "vad" in options, "postfilter" in options, "doa" if "doa" in options else "camera")


@dataclass(frozen=True)
class Enhanced:
    """The recogniser's input (int16 mono), where the beam pointed (unit vector, world frame; None without a
    beam), what aimed it (camera | doa | None), the reply's span in the window (None: VAD off or nothing found)
    and the CPU seconds the enhancement took."""

    samples: np.ndarray
    direction: np.ndarray | None
    steered_by: str | None
    span: tuple[int, int] | None
    cpu_s: float


class Enhancer:
    """Runs `config` on windows recorded at microphones `mics` (3, M)."""

    def __init__(self, config: Enhancement, mics: np.ndarray) -> None:
        self.config, self.mics = config, np.asarray(mics, dtype=np.float64)
        self.frequencies = np.fft.rfftfreq(NFFT, 1.0 / SAMPLE_RATE)

    def __call__(self, channels: np.ndarray, camera_direction: np.ndarray | None = None) -> Enhanced:
        """Enhance one window (M, n) int16; `camera_direction`: where the camera puts the person, if anywhere."""
        from scipy.signal import istft, stft

        from ncbot.speech.vad import speech_span

        started = time.process_time()
        config = self.config
        signals = np.asarray(channels, dtype=np.float64)
        _, _, spectra = stft(signals, fs=SAMPLE_RATE, nperseg=NFFT)  # (M, F, T)
        direction, steered_by = None, None
        if config.beamformer == "none":
            output, noise_frames = spectra[0], None
        else:
            direction, steered_by = self._aim(signals, camera_direction)
            steering = steering_vectors(self.mics, direction, self.frequencies)  # (F, M)
            output = np.einsum("fm,mft->ft", np.conj(steering / self.mics.shape[1]), spectra)  # delay-and-sum
            noise_frames = self._noise_frames(spectra, output, signals.shape[1])
            if config.beamformer == "mvdr":
                output = np.einsum("fm,mft->ft", np.conj(mvdr_weights(spectra[:, :, noise_frames], steering)), spectra)
        if config.postfilter:
            output = wiener(output, noise_frames)
        mono = istft(output, fs=SAMPLE_RATE, nperseg=NFFT)[1][: signals.shape[1]]
        span = speech_span(mono) if config.vad else None
        if config.vad:
            mono = mono[span[0]:span[1]] if span is not None else mono[:0]
        return Enhanced(to_int16(mono), direction, steered_by, span, time.process_time() - started)

    def _aim(self, signals: np.ndarray, camera_direction: np.ndarray | None) -> tuple[np.ndarray, str]:
        if self.config.steering == "camera" and camera_direction is not None:
            return np.asarray(camera_direction, dtype=np.float64), "camera"
        from ncbot.speech.doa import estimate_direction

        return estimate_direction(signals, self.mics), "doa"

    def _noise_frames(self, spectra: np.ndarray, beam: np.ndarray, length: int) -> np.ndarray:
        """The frames outside the reply the VAD finds on the delay-and-sum `beam`; with fewer than
        `MIN_NOISE_FRAMES` of those, the frames where the beam holds the smallest share of the sound."""
        from scipy.signal import istft

        from ncbot.speech.vad import speech_span

        span = speech_span(istft(beam, fs=SAMPLE_RATE, nperseg=NFFT)[1][:length])
        starts = np.arange(spectra.shape[2]) * HOP
        margin = NOISE_MARGIN_S * SAMPLE_RATE
        outside = np.ones(starts.size, dtype=bool) if span is None else (
            (starts < span[0] - margin) | (starts > span[1] + margin))
        if outside.sum() >= MIN_NOISE_FRAMES:
            return outside
        band = (self.frequencies >= PRESENCE_BAND[0]) & (self.frequencies <= PRESENCE_BAND[1])
        share = np.sum(np.abs(beam[band]) ** 2, axis=0) / np.maximum(
            np.sum(np.abs(spectra[:, band]) ** 2, axis=(0, 1)) / spectra.shape[0], 1e-12)
        frames = np.zeros(share.size, dtype=bool)
        frames[np.argsort(share)[:max(MIN_NOISE_FRAMES, int(NOISE_SHARE * share.size))]] = True
        return frames


def mvdr_weights(noise: np.ndarray, steering: np.ndarray) -> np.ndarray:
    """(F, M) MVDR weights from noise spectra (M, F, T) and steering vectors (F, M): R^-1 d / (d^H R^-1 d)."""
    covariance = np.einsum("mft,nft->fmn", noise, np.conj(noise)) / max(noise.shape[2], 1)
    power = np.real(np.trace(covariance, axis1=1, axis2=2)) / covariance.shape[1]
    covariance = covariance + (LOADING * power + 1e-9)[:, None, None] * np.eye(covariance.shape[1])
    solved = np.linalg.solve(covariance, steering[:, :, None])[:, :, 0]
    return solved / np.einsum("fm,fm->f", np.conj(steering), solved)[:, None]


def wiener(output: np.ndarray, noise_frames: np.ndarray | None) -> np.ndarray:
    """A Wiener gain per time-frequency bin, the noise spectrum from `noise_frames` (None: the quietest 40 %)."""
    power = np.abs(output) ** 2
    if noise_frames is None:
        energy = power.sum(axis=0)
        noise_frames = energy <= np.quantile(energy, NOISE_SHARE)
    noise = power[:, noise_frames].mean(axis=1, keepdims=True)
    gain = np.maximum(1.0 - noise / np.maximum(power, 1e-12), POSTFILTER_FLOOR ** 2)
    return output * np.sqrt(gain)


def to_int16(samples: np.ndarray) -> np.ndarray:
    """Mono float -> int16 with the loudest sample at half full scale (silence stays silence)."""
    samples = np.asarray(samples, dtype=np.float64)
    peak = float(np.max(np.abs(samples))) if samples.size else 0.0
    if peak == 0.0:
        return np.zeros(samples.size, dtype=np.int16)
    return np.round(samples * (16383.0 / peak)).astype(np.int16)
