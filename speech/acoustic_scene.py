"""How widely a room may vary as sound sees it (`AcousticRanges`), and one game's room drawn from them
(`draw_layout`): its size and reverberation, where the robot stands in it, where the person's mouth is, and
where the babble talkers stand (a bystander of the scene is one of them).

Why here and not with the scene's other conditions: the room is speech's (its layout is what
``ncbot.speech.room`` simulates); the robot's scene hands over what it knows (where the person stands across
the table, where bystanders are, the robot's head pose), so the same draw serves robot games and benches.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ncbot.speech.array import HOME_HEAD, HeadPose
from ncbot.speech.room import WALL_MARGIN, Point, RoomLayout

Range = tuple[float, float]
#: Where the person stands in the robot's frame when the scene says nothing else: across the 0.8 m table whose far
#: edge is 0.96 m ahead of the robot, mouth 0.25 m beyond it, on the sheet's centre line.
PERSON_X = 1.21
#: Talkers' mouth heights (m) and how far round from the person they stand at least (degrees, seen from the head).
TALKER_MOUTH = (1.3, 1.75)
TALKER_APART_DEG = 20.0
#: Where the camera takes the person's mouth to be (the robot sees the sheet, not the face): across the table at an
#: adult's mouth height.
ASSUMED_MOUTH_HEIGHT = 1.5
DRAWS = 200


@dataclass(frozen=True)
class AcousticRanges:
    """Room size ranges (length ahead of the robot, width, height; m), reverberation time RT60 (s), babble
    talkers drawn round the robot (how many) and their distance from the robot's head (m), talkers at fixed
    `talker_positions` besides them (robot frame, mouths; m), the person's mouth height (m) and sideways offset
    from the sheet's centre line (m)."""

    room_size: tuple[Range, Range, Range] = ((6.0, 7.0), (5.0, 6.0), (2.8, 3.0))
    rt60: Range = (0.3, 0.45)
    talkers: tuple[int, int] = (0, 0)
    talker_distance: Range = (1.5, 4.0)
    talker_positions: tuple[Point, ...] = ()
    mouth_height: Range = (1.45, 1.65)
    person_offset: Range = (-0.1, 0.1)

    def validate(self, name: str) -> None:
        """ValueError (one line, naming `name`'s field) for anything a room cannot be."""
        size = self.room_size
        if len(size) != 3 or any(len(r) != 2 or not 2.5 <= r[0] <= r[1] <= 60.0 for r in size):
            raise ValueError(f"conditions {name!r}: room_size must be three (low, high) ranges in metres within "
                             f"[2.5, 60] (length, width, height); got {size}")
        if size[0][0] < PERSON_X + 2.0 or size[1][0] < 3.0:
            raise ValueError(f"conditions {name!r}: room_size must leave room for the robot, table and person: "
                             f"length at least {PERSON_X + 2.0:g} m, width at least 3 m; got {size}")
        if not 0.1 <= self.rt60[0] <= self.rt60[1] <= 3.0:
            raise ValueError(f"conditions {name!r}: room_rt60 must be (low, high) seconds within [0.1, 3]; got {self.rt60}")
        if not 0 <= self.talkers[0] <= self.talkers[1] <= 12:
            raise ValueError(f"conditions {name!r}: speech_talkers must be (low, high) talkers within [0, 12]; "
                             f"got {self.talkers}")
        if not 0.5 <= self.talker_distance[0] <= self.talker_distance[1] <= 30.0:
            raise ValueError(f"conditions {name!r}: talker_distance must be (low, high) metres within [0.5, 30]; "
                             f"got {self.talker_distance}")
        if any(len(p) != 3 or not 0.3 <= p[2] <= 2.5 for p in self.talker_positions):
            raise ValueError(f"conditions {name!r}: talker_positions must be [x, y, mouth height] points in metres "
                             f"(robot frame, height 0.3-2.5); got {self.talker_positions}")
        if not 0.8 <= self.mouth_height[0] <= self.mouth_height[1] <= 2.0:
            raise ValueError(f"conditions {name!r}: person_mouth_height must be (low, high) metres within [0.8, 2]; "
                             f"got {self.mouth_height}")
        if not -0.5 <= self.person_offset[0] <= self.person_offset[1] <= 0.5:
            raise ValueError(f"conditions {name!r}: person_offset must be (low, high) metres within [-0.5, 0.5] "
                             f"(the person stays across the table); got {self.person_offset}")


def _uniform(rng: np.random.Generator, bounds: Range) -> float:
    return float(bounds[0]) if bounds[0] == bounds[1] else float(rng.uniform(bounds[0], bounds[1]))


def draw_layout(ranges: AcousticRanges, rng: np.random.Generator, head: HeadPose = HOME_HEAD,
                person_y: float = 0.0, bystanders: tuple[Point, ...] = ()) -> RoomLayout:
    """One game's room: the person across the table at `person_y` (the sheet's centre line) plus the drawn offset;
    `talkers` talkers, the scene's `bystanders` (mouths, robot frame) first, the rest drawn round the robot; then
    the fixed `talker_positions`. ValueError if a fixed position does not fit in the drawn room."""
    length, width, height = (_uniform(rng, r) for r in ranges.room_size)
    mouth = (PERSON_X, person_y + _uniform(rng, ranges.person_offset), _uniform(rng, ranges.mouth_height))
    rt60 = _uniform(rng, ranges.rt60)
    # the robot's origin: far enough from the back wall for its head, from the front wall for the person
    origin_x = _uniform(rng, (1.0, max(1.0, length - PERSON_X - 1.0)))
    origin_y = width / 2 + _uniform(rng, (-max(width / 2 - 1.5, 0.0), max(width / 2 - 1.5, 0.0)))
    count = int(rng.integers(ranges.talkers[0], ranges.talkers[1] + 1))
    talkers = list(bystanders)[:count]
    inside = _inside((length, width, height), (origin_x, origin_y))
    while len(talkers) < count:
        talkers.append(_draw_talker(ranges, rng, head, mouth, inside))
    talkers += [tuple(float(v) for v in p) for p in ranges.talker_positions]
    layout = RoomLayout((length, width, height), rt60, (origin_x, origin_y), mouth, tuple(talkers), head)
    layout.check()
    return layout


def _inside(size: Point, origin: tuple[float, float]):
    def test(point: np.ndarray) -> bool:
        room = np.asarray(point) + np.array([*origin, 0.0])
        return bool(np.all(room >= WALL_MARGIN) and np.all(room <= np.asarray(size) - WALL_MARGIN))
    return test


def _draw_talker(ranges: AcousticRanges, rng: np.random.Generator, head: HeadPose, mouth: Point, inside) -> Point:
    """A talker round the robot, at least `TALKER_APART_DEG` round from the person, inside the room (the distance
    shrinks towards the range's low end if the room is too small for the far end)."""
    centre = np.asarray(head.position)
    person = math.atan2(mouth[1] - centre[1], mouth[0] - centre[0])
    low, high = ranges.talker_distance
    for attempt in range(DRAWS):
        bearing = person + math.radians(_uniform(rng, (TALKER_APART_DEG, 360.0 - TALKER_APART_DEG)))
        distance = _uniform(rng, (low, high - (high - low) * attempt / DRAWS))
        point = np.array([centre[0] + distance * math.cos(bearing), centre[1] + distance * math.sin(bearing),
                          _uniform(rng, TALKER_MOUTH)])
        if inside(point):
            return tuple(float(v) for v in point)
    raise ValueError(f"no place for a talker {low:g}-{high:g} m from the robot inside the room; make talker_distance "
                     f"smaller or room_size larger")


def camera_direction(head: HeadPose, mics: np.ndarray, person_y: float) -> np.ndarray:
    """Where the robot's camera puts the person: across the table on the sheet's centre line (`person_y`, from the
    sheet the camera localised) at an adult's mouth height; a unit vector from the array's centre."""
    from ncbot.speech.array import array_centre, unit

    return unit(np.array([PERSON_X, person_y, ASSUMED_MOUTH_HEIGHT]) - array_centre(mics))
