"""The room as sound sees it: a shoebox room (pyroomacoustics' image-source model) with the person's mouth, babble
talkers and Pepper's four head microphones in it, and the impulse responses from every mouth to every microphone.

Why impulse responses once per game: the positions stay put for a game, so the room is simulated once (about
0.1-3 CPU s, more for long reverberation) and each utterance is then a few FFT convolutions. The walls' absorption
comes from the wanted reverberation time by Sabine's formula and is then corrected until the simulated room's
own RT60 (Schroeder decay of the person-to-microphone response) is within 10 % of it: the image-source model
rings longer than Sabine predicts, so without the correction a "0.6 s" room measures about 0.9 s. A room too
large to be as dry as asked gets the driest walls (`DRIEST`) and rings as long as they give (`measured_rt60`).
Coordinates: the robot's world frame (x ahead of the robot's home, y left, z up, m); the robot's origin sits at
`RoomLayout.robot_origin` on the room's floor, so the room spans x in [-origin_x, length - origin_x].
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ncbot.speech import SAMPLE_RATE
from ncbot.speech.array import HOME_HEAD, HeadPose, array_centre, mic_positions, unit

Point = tuple[float, float, float]
WALL_MARGIN = 0.3  # m: no mouth or microphone closer to a wall than this
CALIBRATION_STEPS = 4
DRIEST = 0.99  # the most a wall may absorb: a room too large for the RT60 asked rings as long as this gives


@dataclass(frozen=True)
class RoomLayout:
    """One game's room: its size (length x, width y, height z, m), reverberation time (s), where the robot's origin
    stands on its floor (x, y in room coordinates), the person's mouth and the babble talkers' mouths (world
    frame), and the robot's head pose (which places the microphones)."""

    dimensions: Point
    rt60: float
    robot_origin: tuple[float, float]
    mouth: Point
    talkers: tuple[Point, ...] = ()
    head: HeadPose = field(default_factory=lambda: HOME_HEAD)

    def to_room(self, point: np.ndarray) -> np.ndarray:
        """World frame -> room coordinates."""
        return np.asarray(point, dtype=np.float64) + np.array([*self.robot_origin, 0.0])

    def check(self) -> None:
        """ValueError naming the first thing that does not fit in the room."""
        if not 0.1 <= self.rt60 <= 3.0:
            raise ValueError(f"room RT60 must be 0.1-3 s; got {self.rt60}")
        size = np.asarray(self.dimensions, dtype=np.float64)
        for name, point in (("the person's mouth", self.mouth), *((f"talker {i}", t) for i, t in enumerate(self.talkers)),
                            ("the robot's head", self.head.position)):
            inside = self.to_room(point)
            if np.any(inside < WALL_MARGIN) or np.any(inside > size - WALL_MARGIN):
                raise ValueError(f"{name} at {tuple(round(float(v), 2) for v in point)} m (robot frame) is not inside "
                                 f"the {size[0]:g} x {size[1]:g} x {size[2]:g} m room with {WALL_MARGIN} m to spare")


def sabine(rt60: float, dimensions: Point) -> tuple[float, int]:
    """Wall absorption (energy) for `rt60` by Sabine's formula, at most `DRIEST`, and the image-source order that
    reaches c * rt60 metres (pyroomacoustics' `inverse_sabine`, which refuses a room too large to be that dry)."""
    from itertools import combinations

    from ncbot.speech.array import SPEED_OF_SOUND

    volume = float(np.prod(dimensions))
    surface = 2.0 * sum(a * b for a, b in combinations(dimensions, 2))
    absorption = 24.0 * np.log(10.0) * volume / (SPEED_OF_SOUND * surface * rt60)
    reach = min(a * b / np.hypot(a, b) for a, b in combinations(dimensions, 2))
    return float(min(absorption, DRIEST)), int(np.ceil(SPEED_OF_SOUND * rt60 / reach - 1))


class Room:
    """The simulated room of one `RoomLayout`: `rirs[source][mic]` (source 0 the person, 1.. the talkers), the
    microphones' world positions `mics` (3, 4) and the RT60 the simulation measures (`measured_rt60`)."""

    def __init__(self, layout: RoomLayout, geometry_scale: float = 1.0) -> None:
        import pyroomacoustics as pra

        layout.check()
        self.layout = layout
        self.mics = mic_positions(layout.head, geometry_scale)
        sources = [layout.mouth, *layout.talkers]
        absorption, max_order = sabine(layout.rt60, layout.dimensions)
        measured = layout.rt60
        for _ in range(CALIBRATION_STEPS):  # one source, one microphone: a few % of the full simulation's cost
            measured = self._measured_rt60(pra, absorption, max_order, sources[0])
            if abs(measured - layout.rt60) <= 0.1 * layout.rt60:
                break
            absorption = float(np.clip(absorption * measured / layout.rt60, 0.01, DRIEST))
        self.absorption = absorption
        room = self._shoebox(pra, absorption, max_order)
        room.add_microphone_array(np.stack([layout.to_room(m) for m in self.mics.T], axis=1))
        for source in sources:
            room.add_source(layout.to_room(source))
        room.compute_rir()
        self.rirs = [[np.asarray(room.rir[m][s], dtype=np.float64) for m in range(self.mics.shape[1])]
                     for s in range(len(sources))]
        self.measured_rt60 = float(measured)
        self.rir_length = max(rir.size for per_source in self.rirs for rir in per_source)
        self._transfers: dict[int, np.ndarray] = {}

    def _shoebox(self, pra, absorption: float, max_order: int):
        return pra.ShoeBox(list(self.layout.dimensions), fs=SAMPLE_RATE, materials=pra.Material(absorption),
                           max_order=int(max_order))

    def _measured_rt60(self, pra, absorption: float, max_order: int, source: Point) -> float:
        room = self._shoebox(pra, absorption, max_order)
        room.add_microphone_array(self.layout.to_room(array_centre(self.mics))[:, None])
        room.add_source(self.layout.to_room(source))
        room.compute_rir()
        return float(pra.experimental.measure_rt60(np.asarray(room.rir[0][0]), fs=SAMPLE_RATE))

    def direction_to(self, point: np.ndarray) -> np.ndarray:
        """Unit vector from the array's centre to `point` (world frame)."""
        return unit(np.asarray(point, dtype=np.float64) - array_centre(self.mics))

    def at_microphones(self, samples: np.ndarray, source: int) -> np.ndarray:
        """(4, n + rir length - 1) float: `samples` said at `source` (0 the person) as each microphone hears it."""
        return self.heard_together({source: samples})

    def heard_together(self, said: dict[int, np.ndarray]) -> np.ndarray:
        """(4, longest + rir length - 1) float: what each microphone hears of every source saying its samples at
        once (one FFT per source, one inverse FFT per microphone: talkers cost little more than one)."""
        length = max(np.asarray(samples).size for samples in said.values()) + self.rir_length - 1
        size = 1 << (length - 1).bit_length()
        transfers = self._transfer(size)
        total = sum(np.fft.rfft(np.asarray(samples, dtype=np.float64), size)[None, :] * transfers[source]
                    for source, samples in said.items())
        return np.fft.irfft(total, size, axis=1)[:, :length]

    def _transfer(self, size: int) -> np.ndarray:
        """(sources, mics, size // 2 + 1) spectra of the impulse responses, kept for the last two FFT sizes."""
        if size not in self._transfers:
            if len(self._transfers) >= 2:
                self._transfers.pop(next(iter(self._transfers)))
            self._transfers[size] = np.stack([np.stack([np.fft.rfft(rir, size) for rir in per_source])
                                              for per_source in self.rirs])
        return self._transfers[size]
