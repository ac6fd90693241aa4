"""Robot motion in simulated time: joint trajectories, base driving, gestures and drawing with the pen.

Every motion advances physics at the control rate and, whenever `frame_period` of simulated time has passed,
renders the mouth camera and hands the frame to `on_frame(frame, t)` (the game loop logs it). Rendering is
the dominant cost, so the frame rate during robot motion is a knob (`frame_period`), not a constant.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ncbot.robot_sim.ik import PositionIK
from ncbot.robot_sim.pepper_model import ARM_JOINTS, TOOL_LINKS
from ncbot.robot_sim.sheet import MarkSpec

FrameCallback = Callable[[np.ndarray, float], None]

#: Where the right pen tip is comfortable, relative to the base centre (x ahead, y left), in metres.
REACH_OFFSET = np.array([0.28, -0.14])

# Gestures for the paper's 7 robot commands: keyframes (seconds from start, joint offsets from home).
# They are the "built-in" animations of the real robot, in joint space; every one ends back at home.
_WAVE = [(0.5, {"RShoulderPitch": -2.3, "RShoulderRoll": -0.35, "RElbowYaw": 0.4, "RElbowRoll": 0.9}),
         (0.8, {"RShoulderPitch": -2.3, "RShoulderRoll": -0.35, "RElbowYaw": 0.4, "RElbowRoll": 0.3}),
         (1.1, {"RShoulderPitch": -2.3, "RShoulderRoll": -0.35, "RElbowYaw": 0.4, "RElbowRoll": 0.9}),
         (1.4, {"RShoulderPitch": -2.3, "RShoulderRoll": -0.35, "RElbowYaw": 0.4, "RElbowRoll": 0.3})]
GESTURES: dict[str, list[tuple[float, dict[str, float]]]] = {
    "hello": _WAVE,
    "please": [(0.6, {"LShoulderPitch": -0.75, "RShoulderPitch": -0.75, "LWristYaw": -1.3, "RWristYaw": 1.3,
                      "LElbowRoll": -0.2, "RElbowRoll": 0.2, "LHand": 0.4, "RHand": 0.4}),
               (1.2, {"LShoulderPitch": -0.75, "RShoulderPitch": -0.75, "LWristYaw": -1.3, "RWristYaw": 1.3,
                      "LElbowRoll": -0.2, "RElbowRoll": 0.2, "HeadPitch": -0.15})],
    "happy": [(0.5, {"LShoulderPitch": -2.6, "RShoulderPitch": -2.6, "LShoulderRoll": 0.5, "RShoulderRoll": -0.5}),
              (0.8, {"LShoulderPitch": -2.4, "RShoulderPitch": -2.4, "LShoulderRoll": 0.3, "RShoulderRoll": -0.3,
                     "HeadPitch": -0.2}),
              (1.1, {"LShoulderPitch": -2.6, "RShoulderPitch": -2.6, "LShoulderRoll": 0.5, "RShoulderRoll": -0.5})],
    "no": [(0.3, {"HeadYaw": 0.4}), (0.6, {"HeadYaw": -0.4}), (0.9, {"HeadYaw": 0.4}), (1.2, {"HeadYaw": 0.0})],
    "think": [(0.6, {"RShoulderPitch": -1.35, "RShoulderRoll": 0.0, "RElbowYaw": 0.3, "RElbowRoll": 1.1,
                     "HeadYaw": 0.25, "HeadPitch": -0.2}),
              (1.4, {"RShoulderPitch": -1.35, "RShoulderRoll": 0.0, "RElbowYaw": 0.3, "RElbowRoll": 1.1,
                     "HeadYaw": 0.25, "HeadPitch": -0.2})],
    "asr": [(0.4, {"HeadPitch": -0.45, "HeadYaw": 0.1}), (1.0, {"HeadPitch": -0.45, "HeadYaw": 0.1})],
    "read": [(0.4, {"HeadPitch": 0.25, "HeadYaw": 0.15}), (0.9, {"HeadPitch": 0.25, "HeadYaw": -0.15}), (1.2, {"HeadPitch": 0.0})],
}
GESTURE_NAMES = tuple(GESTURES)


def _waypoints(points: np.ndarray, spacing: float = 6.0) -> np.ndarray:
    """Keep pen waypoints about `spacing` canvas pixels apart (plus both ends): IK per point, not per pixel."""
    keep = [0]
    travelled = 0.0
    for i in range(1, len(points)):
        travelled += float(np.linalg.norm(points[i] - points[i - 1]))
        if travelled >= spacing:
            keep.append(i)
            travelled = 0.0
    if keep[-1] != len(points) - 1:
        keep.append(len(points) - 1)
    return points[keep]


def min_jerk(s: float) -> float:
    """Minimum-jerk time scaling: smooth start and stop, as arm motions of people (and Pepper's) are."""
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


@dataclass
class MotionStats:
    sim_seconds: float = 0.0
    frames: int = 0
    ik_failures: int = 0


class RobotMotion:
    """Executes motions on a `PepperScene`; `on_frame` receives rendered frames during them."""

    def __init__(self, scene, on_frame: FrameCallback | None = None, frame_period: float = 0.25,
                 control_hz: float = 50.0, arm: str = "R") -> None:
        if frame_period <= 0:
            raise ValueError(f"frame_period must be positive seconds; got {frame_period}")
        if arm not in TOOL_LINKS:
            raise ValueError(f"arm must be 'L' or 'R'; got {arm!r}")
        self.scene = scene
        self.on_frame = on_frame
        self.frame_period = frame_period
        self.control_dt = 1.0 / control_hz
        self.arm = arm
        self.ik = PositionIK(scene, TOOL_LINKS[arm], ARM_JOINTS[arm])
        self.stats = MotionStats()
        self._next_frame = scene.time
        self.targets = scene.home.copy()
        #: Where the base returns after each move (the pose it had when this controller was made).
        self.home_base = scene.base_pose()

    # ------------------------------------------------------------ time
    def tick(self, base_goal: np.ndarray | None = None, base_velocity: np.ndarray | None = None) -> None:
        """One control period: steer the base (if a goal is given), step physics, render if a frame is due.

        `base_velocity` is the goal's own velocity (feed-forward) when the goal moves along a path.
        """
        if base_goal is not None:
            self._steer_base(base_goal, base_velocity)
        self.scene.step(self.control_dt)
        self.stats.sim_seconds += self.control_dt
        if self.on_frame is not None and self.scene.time + 1e-9 >= self._next_frame:
            self._next_frame = self.scene.time + self.frame_period
            self.stats.frames += 1
            self.on_frame(self.scene.render(), self.scene.time)

    def wait(self, seconds: float) -> None:
        for _ in range(max(1, int(round(seconds / self.control_dt)))):
            self.tick()

    # ------------------------------------------------------------ joints
    def move_to(self, q_goal: np.ndarray, duration: float, base_goal: np.ndarray | None = None) -> None:
        """Minimum-jerk joint-space move of the drive targets from where they are now to `q_goal`."""
        start = self.targets.copy()
        goal = np.asarray(q_goal, dtype=np.float64)
        steps = max(1, int(round(duration / self.control_dt)))
        for k in range(1, steps + 1):
            self.targets = start + (goal - start) * min_jerk(k / steps)
            self.scene.set_joint_targets(self.targets)
            self.tick(base_goal)

    def settle(self, seconds: float = 0.2) -> None:
        self.wait(seconds)

    def gesture(self, name: str) -> None:
        """Play one of the 7 command gestures (hello, please, happy, no, think, asr, read), then go home."""
        if name not in GESTURES:
            raise ValueError(f"gesture {name!r} is unknown; expected one of {GESTURE_NAMES}")
        previous = 0.0
        base = self.scene.home.copy()
        for at, offsets in GESTURES[name]:
            q = base.copy()
            for joint, value in offsets.items():
                q[self.scene.joint_index[joint]] += value
            self.move_to(q, at - previous)
            previous = at
        self.go_home(0.5)

    def go_home(self, duration: float = 0.8) -> None:
        """Arms and head back to the rest posture (the base stays where it is)."""
        q = self.scene.home.copy()
        base_cols = [self.scene.joint_index[n] for n in ("base_x", "base_y", "base_yaw")]
        q[base_cols] = self.scene.qpos[base_cols]
        self.move_to(q, duration)

    # ------------------------------------------------------------ base
    def _steer_base(self, goal: np.ndarray, feed_forward: np.ndarray | None = None, gain: float = 6.0,
                    v_max: float = 0.35, w_max: float = 0.8) -> None:
        error = goal - self.scene.base_pose()
        error[2] = (error[2] + math.pi) % (2 * math.pi) - math.pi
        v = gain * error[:2] + (feed_forward[:2] if feed_forward is not None else 0.0)
        speed = np.linalg.norm(v)
        if speed > v_max:
            v *= v_max / speed
        self.scene.set_base_velocity(v[0], v[1], float(np.clip(gain * error[2], -w_max, w_max)))

    def drive_base_to(self, goal: np.ndarray, tolerance: float = 0.002, timeout: float = 8.0) -> float:
        """Drive the omni base to (x, y, yaw) with a velocity P-controller; returns the remaining error (m)."""
        goal = np.asarray(goal, dtype=np.float64)
        elapsed = 0.0
        while elapsed < timeout:
            if np.linalg.norm(goal[:2] - self.scene.base_pose()[:2]) < tolerance:
                break
            self.tick(goal)
            elapsed += self.control_dt
        self.scene.set_base_velocity(0.0, 0.0, 0.0)
        return float(np.linalg.norm(goal[:2] - self.scene.base_pose()[:2]))

    def base_goal_for(self, point: np.ndarray) -> np.ndarray:
        """Base pose (x, y, yaw=0) from which the pen reaches `point` comfortably."""
        return np.array([point[0] - REACH_OFFSET[0], point[1] - REACH_OFFSET[1], 0.0])

    # ------------------------------------------------------------ pen
    def reach(self, point: np.ndarray, duration: float) -> float:
        """Move the pen tip to a world point by IK; returns the IK's residual error (m)."""
        result = self.ik.solve(point, self._ik_seed())
        if not result.success:
            self.stats.ik_failures += 1
        goal = self.targets.copy()
        goal[self.ik.columns] = result.qpos[self.ik.columns]
        self.move_to(goal, duration)
        return result.error

    def _ik_seed(self) -> np.ndarray:
        q = self.scene.qpos.copy()
        q[self.ik.columns] = self.targets[self.ik.columns]
        return q

    def trace(self, points: np.ndarray, speed: float = 0.15, on_progress: Callable[[float], None] | None = None) -> float:
        """Move the pen tip through world `points` at `speed` m/s; reports the traced fraction of the path."""
        seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
        total = float(seg.sum()) or 1.0
        done = 0.0
        worst = 0.0
        for i, length in enumerate(seg):
            result = self.ik.solve(points[i + 1], self._ik_seed())
            worst = max(worst, result.error)
            goal = self.targets.copy()
            goal[self.ik.columns] = result.qpos[self.ik.columns]
            self.targets = goal
            self.scene.set_joint_targets(goal)
            for _ in range(max(1, int(math.ceil(length / speed / self.control_dt)))):
                self.tick()
            done += length
            if on_progress is not None:
                on_progress(done / total)
        return worst

    def draw_mark(self, mark: MarkSpec, canvas_to_world: Callable[[float, float], np.ndarray], hover: float = 0.03) -> float:
        """Drive to the cell, write the mark stroke by stroke (ink follows the pen), lift, go home, drive back.

        Returns the largest IK error along the pen path (m).
        """
        scene = self.scene
        strokes = mark.strokes(scene.grid, scene.canvas.px)
        paths = [np.array([canvas_to_world(u, v) for u, v in _waypoints(stroke.points)]) for stroke in strokes]
        lengths = [float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in paths]
        total = sum(lengths) or 1.0
        centre = np.mean(np.concatenate(paths), axis=0)
        self.drive_base_to(self.base_goal_for(centre))
        up = np.array([0.0, 0.0, hover])
        worst = 0.0
        drawn = 0.0
        for path, length in zip(paths, lengths):
            self.reach(path[0] + up, 0.5)
            self.reach(path[0], 0.2)

            def progress(fraction: float, before: float = drawn, length: float = length) -> None:
                scene.canvas.draw(mark, min((before + fraction * length) / total, 0.999))

            worst = max(worst, self.trace(path, on_progress=progress))
            drawn += length
            self.reach(path[-1] + up, 0.2)
        scene.canvas.draw(mark, 1.0)
        self.go_home(0.6)
        self.drive_base_to(self.home_base)
        return worst

    def point_at(self, point: np.ndarray, height: float = 0.12) -> None:
        """Point at a cell from above (the ultimate game: the robot says its move and the human draws it)."""
        self.drive_base_to(self.base_goal_for(point))
        self.reach(point + np.array([0.0, 0.0, height]), 0.8)
        self.wait(0.4)
        self.go_home(0.7)
        self.drive_base_to(self.home_base)
