"""Where a voice comes from, by the array alone: SRP-PHAT (pyroomacoustics) over the directions in front of the
robot, from the loudest frames of the listening window.

Why only the front: the person plays across the table, in front of the robot; talkers behind it are never the
one to listen to. Why the loudest frames: the reply is the window's loudest part when the person is the nearest
talker (near the robot, a voice is heard above babble from metres away); when a talker is louder the estimate
goes to them, which is why the camera's direction is preferred whenever the robot has one.
"""
from __future__ import annotations

import numpy as np

from ncbot.speech import SAMPLE_RATE
from ncbot.speech.array import SPEED_OF_SOUND, array_centre

NFFT = 512
AZIMUTHS_DEG = np.arange(-75.0, 76.0, 2.0)  # around the robot's heading (+x)
#: Pepper's microphones lie in one nearly horizontal plane, so their delays say little about elevation: the
#: array estimates the azimuth, and the voice is taken to come from this elevation (a mouth about 0.3 m above
#: Pepper's head, 1.2 m away)
ELEVATION_DEG = 14.0
FREQUENCY_RANGE = (300.0, 3500.0)
LOUDEST_FRAMES = 0.3  # share of the window's frames used: the loudest
METHODS = ("SRP", "MUSIC")


def estimate_direction(channels: np.ndarray, mics: np.ndarray, method: str = "SRP") -> np.ndarray:
    """Unit vector (world frame, from the array's centre) towards the loudest voice in front, from (M, n) signals
    at microphones `mics` (3, M)."""
    import pyroomacoustics as pra
    from scipy.signal import stft

    if method not in METHODS:
        raise ValueError(f"unknown direction-of-arrival method {method!r}; methods: {', '.join(METHODS)}")
    _, _, spectra = stft(np.asarray(channels, dtype=np.float64), fs=SAMPLE_RATE, nperseg=NFFT)
    power = np.sum(np.abs(spectra) ** 2, axis=(0, 1))
    loudest = power >= np.quantile(power, 1.0 - LOUDEST_FRAMES)
    relative = np.asarray(mics, dtype=np.float64) - array_centre(mics)[:, None]
    doa = pra.doa.algorithms[method](relative[:2], SAMPLE_RATE, NFFT, c=SPEED_OF_SOUND, num_src=1, dim=2,
                                     azimuth=np.radians(AZIMUTHS_DEG))
    doa.locate_sources(spectra[:, :, loudest], freq_range=list(FREQUENCY_RANGE))
    azimuth, elevation = float(doa.azimuth_recon[0]), np.radians(ELEVATION_DEG)
    return np.array([np.cos(azimuth) * np.cos(elevation), np.sin(azimuth) * np.cos(elevation), np.sin(elevation)])
