"""One game's concrete scene: the lights, props, camera effects and sheet that `PepperScene` builds.

Why its own module: `ncbot.robot_sim.conditions` says how widely a scene may vary and draws one game from a seed; what
it draws (`SceneConditions`) is read by the scene, its dressing and the camera's post-processing, which need the
values and not the ranges. The defaults are the lab scene the robot was built in (kept bit-identical).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ncbot.robot_sim.sheet_shape import SheetShape

Range = tuple[float, float]

#: The lab scene as built before conditions existed (kept bit-identical).
LAB_AMBIENT = (0.45, 0.45, 0.45)
LAB_LIGHTS = (("directional", (0.4, 0.25, -1.0), (0.75, 0.75, 0.72)), ("point", (0.6, 0.4, 2.0), (0.6, 0.6, 0.6)))
LAB_SKIN = (0.87, 0.68, 0.56)
LAB_SLEEVE = (0.25, 0.32, 0.45)
LAB_INK_BGR = (120, 40, 20)   # a blue ballpoint


def kelvin_to_rgb(kelvin: float) -> tuple[float, float, float]:
    """Colour of a black body at `kelvin` as RGB in [0, 1], brightest channel 1 (Tanner Helland's fit)."""
    t = kelvin / 100.0
    r = 255.0 if t <= 66 else 329.698727446 * (t - 60) ** -0.1332047592
    g = 99.4708025861 * math.log(t) - 161.1195681661 if t <= 66 else 288.1221695283 * (t - 60) ** -0.0755148492
    b = 255.0 if t >= 66 else (0.0 if t <= 19 else 138.5177312231 * math.log(t - 10) - 305.0447927307)
    rgb = np.clip([r, g, b], 1.0, 255.0)
    return tuple(float(v) for v in rgb / rgb.max())


@dataclass(frozen=True)
class Light:
    """One light: kind (directional/point/spot), position or direction, RGB colour (intensity folded in)."""

    kind: str
    vector: tuple[float, float, float]
    colour: tuple[float, float, float]
    shadow: bool = False
    direction: tuple[float, float, float] | None = None   # of a spot lamp


@dataclass(frozen=True)
class Prop:
    """One object on the table: kind, centre (x, y) in the world, yaw, RGB colour, and a size scale."""

    kind: str
    x: float
    y: float
    yaw: float
    colour: tuple[float, float, float]
    scale: float = 1.0


@dataclass(frozen=True)
class CameraEffects:
    """The camera's post-processing for one game; the per-frame parts are drawn from `seed` frame by frame."""

    exposure: float = 1.0
    #: Per-channel gain of the (imperfect) auto white balance.
    white_balance_gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    noise: float = 0.0
    blur_probability: float = 0.0
    blur_px: Range = (0.0, 0.0)
    jpeg_quality: int | None = None
    vignette: float = 0.0
    seed: int = 0
    #: Auto exposure: per frame the gain moves this fraction of the way (in log) towards the gain that would
    #: put the metered (centre-weighted) mean grey at `exposure_target` x 255; 0 keeps `exposure` fixed.
    auto_exposure_rate: float = 0.0
    exposure_target: float = 0.45

    @property
    def identity(self) -> bool:
        return (self.exposure == 1.0 and self.white_balance_gain == (1.0, 1.0, 1.0) and self.noise == 0.0
                and self.blur_probability == 0.0 and self.jpeg_quality is None and self.vignette == 0.0
                and self.auto_exposure_rate == 0.0)


@dataclass(frozen=True)
class SceneConditions:
    """One game's concrete scene: what `PepperScene` builds and what its camera does to every frame."""

    preset: str = "lab"
    ambient: tuple[float, float, float] = LAB_AMBIENT
    lights: tuple[Light, ...] = tuple(Light(kind, vec, col) for kind, vec, col in LAB_LIGHTS)
    #: Main light drift: amplitude (fraction of its intensity) and period (simulated s), and its phase.
    light_drift: float = 0.0
    light_drift_period: float = 60.0
    light_drift_phase: float = 0.0
    table_texture: str = "plain"
    floor_texture: str = "plain"
    wall_texture: str = "none"
    #: RGB base colours of the surfaces (used by their textures too).
    table_colour: tuple[float, float, float] = (0.40, 0.26, 0.16)
    floor_colour: tuple[float, float, float] = (0.55, 0.56, 0.58)
    wall_colour: tuple[float, float, float] = (0.8, 0.8, 0.78)
    texture_seed: int = 0
    props: tuple[Prop, ...] = ()
    #: The sheet: offset (m, x away from the robot, y to its left) and yaw (rad) from the lab's pose; paper tint.
    sheet_offset: tuple[float, float] = (0.0, 0.0)
    sheet_yaw: float = 0.0
    paper_colour: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ink_bgr: tuple[int, int, int] = LAB_INK_BGR
    skin: tuple[float, float, float] = LAB_SKIN
    sleeve: tuple[float, float, float] = LAB_SLEEVE
    camera: CameraEffects = field(default_factory=CameraEffects)
    bystander: bool = False
    bystander_arm_probability: float = 0.0
    bystander_colours: tuple[tuple[float, float, float], tuple[float, float, float]] = ((0.3, 0.3, 0.3), LAB_SKIN)
    seed: int = 0
    sheet_shape: SheetShape = field(default_factory=lambda: SheetShape())

    def summary(self) -> dict[str, Any]:
        """The few values worth logging per game (JSON-friendly)."""
        main = self.lights[0]
        return {"preset": self.preset, "seed": self.seed, "main_light": [round(c, 3) for c in main.colour],
                "lights": len(self.lights), "shadows": any(light.shadow for light in self.lights),
                "surfaces": [self.table_texture, self.floor_texture, self.wall_texture],
                "props": [p.kind for p in self.props], "sheet_yaw_deg": round(math.degrees(self.sheet_yaw), 1),
                "sheet_offset_m": [round(v, 4) for v in self.sheet_offset],
                "paper": [round(c, 3) for c in self.paper_colour], "ink_bgr": list(self.ink_bgr),
                "exposure": round(self.camera.exposure, 3), "noise": round(self.camera.noise, 2),
                "jpeg_quality": self.camera.jpeg_quality, "bystander": self.bystander,
                "auto_exposure_rate": round(self.camera.auto_exposure_rate, 3), **self.sheet_shape.summary()}
