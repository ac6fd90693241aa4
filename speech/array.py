"""Pepper's four head microphones: where they sit on the head, where a head pose puts them, and the steering
vectors a beamformer aims with.

Where the geometry comes from: Aldebaran / SoftBank Robotics' hardware documentation of Pepper (NAOqi 2.5,
"Pepper - Microphones") places four microphones on the top of the head, two at the front (left, right) and two
at the rear (left, right), and gives their coordinates in the Head frame. That table could not be consulted
where this model was built, so the coordinates below are an estimate of that layout: a horizontal rectangle
6.6 cm long (front to rear) and 6.8 cm wide, 0.209 m above the HeadPitch axis (Pepper stands 1.21 m tall, its
Head frame sits 0.99 m above the floor). Each coordinate is uncertain by about ±1.5 cm (`GEOMETRY_UNCERTAINTY_M`);
`bench/studies/array_wer.py --geometry-scale` measures what a smaller or larger array changes.
The Head frame is Pepper's: x forward, y left, z up, origin on the HeadPitch axis; positive pitch looks down.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SPEED_OF_SOUND = 343.0  # m/s, air at about 20 degrees C
MIC_NAMES = ("front_left", "front_right", "rear_left", "rear_right")
#: The four microphones in the Head frame (m), rows in `MIC_NAMES` order.
HEAD_MICS = np.array([[0.033, 0.034, 0.209], [0.033, -0.034, 0.209], [-0.033, 0.034, 0.209], [-0.033, -0.034, 0.209]])
GEOMETRY_UNCERTAINTY_M = 0.015


@dataclass(frozen=True)
class HeadPose:
    """Where Pepper's Head frame is in the robot's world frame (x ahead of the robot's home, y left, z up, m) and
    how it is turned (yaw about z, pitch about the head's y axis, radians, positive pitch looks down)."""

    position: tuple[float, float, float]
    yaw: float = 0.0
    pitch: float = 0.0

    def rotation(self) -> np.ndarray:
        """Head frame -> world frame rotation (yaw, then pitch about the turned y axis)."""
        cy, sy, cp, sp = math.cos(self.yaw), math.sin(self.yaw), math.cos(self.pitch), math.sin(self.pitch)
        yaw = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        pitch = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
        return yaw @ pitch


#: The head at the robot's home posture looking at the sheet (`ncbot.robot_sim.scene.PepperScene`, lab scene):
#: for hearing without the simulator (benches); a game passes its scene's own head pose.
HOME_HEAD = HeadPose((-0.038, 0.0, 0.990), 0.0, 0.1786)


def mic_positions(head: HeadPose = HOME_HEAD, scale: float = 1.0) -> np.ndarray:
    """(3, 4) world positions of the microphones (columns in `MIC_NAMES` order); `scale` shrinks or grows the
    array about its centre (a sensitivity check of the geometry, 1 = as modelled)."""
    local = HEAD_MICS.copy()
    centre = local.mean(axis=0)
    local = centre + scale * (local - centre)
    return (np.asarray(head.position, dtype=np.float64)[:, None] + head.rotation() @ local.T)


def array_centre(mics: np.ndarray) -> np.ndarray:
    """The centre of an array given as (3, M) positions."""
    return np.asarray(mics, dtype=np.float64).mean(axis=1)


def unit(vector: np.ndarray) -> np.ndarray:
    vector = np.asarray(vector, dtype=np.float64)
    norm = float(np.linalg.norm(vector))
    if norm == 0.0:
        raise ValueError("a direction needs a non-zero vector")
    return vector / norm


def steering_vectors(mics: np.ndarray, direction: np.ndarray, frequencies: np.ndarray) -> np.ndarray:
    """(F, M) far-field steering vectors for a plane wave arriving from unit `direction` (pointing from the array
    towards the source): a microphone nearer the source hears the wave earlier, by (m - centre) . direction / c."""
    offsets = np.asarray(mics, dtype=np.float64).T - array_centre(mics)
    lead = offsets @ unit(direction) / SPEED_OF_SOUND  # seconds each microphone hears the wave before the centre
    return np.exp(2j * np.pi * np.asarray(frequencies)[:, None] * lead[None, :])


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees between two directions."""
    return math.degrees(math.acos(float(np.clip(unit(a) @ unit(b), -1.0, 1.0))))
