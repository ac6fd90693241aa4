"""Where the reply is in a listening window: voice activity detection (WebRTC's VAD) and a rise above the window's
noise floor, so only the person's speech reaches the recogniser.

Why both: WebRTC's VAD tells speech from hum and hiss but calls babble speech too; the energy rise tells the
beam's target (louder once the beamformer points at it) from the talkers it suppresses, but not from a door
slam. A frame is the reply's when both say so; short blips are smoothed away; the reply is the run of such
frames (gaps under `MAX_GAP_S` bridged) holding the most energy, widened by `MARGIN_S` on both sides.
Nothing found is a valid result (None): the robot heard nothing and asks again.
"""
from __future__ import annotations

import numpy as np

from ncbot.speech import SAMPLE_RATE

FRAME = 480  # 30 ms at 16 kHz, one of the frame lengths WebRTC's VAD takes
AGGRESSIVENESS = 3  # WebRTC VAD mode 0-3: 3 calls the fewest noise frames speech
RISE_DB = 9.0  # a reply frame is this far above the window's noise floor
FLOOR_QUANTILE = 15.0  # percentile of the frames' energies taken as the noise floor
MAX_GAP_S = 0.3
MARGIN_S = 0.2
SMOOTH_FRAMES = 5


def speech_span(samples: np.ndarray, rise_db: float = RISE_DB, use_webrtc: bool = True) -> tuple[int, int] | None:
    """(start, stop) samples of the reply in mono `samples` (any scale), or None when no frame is speech."""
    from scipy.signal import medfilt

    samples = np.asarray(samples, dtype=np.float64)
    count = samples.size // FRAME
    if count < 3:
        return None
    frames = samples[: count * FRAME].reshape(count, FRAME)
    energy = 10.0 * np.log10(np.mean(frames ** 2, axis=1) + 1e-9)
    active = energy > np.percentile(energy, FLOOR_QUANTILE) + rise_db
    if use_webrtc:
        active &= webrtc_frames(samples)[:count]
    active = medfilt(active.astype(np.float64), SMOOTH_FRAMES) > 0.5
    if not active.any():
        return None
    index = np.flatnonzero(active)
    runs = np.split(index, np.flatnonzero(np.diff(index) > MAX_GAP_S * SAMPLE_RATE / FRAME) + 1)
    best = max(runs, key=lambda run: float(np.sum(10.0 ** (energy[run] / 10.0))))
    margin = int(MARGIN_S * SAMPLE_RATE)
    return max(int(best[0]) * FRAME - margin, 0), min((int(best[-1]) + 1) * FRAME + margin, samples.size)


def webrtc_frames(samples: np.ndarray) -> np.ndarray:
    """Per 30 ms frame, whether WebRTC's VAD calls it speech (the samples peak-normalised to int16 first)."""
    import webrtcvad

    vad = webrtcvad.Vad(AGGRESSIVENESS)
    peak = float(np.max(np.abs(samples))) or 1.0
    pcm = np.round(np.asarray(samples, dtype=np.float64) * (16000.0 / peak)).astype(np.int16)
    return np.array([vad.is_speech(pcm[i:i + FRAME].tobytes(), SAMPLE_RATE)
                     for i in range(0, pcm.size - FRAME + 1, FRAME)], dtype=bool)
