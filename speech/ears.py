"""The robot's ears for one reply: what the microphones take in and what of it reaches the recogniser.

Two kinds, one interface (`take(clean samples, snr_db, rng) -> EarTake`):
- `MonoEars`: one microphone, the noise mixed into the reply's own samples at the SNR (``ncbot.speech.noise``); the
  recogniser decodes exactly the reply. The training channel model was fitted this way.
- `ArrayEars`: Pepper's four head microphones in a simulated room (``ncbot.speech.room``, ``listening``) record a
  listening window, and the enhancement (``ncbot.speech.enhance``: beam, voice activity detection, post-filter)
  makes the recogniser's mono input.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ncbot.speech.enhance import Enhanced, Enhancement, Enhancer
from ncbot.speech.noise import add_noise
from ncbot.speech.room import Room


@dataclass(frozen=True)
class EarTake:
    """What the recogniser decodes (int16 mono), what the microphones took in ((C, n) int16; C = 1 for one
    microphone), the SNR (None: no noise) and, for the array, what the enhancement did and how far its beam was
    from the person's true direction (degrees; None without a beam: a figure for the logs, the robot never reads it)."""

    samples: np.ndarray
    channels: np.ndarray
    snr_db: float | None
    enhanced: Enhanced | None = None
    beam_error_deg: float | None = None


class MonoEars:
    """One microphone: `kind` noise (white, or babble from `babble_pool`) mixed into the reply at the SNR."""

    def __init__(self, kind: str = "babble", babble_pool: Sequence[np.ndarray] = ()) -> None:
        self.kind, self.babble_pool = kind, list(babble_pool)

    def take(self, samples: np.ndarray, snr_db: float | None, rng: np.random.Generator) -> EarTake:
        noisy = add_noise(samples, self.kind, snr_db, rng, self.babble_pool)
        return EarTake(noisy, noisy[None, :], snr_db)


class ArrayEars:
    """Pepper's array in `room`: `kind` noise (babble from the room's talkers saying `babble_pool`, or a diffuse
    field), then `enhancement`, its beam aimed at `camera_direction` (where the camera puts the person; None:
    the array's own estimate)."""

    def __init__(self, room: Room, kind: str, babble_pool: Sequence[np.ndarray] = (),
                 enhancement: Enhancement = Enhancement(), camera_direction: np.ndarray | None = None) -> None:
        from ncbot.speech.listening import ArrayRecorder

        self.room, self.kind, self.enhancement = room, kind, enhancement
        self.recorder = ArrayRecorder(room, kind, babble_pool)
        self.enhancer = Enhancer(enhancement, room.mics)
        self.camera_direction = camera_direction

    @property
    def person_direction(self) -> np.ndarray:
        """Where the person's mouth truly is, from the array (to judge the beam's aim; the robot never reads it)."""
        return self.room.direction_to(self.room.layout.mouth)

    def take(self, samples: np.ndarray, snr_db: float | None, rng: np.random.Generator) -> EarTake:
        from ncbot.speech.array import angle_between

        window = self.recorder.record(samples, snr_db, rng)
        enhanced = self.enhancer(window.channels, self.camera_direction)
        error = None if enhanced.direction is None else angle_between(enhanced.direction, self.person_direction)
        return EarTake(enhanced.samples, window.channels, snr_db, enhanced, error)
