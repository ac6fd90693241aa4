"""The SAPIEN scene: floor, table, the game sheet, lights, the primitive Pepper and the human's arm.

Everything the robot perceives comes out of `render()` (the mouth camera, CameraBottom). Joints are PD
position drives; the virtual base joints are velocity drives steered by `drive_base_towards`, as the omni
wheels would be. Robot links have no collision shapes (only the motion matters, not contact), and gravity is
off for them, as if Pepper's own controllers compensated it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ncbot.robot_sim.camera_post import CameraPost
from ncbot.robot_sim.conditions import PRESETS, ConditionRanges, SceneConditions, sample_conditions
from ncbot.robot_sim.dressing import SceneDressing, add_bent_sheet_visual
from ncbot.robot_sim.pepper_model import (BASE_JOINTS, CAMERA_BOTTOM_PITCH, PACKAGED_URDF, TOOL_LINKS,
                                    write_pepper_urdf)
from ncbot.robot_sim.render_system import new_render_system
from ncbot.robot_sim.sheet import SheetCanvas
from ncbot.vision.sheet import Grid, built_in_like, game_grid

#: The sheet lies this far from the table's edge, so that nudges (<= 1.5 cm, 6 degrees) never push it over.
SHEET_MARGIN = 0.03


TABLE_DEPTH, TABLE_WIDTH = 0.8, 1.2


def sheet_grid(game: str) -> Grid:
    """The grid on the sheet of a game (its id, ``ncbot.envs.games``): 3, 9 or (rows, cols); a one-line ValueError
    naming the choices, or saying the sheet cannot draw the game's board."""
    from ncbot.envs.games import make_game

    return game_grid(make_game(game))


def check_game(game: str) -> Grid:
    """The grid of a game the robot plays (`sheet_grid`). Kept as its own name for the callers that only check."""
    return sheet_grid(game)


def placed_by_hand(game: str) -> bool:
    """The 3x3 and 9x9 sheets' drawing positions were placed by hand; a plain grid's were derived from its layout
    (`ncbot.robot_sim.reach` checks them)."""
    return isinstance(sheet_grid(game), int)


@dataclass
class SceneConfig:
    """What the scene looks like; every length in metres."""

    game: str = "standard"
    camera_width: int = 640
    camera_height: int = 480
    #: Vertical field of view of Pepper's 2D cameras (OV5640: 44.3 degrees).
    camera_fovy_deg: float = 44.3
    #: Side of the square sheet; None = 0.22 m for 3x3 (and declared grids up to 5 a side), 0.28 m for ultimate
    #: (and larger declared grids: their cells stay at least 3 cm).
    sheet_side: float | None = None
    texture_px: int = 600
    table_height: float = 0.75
    #: The table's near edge, measured from the robot's home position; the sheet lies right at it.
    table_edge_x: float = 0.16
    physics_hz: int = 200
    #: Optional folder of licensed Pepper meshes (<Link>.dae ...) replacing the primitive visuals.
    meshes_dir: str | None = None
    home_qpos: dict[str, float] = field(default_factory=dict)
    #: The field's conditions (robot_sim.conditions): a preset's ranges, sampled once per scene with
    #: `conditions_seed` (lights, surfaces, clutter, the sheet's pose and tint, camera, bystander).
    conditions: ConditionRanges = PRESETS["lab"]
    conditions_seed: int = 0

    def resolved_sheet_side(self) -> float:
        small = built_in_like(sheet_grid(self.game)) == 3
        return self.sheet_side or (0.22 if small else 0.28)

    def lab_sheet_centre(self) -> tuple[float, float]:
        """Where the sheet lies in the lab (x, y): at the table's near edge, centred on the robot."""
        return (self.table_edge_x + SHEET_MARGIN + self.resolved_sheet_side() / 2, 0.0)

    def sample_conditions(self) -> SceneConditions:
        return sample_conditions(self.conditions, self.conditions_seed, self.resolved_sheet_side(), self.lab_sheet_centre())


#: Pepper's rest posture: arms hanging beside the body (the robot's "home").
REST_POSTURE = {
    "LShoulderPitch": 1.55, "LShoulderRoll": 0.13, "LElbowYaw": -1.22, "LElbowRoll": -0.52, "LWristYaw": 0.0,
    "RShoulderPitch": 1.55, "RShoulderRoll": -0.13, "RElbowYaw": 1.22, "RElbowRoll": 0.52, "RWristYaw": 0.0,
    "LHand": 0.6, "RHand": 0.6, "HeadYaw": 0.0, "HeadPitch": 0.0, "HipRoll": 0.0, "HipPitch": 0.0, "KneePitch": 0.0,
}


class PepperScene:
    """A table, a sheet with the game grid, a primitive Pepper with its mouth camera, and a human arm."""

    def __init__(self, config: SceneConfig | None = None) -> None:
        import sapien

        self.config = config or SceneConfig()
        self.grid = sheet_grid(self.config.game)
        if self.config.camera_width < 32 or self.config.camera_height < 24:
            raise ValueError(f"camera must be at least 32x24 pixels; got {self.config.camera_width}x{self.config.camera_height}")
        render_system = new_render_system()
        self.scene = sapien.Scene([sapien.physx.PhysxCpuSystem(), render_system])
        self.scene.set_timestep(1.0 / self.config.physics_hz)
        self.conditions = self.config.sample_conditions()
        cfg = self.config
        centre = cfg.lab_sheet_centre()
        self.dressing = SceneDressing(self.scene, self.conditions, cfg.table_height, cfg.table_edge_x + TABLE_DEPTH / 2,
                                      np.array([centre[0] + self.conditions.sheet_offset[0],
                                                centre[1] + self.conditions.sheet_offset[1], cfg.table_height]))
        self.dressing.add_lights()
        self.camera_post = CameraPost(self.conditions.camera)
        self.time = 0.0
        self._build_room()
        self.dressing.add_surfaces(TABLE_DEPTH, TABLE_WIDTH)
        self.dressing.add_props()
        self.dressing.add_bystander()
        self._build_sheet()
        self._build_robot()
        self._build_human_arm()
        self.camera = self.scene.add_mounted_camera(
            "CameraBottom", self.links["CameraBottom_frame"].entity, sapien.Pose(),
            self.config.camera_width, self.config.camera_height, math.radians(self.config.camera_fovy_deg), 0.02, 6.0)
        self.home = self._home_posture()
        self.reset_robot()

    # ---------------------------------------------------------------- building
    def _build_room(self) -> None:
        import sapien

        colours = self.conditions
        floor = sapien.render.RenderMaterial(base_color=[*colours.floor_colour, 1.0], roughness=0.9)
        self.scene.add_ground(0.0, render_material=floor)
        wood = sapien.render.RenderMaterial(base_color=[*colours.table_colour, 1.0], roughness=0.7)
        cfg = self.config
        depth, width, thick = TABLE_DEPTH, TABLE_WIDTH, 0.03
        builder = self.scene.create_actor_builder()
        centre_x = cfg.table_edge_x + depth / 2
        builder.add_box_visual(sapien.Pose([0, 0, -thick / 2]), [depth / 2, width / 2, thick / 2], wood)
        for sx in (-1, 1):
            for sy in (-1, 1):
                builder.add_box_visual(sapien.Pose([sx * (depth / 2 - 0.05), sy * (width / 2 - 0.05), -cfg.table_height / 2]),
                                       [0.025, 0.025, cfg.table_height / 2 - thick], wood)
        self.table = builder.build_static(name="table")
        self.table.set_pose(sapien.Pose([centre_x, 0.0, cfg.table_height]))

    def _build_sheet(self) -> None:
        import sapien

        side = self.config.resolved_sheet_side()
        self.sheet_side = side
        self.canvas = SheetCanvas(self.grid, self.config.texture_px)
        self._texture = sapien.render.RenderTexture2D(self.canvas.texture_rgba(), "R8G8B8A8Unorm")
        # The paper's tint multiplies the canvas (white in the lab).
        material = sapien.render.RenderMaterial(base_color=[*self.conditions.paper_colour, 1.0], roughness=0.95)
        material.base_color_texture = self._texture
        builder = self.scene.create_actor_builder()
        shape = self.conditions.sheet_shape
        if shape.flat:
            # A plane faces +x; turn it to face up (+z), scaled to the sheet.
            builder.add_plane_visual(sapien.Pose(q=[0.7071068, 0.0, -0.7071068, 0.0]), [1.0, side / 2, side / 2], material)
            self.sheet = builder.build_kinematic(name="sheet")
        else:  # curled or folded: a bent mesh with the same texture layout
            self.sheet = builder.build_kinematic(name="sheet")
            add_bent_sheet_visual(self.sheet, shape, side, material)
        (x, y), (dx, dy), yaw = self.config.lab_sheet_centre(), self.conditions.sheet_offset, self.conditions.sheet_yaw
        self.sheet_home_pose = sapien.Pose([x + dx, y + dy, self.config.table_height + 0.0008],
                                           [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
        self.sheet.set_pose(self.sheet_home_pose)
        self._uploaded_version = self.canvas.version

    def _build_robot(self) -> None:
        import tempfile

        urdf = PACKAGED_URDF
        if self.config.meshes_dir is not None:
            urdf = write_pepper_urdf(Path(tempfile.gettempdir()) / "ncbot-pepper-meshes.urdf", self.config.meshes_dir)
        elif not urdf.is_file():  # an install without package data: the description is code, so rebuild it
            urdf = write_pepper_urdf(Path(tempfile.gettempdir()) / "ncbot-pepper.urdf")
        loader = self.scene.create_urdf_loader()
        loader.fix_root_link = True
        self.robot = loader.load(str(urdf))
        self.links = {link.name: link for link in self.robot.get_links()}
        for link in self.robot.get_links():
            link.disable_gravity = True
        self.joints = {joint.name: joint for joint in self.robot.get_active_joints()}
        self.joint_names = [joint.name for joint in self.robot.get_active_joints()]
        self.joint_index = {name: i for i, name in enumerate(self.joint_names)}
        self.limits = np.array([joint.get_limits()[0] for joint in self.robot.get_active_joints()], dtype=np.float64)
        for name, joint in self.joints.items():
            if name in BASE_JOINTS:
                joint.set_drive_property(stiffness=0.0, damping=2.0e4, force_limit=1.0e6)
            else:
                joint.set_drive_property(stiffness=400.0, damping=40.0, force_limit=1.0e4)
        self.pinocchio = self.robot.create_pinocchio_model()
        self.link_index = {link.name: i for i, link in enumerate(self.robot.get_links())}

    def _build_human_arm(self) -> None:
        """The human's forearm, hand and pen: kinematic primitives moved by the simulated human."""
        import sapien

        skin = sapien.render.RenderMaterial(base_color=[*self.conditions.skin, 1.0], roughness=0.8)
        sleeve = sapien.render.RenderMaterial(base_color=[*self.conditions.sleeve, 1.0], roughness=0.9)
        pen = sapien.render.RenderMaterial(base_color=[0.1, 0.2, 0.7, 1.0])
        builder = self.scene.create_actor_builder()
        # Local frame: origin at the pen tip; the arm runs along +x towards the elbow.
        builder.add_cylinder_visual(sapien.Pose([0.03, 0, 0.035], [0.9659, 0, -0.2588, 0]), 0.005, 0.045, pen)
        builder.add_box_visual(sapien.Pose([0.075, 0.0, 0.06]), [0.05, 0.042, 0.018], skin)
        builder.add_sphere_visual(sapien.Pose([0.04, 0.03, 0.045]), 0.018, skin)
        builder.add_capsule_visual(sapien.Pose([0.27, 0.0, 0.12], [0.9877, 0, -0.1564, 0]), 0.038, 0.13, skin)
        builder.add_capsule_visual(sapien.Pose([0.52, 0.0, 0.22], [0.9877, 0, -0.1564, 0]), 0.048, 0.14, sleeve)
        self.human_arm = builder.build_kinematic(name="human_arm")
        self.hide_human_arm()

    def _home_posture(self) -> np.ndarray:
        """Rest posture with the head pitched so the sheet's centre sits in the middle of the image."""
        q = np.zeros(len(self.joint_names))
        for name, value in {**REST_POSTURE, **self.config.home_qpos}.items():
            q[self.joint_index[name]] = value
        target = np.array(self.sheet_home_pose.p)
        for _ in range(4):  # head pitch moves the camera a little: a few fixed-point passes
            cam = self.link_pose("CameraBottom_frame", q)
            d = target - cam.p
            wanted = math.atan2(-d[2], math.hypot(d[0], d[1]))
            q[self.joint_index["HeadPitch"]] = float(np.clip(wanted - CAMERA_BOTTOM_PITCH, *self.limits[self.joint_index["HeadPitch"]]))
        return q

    # ---------------------------------------------------------------- robot state
    def link_pose(self, link: str, qpos: np.ndarray | None = None):
        """World pose of a robot link at `qpos` (default: the current joint positions), by forward kinematics."""
        q = self.robot.get_qpos() if qpos is None else np.asarray(qpos, dtype=np.float64)
        self.pinocchio.compute_forward_kinematics(q)
        return self.robot.pose * self.pinocchio.get_link_pose(self.link_index[link])

    def tool_position(self, side: str = "R") -> np.ndarray:
        return np.array(self.links[TOOL_LINKS[side]].entity_pose.p, dtype=np.float64)

    @property
    def qpos(self) -> np.ndarray:
        return np.asarray(self.robot.get_qpos(), dtype=np.float64)

    def reset_robot(self, qpos: np.ndarray | None = None) -> None:
        """Teleport to `qpos` (default home) at rest, with the drives holding it."""
        q = self.home.copy() if qpos is None else np.asarray(qpos, dtype=np.float64)
        self.robot.set_qpos(q)
        self.robot.set_qvel(np.zeros_like(q))
        self.set_joint_targets(q)

    def set_joint_targets(self, q: np.ndarray) -> None:
        """Position targets for every non-base joint (clamped to limits); base joints are left alone."""
        q = np.clip(np.asarray(q, dtype=np.float64), self.limits[:, 0], self.limits[:, 1])
        for name, joint in self.joints.items():
            if name not in BASE_JOINTS:
                joint.set_drive_target(float(q[self.joint_index[name]]))

    def set_base_velocity(self, vx: float, vy: float, vyaw: float) -> None:
        for name, v in zip(BASE_JOINTS, (vx, vy, vyaw)):
            self.joints[name].set_drive_velocity_target(float(v))

    def base_pose(self) -> np.ndarray:
        """(x, y, yaw) of the base from the virtual base joints."""
        q = self.qpos
        return np.array([q[self.joint_index[n]] for n in BASE_JOINTS])

    def step(self, seconds: float) -> None:
        """Advance physics by `seconds` (rounded to whole physics steps)."""
        steps = max(1, int(round(seconds * self.config.physics_hz)))
        for _ in range(steps):
            self.scene.step()
        self.time += steps / self.config.physics_hz

    # ---------------------------------------------------------------- sheet and human
    def canvas_to_world(self, u: float, v: float) -> np.ndarray:
        """World point of canvas pixel (u = column, v = row) on the sheet's surface, following the sheet pose."""
        px = self.canvas.px
        local = np.array([self.sheet_side * (0.5 - (v + 0.5) / px), self.sheet_side * (0.5 - (u + 0.5) / px), 0.0])
        local[2] = float(self.conditions.sheet_shape.height(local[0], local[1], self.sheet_side))  # a curl or fold
        pose = self.sheet.pose
        return np.array(pose.to_transformation_matrix()[:3, :3] @ local + pose.p)

    def cell_world(self, cell: int) -> np.ndarray:
        return self.canvas_to_world(*self.canvas.cell_pixel(cell))

    def refresh_sheet(self) -> None:
        """Upload the canvas to the sheet's texture if it changed since the last upload."""
        if self.canvas.version != self._uploaded_version:
            self._texture.upload(self.canvas.texture_rgba())
            self._uploaded_version = self.canvas.version

    def nudge_sheet(self, dx: float, dy: float, dyaw: float, max_offset: float = 0.015, max_yaw: float = 0.1) -> None:
        """Move the sheet a little on the table (a person bumping it); it stays within `max_offset` m and
        `max_yaw` rad of where it was laid, so it never slides off the table's edge."""
        import sapien

        home = np.array(self.sheet_home_pose.p)
        offset = np.clip(np.array(self.sheet.pose.p) + np.array([dx, dy, 0.0]) - home, -max_offset, max_offset)
        offset[2] = 0.0
        laid = self.conditions.sheet_yaw
        yaw = laid + float(np.clip(self.sheet_yaw() - laid + dyaw, -max_yaw, max_yaw))
        self.sheet.set_pose(sapien.Pose(home + offset, [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]))

    def sheet_yaw(self) -> float:
        w, _, _, z = self.sheet.pose.q
        return 2.0 * math.atan2(z, w)

    def place_human_arm(self, tip: np.ndarray, lift: float = 0.0, yaw: float = 0.0) -> None:
        """Put the human's pen tip at `tip` (+ `lift` above it), arm reaching from the far side of the table."""
        import sapien

        self.human_arm.set_pose(sapien.Pose([tip[0], tip[1], tip[2] + lift], [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]))
        self.arm_visible = True

    def hide_human_arm(self) -> None:
        import sapien

        self.human_arm.set_pose(sapien.Pose([2.5, 0.0, -1.0]))
        self.arm_visible = False

    # ---------------------------------------------------------------- camera
    def render_overview(self, width: int = 640, height: int = 480,
                        eye: tuple[float, float, float] = (1.25, -1.05, 1.55),
                        target: tuple[float, float, float] = (0.25, 0.0, 0.8)) -> np.ndarray:
        """A third-person view of robot, table and sheet (for people, never for the robot's perception)."""
        import sapien

        if getattr(self, "_overview", None) is None or self._overview.width != width or self._overview.height != height:
            self._overview = self.scene.add_camera("overview", width, height, math.radians(50.0), 0.05, 10.0)
        forward = np.array(target, dtype=np.float64) - np.array(eye, dtype=np.float64)
        forward /= np.linalg.norm(forward)
        left = np.cross([0.0, 0.0, 1.0], forward)
        left /= np.linalg.norm(left)
        matrix = np.eye(4)
        matrix[:3, :3] = np.stack([forward, left, np.cross(forward, left)], axis=1)
        matrix[:3, 3] = eye
        self._overview.entity.set_pose(sapien.Pose(matrix))
        self.refresh_sheet()
        self.scene.update_render()
        self._overview.take_picture()
        return np.ascontiguousarray(self._overview.get_picture("Color")[:, :, :3])

    def render(self) -> np.ndarray:
        """One mouth-camera frame as uint8 RGB (H, W, 3), with the sheet's latest texture, as the camera
        delivers it (the conditions' exposure, noise, blur and compression; untouched in the lab)."""
        self.dressing.before_frame(self.time)
        self.refresh_sheet()
        self.scene.update_render()
        self.camera.take_picture()
        rgba = self.camera.get_picture("Color")
        return self.camera_post(np.ascontiguousarray(rgba[:, :, :3]))
