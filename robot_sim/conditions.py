"""The field's conditions for the robot's scene: presets as typed ranges, and one game's values drawn from a seed.

The paper's robot was tested in a lab and then in an atrium with other light, other backgrounds and people
standing by. `ConditionRanges` says how widely each property of the scene may vary (light, surfaces, clutter,
the sheet's pose and tint, pen, camera, a bystander); `sample_conditions(ranges, seed)` draws one game's
`SceneConditions` from them, so one seed always gives the same scene. `lab` has no ranges at all: it is the
scene the robot was built in, unchanged (the robot tests and figures rely on it). A YAML file can override any
field of a preset (`base: office` plus the fields to change).
"""
from __future__ import annotations

import dataclasses
import math
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.robot_sim.scene_conditions import (LAB_INK_BGR, LAB_SKIN, LAB_SLEEVE, CameraEffects, Light, Prop, Range,
                                        SceneConditions, kelvin_to_rgb)
from ncbot.robot_sim.sheet_shape import sample_sheet_shape

PRESETS_NAMES = ("lab", "office", "atrium", "random")
CLUTTER_KINDS = ("cup", "phone", "pen", "scrap", "sheet")
TABLE_TEXTURES = ("plain", "wood", "laminate", "linen")
FLOOR_TEXTURES = ("plain", "carpet", "tiles", "stone")
WALL_TEXTURES = ("none", "paint", "brick", "panels")

#: Pens people bring (BGR): blue, black, dark blue, red, green, purple.
PEN_INKS_BGR = ((120, 40, 20), (30, 30, 30), (90, 30, 10), (40, 40, 170), (50, 110, 30), (110, 40, 90))
#: Skin tones (RGB, linear-ish base colours) from light to dark.
SKIN_TONES = ((0.92, 0.76, 0.66), (0.87, 0.68, 0.56), (0.78, 0.57, 0.43), (0.62, 0.43, 0.30), (0.45, 0.30, 0.20),
              (0.32, 0.21, 0.14))


@dataclass(frozen=True)
class ConditionRanges:
    """How much each property of the scene may vary; (lo, hi) ranges are sampled uniformly per game."""

    name: str = "lab"
    #: Scale of every light's intensity (1 = the lab's).
    light_intensity: Range = (1.0, 1.0)
    #: Colour temperature of the main light (K); None keeps the lab's neutral lights.
    colour_temperature: Range | None = None
    #: Colour temperature of the extra lamps (K).
    lamp_temperature: Range = (2700.0, 3300.0)
    #: Elevation and azimuth of the main (directional) light, degrees; it casts shadows when `shadows`.
    light_elevation: Range = (55.0, 75.0)
    light_azimuth: Range = (-180.0, 180.0)
    shadows: bool = False
    #: Extra point/spot lamps around the table (how many, and their intensity relative to the main light).
    extra_lights: tuple[int, int] = (0, 0)
    lamp_intensity: Range = (0.2, 0.5)
    #: Ambient light as a fraction of the main light.
    ambient: Range = (0.45, 0.45)
    #: Slow drift of the main light per frame (clouds over an atrium): amplitude (fraction) and period (s).
    light_drift: Range = (0.0, 0.0)
    light_drift_period: Range = (60.0, 180.0)
    table_textures: tuple[str, ...] = ("plain",)
    floor_textures: tuple[str, ...] = ("plain",)
    wall_textures: tuple[str, ...] = ("none",)
    #: Objects on the table around the sheet (how many), from these kinds.
    clutter: tuple[int, int] = (0, 0)
    clutter_kinds: tuple[str, ...] = ("cup", "phone", "pen", "scrap")
    second_sheet_probability: float = 0.0
    #: The sheet's pose on the table: yaw (degrees) and offset (m) from where it is laid in the lab.
    sheet_yaw: Range = (0.0, 0.0)
    sheet_offset: Range = (0.0, 0.0)
    #: Paper tint: how far from white the paper is (0 = white), in any warm/cool/grey direction.
    paper_tint: Range = (0.0, 0.0)
    #: Pens the person may bring (BGR inks); the first one is the lab's.
    pen_inks: tuple[tuple[int, int, int], ...] = (LAB_INK_BGR,)
    skin_tones: tuple[tuple[float, float, float], ...] = (LAB_SKIN,)
    vary_sleeve: bool = False
    #: Camera: exposure gain, how much of the light's colour cast auto white balance removes (1 = all),
    #: sensor noise (std of gray levels at mid grey), blur length in pixels per frame, JPEG quality.
    exposure: Range = (1.0, 1.0)
    white_balance: Range = (1.0, 1.0)
    noise: Range = (0.0, 0.0)
    blur_probability: float = 0.0
    blur_px: Range = (0.0, 0.0)
    jpeg_quality: tuple[int, int] | None = None
    vignette: Range = (0.0, 0.0)
    #: A second person standing by: present in a game with this probability; per frame their arm enters the
    #: view with `bystander_arm_probability` and stays a few frames.
    bystander_probability: float = 0.0
    bystander_arm_probability: float = 0.0
    #: What the robot hears behind the person's voice (speech.noise; `ncbot robot play --speech real`): noise
    #: kinds (one drawn per game) and the SNR range in dB (drawn per utterance); None = a quiet room, clean.
    speech_noise: tuple[str, ...] = ("babble",)
    speech_snr_db: Range | None = None
    #: The room as sound sees it (`ncbot.speech.acoustic_scene`; heard through Pepper's four head microphones with
    #: `ears: array`, where `speech_snr_db` is the SNR at the array): size ranges (length ahead of the robot, width,
    #: height; m) and reverberation time RT60 (s), drawn per game.
    room_size: tuple[Range, Range, Range] = ((6.0, 7.0), (5.0, 6.0), (2.8, 3.0))
    room_rt60: Range = (0.3, 0.45)
    #: Babble talkers round the robot (how many, drawn per game; a bystander of the scene is one of them), their
    #: distance from the robot's head (m), and talkers at fixed places besides them ([x, y, mouth height], robot
    #: frame, m). Diffuse noise (`white`) has no place: it fills the room.
    speech_talkers: tuple[int, int] = (0, 0)
    talker_distance: Range = (1.5, 4.0)
    talker_positions: tuple[tuple[float, float, float], ...] = ()
    #: The person across the table: mouth height (m) and sideways offset from the sheet's centre line (m).
    person_mouth_height: Range = (1.45, 1.65)
    person_offset: Range = (-0.1, 0.1)
    #: The sheet is not flat (drawn apart from the rest, see `sample_sheet_shape`): a curl lifts one edge
    #: (height in m at that edge), a fold left a crease across the sheet that tents it (crease height in m).
    curl_probability: float = 0.0
    curl_height: Range = (0.0, 0.0)
    fold_probability: float = 0.0
    fold_height: Range = (0.0, 0.0)
    #: Auto exposure (`sample_auto_exposure`): how fast the camera's gain follows the frame's metered
    #: brightness (fraction of the way per frame in log gain; 0 = a fixed exposure) and the mean grey it aims at.
    auto_exposure_rate: Range = (0.0, 0.0)
    auto_exposure_target: Range = (0.45, 0.45)
    #: The simulated person's handwriting (`ncbot.vision.strokes.STYLES`; one drawn per game from the game's seed):
    #: "pen" and "hasty" are what the reader was trained on, "marker" its tuning style, "sketch" and "hershey" held
    #: out; a person writing in a held-out style is someone whose hand the reader never saw.
    handwriting: tuple[str, ...] = ("pen",)

    def acoustics(self):
        """The room's ranges as `ncbot.speech.acoustic_scene.AcousticRanges`."""
        from ncbot.speech.acoustic_scene import AcousticRanges

        return AcousticRanges(self.room_size, self.room_rt60, self.speech_talkers, self.talker_distance,
                              self.talker_positions, self.person_mouth_height, self.person_offset)

    def validate(self) -> None:
        for item in dataclasses.fields(self):
            value = getattr(self, item.name)
            if isinstance(value, tuple) and len(value) == 2 and all(isinstance(v, (int, float)) for v in value):
                if value[0] > value[1]:
                    raise ValueError(f"conditions {self.name!r}: {item.name} range must be (low, high); got {value}")
        for name in ("second_sheet_probability", "blur_probability", "bystander_probability", "bystander_arm_probability",
                     "curl_probability", "fold_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"conditions {self.name!r}: {name} must be in [0, 1]; got {getattr(self, name)}")
        for name, allowed in (("table_textures", TABLE_TEXTURES), ("floor_textures", FLOOR_TEXTURES),
                              ("wall_textures", WALL_TEXTURES), ("clutter_kinds", CLUTTER_KINDS)):
            bad = [v for v in getattr(self, name) if v not in allowed]
            if bad or not getattr(self, name):
                raise ValueError(f"conditions {self.name!r}: {name} must be a non-empty list of {', '.join(allowed)}; got {list(getattr(self, name))}")
        if abs(self.sheet_yaw[0]) > 30 or abs(self.sheet_yaw[1]) > 30 or self.sheet_offset[1] > 0.05:
            raise ValueError(f"conditions {self.name!r}: the sheet may turn at most 30 degrees and move at most 0.05 m "
                             f"(the robot must still reach it); got yaw {self.sheet_yaw}, offset {self.sheet_offset}")
        from ncbot.speech.noise import NOISE_KINDS

        if not self.speech_noise or any(kind not in NOISE_KINDS for kind in self.speech_noise):
            raise ValueError(f"conditions {self.name!r}: speech_noise must be a non-empty list of {', '.join(NOISE_KINDS)}; "
                             f"got {list(self.speech_noise)}")
        if self.speech_snr_db is not None and not (len(self.speech_snr_db) == 2 and -10 <= self.speech_snr_db[0] <= self.speech_snr_db[1] <= 60):
            raise ValueError(f"conditions {self.name!r}: speech_snr_db must be (low, high) dB within [-10, 60], or null "
                             f"for clean speech; got {self.speech_snr_db}")
        acoustics = self.acoustics()
        acoustics.validate(self.name)
        if ("babble" in self.speech_noise and self.speech_snr_db is not None and acoustics.talkers[1] == 0
                and not acoustics.talker_positions):
            raise ValueError(f"conditions {self.name!r}: babble noise needs talkers in the room: speech_talkers must "
                             f"allow at least one (or give talker_positions); got {self.speech_talkers}")
        if min(self.curl_height[0], self.fold_height[0]) < 0 or max(self.curl_height[1], self.fold_height[1]) > 0.03:
            raise ValueError(f"conditions {self.name!r}: curl_height and fold_height must lie in [0, 0.03] m (a sheet on a "
                             f"table, not a roll); got curl {self.curl_height}, fold {self.fold_height}")
        if not (0.0 <= self.auto_exposure_rate[0] and self.auto_exposure_rate[1] <= 1.0
                and 0.05 <= self.auto_exposure_target[0] and self.auto_exposure_target[1] <= 0.95):
            raise ValueError(f"conditions {self.name!r}: auto_exposure_rate must lie in [0, 1] and auto_exposure_target in "
                             f"[0.05, 0.95]; got {self.auto_exposure_rate}, {self.auto_exposure_target}")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality[0] <= self.jpeg_quality[1] <= 100:
            raise ValueError(f"conditions {self.name!r}: jpeg_quality must be (low, high) in [1, 100]; got {self.jpeg_quality}")
        from ncbot.vision.strokes import STYLES

        if isinstance(self.handwriting, str) or not self.handwriting or any(s not in STYLES for s in self.handwriting):
            raise ValueError(f"conditions {self.name!r}: handwriting must be a non-empty list of {', '.join(STYLES)}; "
                             f"got {self.handwriting!r}")


PRESETS: dict[str, ConditionRanges] = {
    "lab": ConditionRanges(),
    # Fluorescent ceiling lights, a desk, a few things on it; the sheet roughly where the robot put it.
    "office": ConditionRanges(
        name="office", light_intensity=(0.8, 1.1), colour_temperature=(3800.0, 4800.0), lamp_temperature=(3500.0, 4500.0),
        light_elevation=(60.0, 85.0), shadows=True, extra_lights=(1, 3), lamp_intensity=(0.15, 0.35), ambient=(0.35, 0.5),
        table_textures=("wood", "laminate"), floor_textures=("carpet", "tiles"), wall_textures=("paint", "panels"),
        clutter=(1, 3), clutter_kinds=("cup", "phone", "pen", "scrap"), second_sheet_probability=0.15,
        sheet_yaw=(-10.0, 10.0), sheet_offset=(0.0, 0.015), paper_tint=(0.0, 0.03),
        pen_inks=PEN_INKS_BGR[:3], skin_tones=SKIN_TONES, vary_sleeve=True,
        exposure=(0.9, 1.1), white_balance=(0.85, 0.98), noise=(0.8, 2.0), blur_probability=0.1, blur_px=(0.0, 1.5),
        jpeg_quality=(85, 95), vignette=(0.0, 0.15),
        curl_probability=0.3, curl_height=(0.003, 0.008), fold_probability=0.1, fold_height=(0.002, 0.005),
        auto_exposure_rate=(0.3, 0.6), auto_exposure_target=(0.42, 0.5)),
    # The paper's field trial: sun through a glass roof (hard shadows, slow clouds), warm lamps, stone floor,
    # a busy table, the sheet wherever the last player left it, a cheap webcam, people standing by.
    "atrium": ConditionRanges(
        name="atrium", light_intensity=(0.55, 1.5), colour_temperature=(5000.0, 6800.0), lamp_temperature=(2700.0, 3200.0),
        light_elevation=(35.0, 70.0), shadows=True, extra_lights=(2, 4), lamp_intensity=(0.2, 0.5), ambient=(0.25, 0.45),
        light_drift=(0.0, 0.12), light_drift_period=(40.0, 120.0),
        table_textures=("wood", "laminate", "linen"), floor_textures=("stone", "tiles"), wall_textures=("brick", "panels"),
        clutter=(2, 6), clutter_kinds=CLUTTER_KINDS[:4], second_sheet_probability=0.5,
        sheet_yaw=(-25.0, 25.0), sheet_offset=(0.0, 0.03), paper_tint=(0.0, 0.08),
        pen_inks=PEN_INKS_BGR, skin_tones=SKIN_TONES, vary_sleeve=True,
        exposure=(0.75, 1.25), white_balance=(0.7, 0.95), noise=(2.0, 4.0), blur_probability=0.3, blur_px=(0.5, 3.0),
        jpeg_quality=(60, 85), vignette=(0.05, 0.3), bystander_probability=0.7, bystander_arm_probability=0.06,
        curl_probability=0.5, curl_height=(0.004, 0.012), fold_probability=0.3, fold_height=(0.003, 0.008),
        auto_exposure_rate=(0.2, 0.5), auto_exposure_target=(0.38, 0.52)),
    # Everything at once, each over its widest range: for robustness studies, not a place.
    "random": ConditionRanges(
        name="random", light_intensity=(0.45, 1.7), colour_temperature=(2600.0, 7500.0), lamp_temperature=(2600.0, 6500.0),
        light_elevation=(30.0, 85.0), shadows=True, extra_lights=(0, 4), lamp_intensity=(0.1, 0.6), ambient=(0.2, 0.55),
        light_drift=(0.0, 0.15), light_drift_period=(30.0, 150.0),
        table_textures=TABLE_TEXTURES, floor_textures=FLOOR_TEXTURES, wall_textures=WALL_TEXTURES,
        clutter=(0, 7), clutter_kinds=CLUTTER_KINDS[:4], second_sheet_probability=0.4,
        sheet_yaw=(-25.0, 25.0), sheet_offset=(0.0, 0.03), paper_tint=(0.0, 0.1),
        pen_inks=PEN_INKS_BGR, skin_tones=SKIN_TONES, vary_sleeve=True,
        exposure=(0.7, 1.3), white_balance=(0.6, 1.0), noise=(0.0, 5.0), blur_probability=0.35, blur_px=(0.0, 3.5),
        jpeg_quality=(50, 95), vignette=(0.0, 0.35), bystander_probability=0.5, bystander_arm_probability=0.08,
        curl_probability=0.5, curl_height=(0.0, 0.015), fold_probability=0.3, fold_height=(0.0, 0.01),
        auto_exposure_rate=(0.0, 0.7), auto_exposure_target=(0.35, 0.55)),
}

# What the robot hears behind the person (kept apart from the scene's fields above): the lab is quiet; an office
# has colleagues talking a few metres away; the atrium is a busy hall of talkers; random spans the channel
# model's fitted range (5-30 dB) in either kind. docs/speech.md gives the recogniser's figures at these levels.
for _name, _kinds, _snr in (("office", ("babble",), (20.0, 30.0)), ("atrium", ("babble",), (10.0, 20.0)),
                            ("random", ("white", "babble"), (5.0, 30.0))):
    PRESETS[_name] = dataclasses.replace(PRESETS[_name], speech_noise=_kinds, speech_snr_db=_snr)
# The rooms (docs/speech.md, "The room as sound sees it"): the lab is a small quiet room; an office a furnished room
# with two or three colleagues talking; the atrium a tall glass and stone hall, reverberant, with groups standing
# round (children among the players); random anything from a booth to a hall.
PRESETS["office"] = dataclasses.replace(
    PRESETS["office"], room_size=((7.0, 10.0), (6.0, 9.0), (2.7, 3.2)), room_rt60=(0.4, 0.7), speech_talkers=(2, 3),
    talker_distance=(2.0, 5.0), person_offset=(-0.3, 0.3))
PRESETS["atrium"] = dataclasses.replace(
    PRESETS["atrium"], room_size=((15.0, 25.0), (12.0, 20.0), (6.0, 10.0)), room_rt60=(1.0, 1.6),
    speech_talkers=(4, 8), talker_distance=(1.5, 6.0), person_mouth_height=(1.15, 1.65), person_offset=(-0.3, 0.3))
PRESETS["random"] = dataclasses.replace(
    PRESETS["random"], room_size=((4.0, 25.0), (4.0, 20.0), (2.6, 10.0)), room_rt60=(0.2, 1.6), speech_talkers=(1, 8),
    talker_distance=(1.2, 6.0), person_mouth_height=(1.15, 1.7), person_offset=(-0.3, 0.3))


def load_conditions(spec: str | Path) -> ConditionRanges:
    """A preset by name (lab, office, atrium, random) or a YAML file: `base: <preset>` plus fields to override."""
    text = str(spec)
    if text in PRESETS:
        return PRESETS[text]
    path = Path(text)
    if not path.is_file():
        raise FileNotFoundError(f"conditions {text!r} is neither a preset ({', '.join(PRESETS_NAMES)}) nor a YAML file")
    from ncbot.fileio.yaml_file import read_yaml

    data = read_yaml(path, "conditions file", "a YAML mapping: base: <preset> plus fields to override") or {}
    if not isinstance(data, dict):
        raise ValueError(f"conditions file {path} must hold a mapping of fields; got {type(data).__name__}")
    base = data.pop("base", "lab")
    if base not in PRESETS:
        raise ValueError(f"conditions file {path}: base must be one of {', '.join(PRESETS_NAMES)}; got {base!r}")
    known = {f.name: f for f in dataclasses.fields(ConditionRanges)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ValueError(f"conditions file {path}: unknown fields {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    values: dict[str, Any] = {"name": str(path)}
    for key, value in data.items():
        values[key] = _as_tuple(value)
    ranges = dataclasses.replace(PRESETS[base], **values)
    ranges.validate()
    return ranges


def _as_tuple(value: Any) -> Any:
    """YAML lists -> tuples (nested), so a file's ranges compare and hash like the presets'."""
    if isinstance(value, list):
        return tuple(_as_tuple(v) for v in value)
    return value


def _uniform(rng: np.random.Generator, bounds: Range) -> float:
    return float(bounds[0]) if bounds[0] == bounds[1] else float(rng.uniform(bounds[0], bounds[1]))


def _pick(rng: np.random.Generator, options: tuple) -> Any:
    return options[int(rng.integers(len(options)))]


def _scaled(colour: tuple[float, float, float], scale: float) -> tuple[float, float, float]:
    return tuple(float(c * scale) for c in colour)


def sample_conditions(ranges: ConditionRanges, seed: int, sheet_side: float = 0.22, sheet_centre: tuple[float, float] = (0.30, 0.0)) -> SceneConditions:
    """One game's scene drawn from `ranges` with `seed`; `lab` (no colour temperature, no variation) returns the lab."""
    if dataclasses.replace(ranges, name="lab", handwriting=PRESETS["lab"].handwriting) == PRESETS["lab"]:
        return SceneConditions(seed=seed)  # the lab (a YAML file may only change who writes on the sheet)
    ranges.validate()
    rng = np.random.default_rng([seed, zlib.crc32(ranges.name.encode())])  # presets differ at one seed
    intensity = _uniform(rng, ranges.light_intensity)
    main_rgb = kelvin_to_rgb(_uniform(rng, ranges.colour_temperature)) if ranges.colour_temperature else (1.0, 1.0, 0.96)
    elevation, azimuth = math.radians(_uniform(rng, ranges.light_elevation)), math.radians(_uniform(rng, ranges.light_azimuth))
    direction = (-math.cos(elevation) * math.cos(azimuth), -math.cos(elevation) * math.sin(azimuth), -math.sin(elevation))
    lights = [Light("directional", direction, _scaled(main_rgb, 1.1 * intensity), ranges.shadows)]
    lamps = int(rng.integers(ranges.extra_lights[0], ranges.extra_lights[1] + 1))
    for _ in range(lamps):
        colour = _scaled(kelvin_to_rgb(_uniform(rng, ranges.lamp_temperature)), intensity * _uniform(rng, ranges.lamp_intensity))
        position = (float(rng.uniform(-0.8, 1.6)), float(rng.uniform(-1.5, 1.5)), float(rng.uniform(1.8, 2.8)))
        if rng.random() < 0.5:
            lights.append(Light("point", position, _scaled(colour, 2.5)))
        else:
            target = (sheet_centre[0] + float(rng.uniform(-0.4, 0.4)), sheet_centre[1] + float(rng.uniform(-0.4, 0.4)), 0.75)
            aim = tuple(float(t - p) for t, p in zip(target, position))
            lights.append(Light("spot", position, _scaled(colour, 6.0), False, aim))
    ambient_rgb = np.mean([main_rgb] + [kelvin_to_rgb(_uniform(rng, ranges.lamp_temperature))] * min(lamps, 1), axis=0)
    ambient = _scaled(tuple(ambient_rgb), _uniform(rng, ranges.ambient) * intensity)
    # The camera's auto white balance removes part of the light's cast (the lights' summed colour).
    light_mix = np.sum([np.array(light.colour) for light in lights[:1]], axis=0) * 2.0 + np.array(ambient)
    light_mix = light_mix / light_mix.max()
    correction = _uniform(rng, ranges.white_balance)
    # (in display space: the renderer's output is sRGB-encoded, hence the 1/2.2)
    gain = (light_mix.max() / np.maximum(light_mix, 1e-3)) ** (correction / 2.2)
    gain = gain / gain.mean()
    camera = CameraEffects(exposure=_uniform(rng, ranges.exposure), white_balance_gain=tuple(float(g) for g in gain),
                           noise=_uniform(rng, ranges.noise), blur_probability=ranges.blur_probability,
                           blur_px=ranges.blur_px, vignette=_uniform(rng, ranges.vignette),
                           jpeg_quality=None if ranges.jpeg_quality is None else int(rng.integers(ranges.jpeg_quality[0], ranges.jpeg_quality[1] + 1)),
                           seed=int(rng.integers(2**31)))
    yaw = math.radians(_uniform(rng, ranges.sheet_yaw))
    # Away from the robot by at least what the turned sheet's near corner needs to stay on the table.
    turned = (sheet_side / 2) * (abs(math.cos(yaw)) + abs(math.sin(yaw)) - 1.0)
    offset = _uniform(rng, ranges.sheet_offset)
    sheet_offset = (turned + offset * float(rng.uniform(0.0, 1.0)), offset * float(rng.uniform(-1.0, 1.0)))
    tint_amount = _uniform(rng, ranges.paper_tint)
    tint_direction = _pick(rng, ((1.0, 0.97, 0.85), (0.9, 0.95, 1.0), (0.93, 0.93, 0.93), (1.0, 0.95, 0.9), (0.95, 1.0, 0.9)))
    paper = tuple(float(1.0 - tint_amount * (1.0 - c) / 0.15) for c in tint_direction)
    table_colour = _pick(rng, ((0.40, 0.26, 0.16), (0.55, 0.40, 0.26), (0.30, 0.20, 0.13), (0.62, 0.60, 0.56),
                               (0.22, 0.23, 0.25), (0.68, 0.55, 0.40)))
    floor_colour = _pick(rng, ((0.55, 0.56, 0.58), (0.35, 0.33, 0.30), (0.62, 0.58, 0.50), (0.25, 0.28, 0.35)))
    wall_colour = _pick(rng, ((0.85, 0.84, 0.80), (0.75, 0.80, 0.82), (0.70, 0.45, 0.35), (0.88, 0.85, 0.72)))
    sleeve = tuple(float(v) for v in rng.uniform(0.08, 0.85, 3)) if ranges.vary_sleeve else LAB_SLEEVE
    cx, cy = sheet_centre[0] + sheet_offset[0], sheet_centre[1] + sheet_offset[1]
    props = _sample_props(rng, ranges, sheet_side, (cx, cy), yaw)
    bystander = bool(rng.random() < ranges.bystander_probability)
    bystander_colours = (tuple(float(v) for v in rng.uniform(0.08, 0.85, 3)), _pick(rng, ranges.skin_tones))
    scene = SceneConditions(
        preset=ranges.name, ambient=ambient, lights=tuple(lights),
        light_drift=_uniform(rng, ranges.light_drift), light_drift_period=_uniform(rng, ranges.light_drift_period),
        light_drift_phase=float(rng.uniform(0, 2 * math.pi)),
        table_texture=_pick(rng, ranges.table_textures), floor_texture=_pick(rng, ranges.floor_textures),
        wall_texture=_pick(rng, ranges.wall_textures), table_colour=table_colour, floor_colour=floor_colour,
        wall_colour=wall_colour, texture_seed=int(rng.integers(2**31)), props=props, sheet_offset=sheet_offset,
        sheet_yaw=yaw, paper_colour=paper, ink_bgr=_pick(rng, ranges.pen_inks), skin=_pick(rng, ranges.skin_tones),
        sleeve=sleeve, camera=camera, bystander=bystander,
        bystander_arm_probability=ranges.bystander_arm_probability if bystander else 0.0,
        bystander_colours=bystander_colours, seed=seed)
    return _bend_and_meter(scene, ranges, seed)


def sample_handwriting(ranges: ConditionRanges, seed: int) -> str:
    """The person's handwriting in the game of `seed`, from its own generator (nothing else drawn changes)."""
    if len(ranges.handwriting) == 1:
        return ranges.handwriting[0]
    rng = np.random.default_rng([seed, zlib.crc32(ranges.name.encode()), 23])
    return ranges.handwriting[int(rng.integers(len(ranges.handwriting)))]


def _bend_and_meter(scene: SceneConditions, ranges: ConditionRanges, seed: int) -> SceneConditions:
    """Add the sheet's curl/fold and the camera's auto exposure, drawn from their own generator of the game's
    seed: every value drawn before them (and so every scene of an earlier run) stays as it was."""
    rng = np.random.default_rng([seed, zlib.crc32(ranges.name.encode()), 15])
    camera = dataclasses.replace(scene.camera, **sample_auto_exposure(rng, ranges))
    shape = sample_sheet_shape(rng, (ranges.curl_probability, ranges.curl_height), (ranges.fold_probability, ranges.fold_height))
    return dataclasses.replace(scene, sheet_shape=shape, camera=camera)


def sample_auto_exposure(rng: np.random.Generator, ranges: ConditionRanges) -> dict[str, float]:
    """One game's auto-exposure speed and target (fields of `CameraEffects`)."""
    return {"auto_exposure_rate": _uniform(rng, ranges.auto_exposure_rate),
            "exposure_target": _uniform(rng, ranges.auto_exposure_target)}


#: Footprint radius (m) of each prop kind, to keep them off the game sheet and each other.
PROP_RADIUS = {"cup": 0.045, "phone": 0.08, "pen": 0.075, "scrap": 0.05, "sheet": 0.16}


def _sample_props(rng: np.random.Generator, ranges: ConditionRanges, side: float, centre: tuple[float, float],
                  yaw: float) -> tuple[Prop, ...]:
    """Objects around the sheet (in the camera's view, off the sheet itself: they lie on the table, not on it)."""
    count = int(rng.integers(ranges.clutter[0], ranges.clutter[1] + 1))
    kinds = [_pick(rng, ranges.clutter_kinds) for _ in range(count)]
    if rng.random() < ranges.second_sheet_probability:
        kinds.insert(0, "sheet")
    colours = {"cup": ((0.9, 0.9, 0.88), (0.75, 0.15, 0.12), (0.15, 0.35, 0.65), (0.95, 0.8, 0.2), (0.2, 0.2, 0.2)),
               "phone": ((0.05, 0.05, 0.06), (0.85, 0.85, 0.87), (0.3, 0.35, 0.45)),
               "pen": ((0.1, 0.2, 0.7), (0.05, 0.05, 0.05), (0.8, 0.1, 0.1), (0.9, 0.9, 0.9)),
               "scrap": ((0.96, 0.96, 0.94), (0.98, 0.92, 0.45), (0.7, 0.85, 0.95), (0.95, 0.75, 0.8)),
               "sheet": ((0.97, 0.97, 0.96), (0.98, 0.96, 0.9))}
    placed: list[Prop] = []
    reach = side / 2 * math.sqrt(2)
    for kind in kinds:
        radius = PROP_RADIUS[kind]
        for _ in range(40):
            angle = float(rng.uniform(0, 2 * math.pi))
            distance = reach + radius + float(rng.uniform(0.01, 0.12))
            x, y = centre[0] + distance * math.cos(angle), centre[1] + distance * math.sin(angle)
            # on the table (its near edge at 0.16 m, far edge 0.96 m, half width 0.6 m) and not at its near edge
            if not (0.16 + radius <= x <= 0.9 and abs(y) <= 0.55):
                continue
            if all(math.hypot(x - p.x, y - p.y) > radius + PROP_RADIUS[p.kind] for p in placed):
                placed.append(Prop(kind, x, y, float(rng.uniform(-math.pi, math.pi)), _pick(rng, colours[kind]),
                                   float(rng.uniform(0.85, 1.15))))
                break
    return tuple(placed)
