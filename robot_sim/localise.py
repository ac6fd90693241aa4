"""Where the sheet lies on the table, from one mouth-camera frame.

The robot must not draw where the sheet was but where it is (people nudge it). The vision package finds the
page's four corners in the frame; each corner's pixel ray from the camera (pose from forward kinematics,
intrinsics from the field of view) meets the table plane at a world point. The four points give the sheet's
centre and yaw, and `SheetEstimate.canvas_to_world` maps canvas pixels onto that estimate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class SheetEstimate:
    """The sheet's pose on the table as seen by the robot: centre (x, y, z) and yaw about +z."""

    centre: np.ndarray
    yaw: float
    side: float
    px: int

    def canvas_to_world(self, u: float, v: float) -> np.ndarray:
        """World point of canvas pixel (u = column, v = row): rows run away from the robot, columns to its right."""
        local = np.array([self.side * (0.5 - (v + 0.5) / self.px), self.side * (0.5 - (u + 0.5) / self.px)])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([self.centre[0] + c * local[0] - s * local[1], self.centre[1] + s * local[0] + c * local[1],
                         self.centre[2]])


def pixel_rays(scene, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera origin and world ray directions of `pixels` (N, 2) of the mouth camera (SAPIEN: x fwd, y left, z up)."""
    cfg = scene.config
    focal = (cfg.camera_height / 2) / math.tan(math.radians(cfg.camera_fovy_deg) / 2)
    pose = scene.links["CameraBottom_frame"].entity_pose
    rotation = pose.to_transformation_matrix()[:3, :3]
    # Pixel centres: SAPIEN's image spans [0, W] x [0, H]; pixel (u, v) is centred at u + 0.5.
    du = (pixels[:, 0] + 0.5 - cfg.camera_width / 2) / focal
    dv = (pixels[:, 1] + 0.5 - cfg.camera_height / 2) / focal
    directions = np.stack([np.ones_like(du), -du, -dv], axis=1) @ rotation.T
    return np.asarray(pose.p, dtype=np.float64), directions


def localise_sheet(scene, frame_rgb: np.ndarray) -> SheetEstimate | None:
    """The sheet's pose from a frame, or None if the page cannot be found (then keep the last estimate)."""
    from ncbot.vision.page import find_page

    corners = find_page(np.ascontiguousarray(frame_rgb[:, :, ::-1]))
    if corners is None:
        return None
    origin, rays = pixel_rays(scene, np.asarray(corners, dtype=np.float64))
    height = scene.sheet.pose.p[2]  # the table top (+ paper): known furniture, not the sheet's pose
    if np.any(rays[:, 2] >= -1e-6):
        return None
    points = origin + rays * ((height - origin[2]) / rays[:, 2])[:, None]
    tl, tr, br, bl = points
    # Canvas columns run to the robot's right (-y of the sheet frame): TL->TR points along the sheet's -y axis.
    across = (tr - tl) + (br - bl)
    yaw = math.atan2(across[1], across[0]) + math.pi / 2
    yaw = (yaw + math.pi) % (2 * math.pi) - math.pi
    # The paper's size is known (the robot brought the sheet); the contour's own size runs a little small.
    return SheetEstimate(points.mean(axis=0), yaw, scene.sheet_side, scene.canvas.px)
