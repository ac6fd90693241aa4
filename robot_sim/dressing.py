"""Dressing the robot's SAPIEN scene with one game's conditions: lights, textured surfaces, clutter, a bystander.

`PepperScene` builds the robot, table and sheet; this module adds what makes the scene a place rather than
the lab: the lights of `SceneConditions` (a main light with shadows that may drift slowly like sun behind
clouds, lamps of other colours), procedural table/floor/wall textures, objects on the table, and a second
person standing by whose arm now and then comes into the camera's view. `before_frame` is called before
every mouth-camera frame to move what changes per frame, from the scene's own seeded generator.
"""
from __future__ import annotations

import math

import numpy as np

from ncbot.robot_sim.scene_conditions import Prop, SceneConditions
from ncbot.robot_sim.sheet_shape import SheetShape
from ncbot.robot_sim.textures import surface_texture

#: A bystander's arm leaves the view with this probability per frame once it is in.
BYSTANDER_LEAVE = 0.35
#: Cells per side of a bent sheet's mesh (~4.6 mm on a 0.22 m sheet: a crease's shading step stays sharp).
SHEET_MESH_CELLS = 48


def _material(colour, roughness: float = 0.8, texture=None):
    import sapien

    material = sapien.render.RenderMaterial(base_color=[*colour, 1.0], roughness=roughness)
    if texture is not None:
        material.base_color_texture = sapien.render.RenderTexture2D(texture, "R8G8B8A8Unorm")
        material.base_color = [1.0, 1.0, 1.0, 1.0]
    return material


def _yaw_quat(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


FACE_UP = [0.7071068, 0.0, -0.7071068, 0.0]   # a plane faces +x: turned to face +z
UPRIGHT = [0.7071068, 0.0, -0.7071068, 0.0]   # a cylinder runs along x: turned to run along z


def add_bent_sheet_visual(entity, shape: SheetShape, side: float, material, cells: int = SHEET_MESH_CELLS) -> None:
    """Give `entity` the sheet as a bent triangle mesh (curl, fold) in its local frame: z up, the flat sheet's
    texture coordinates (u along +x, v along +y, as SAPIEN's plane visual the flat sheet uses), normals from
    the height field so the lights shade each part of the bend as it faces them."""
    import sapien

    g = np.linspace(-side / 2, side / 2, cells + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    z = shape.height(x, y, side)
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    uvs = np.stack([x / side + 0.5, y / side + 0.5], axis=-1).reshape(-1, 2).astype(np.float32)
    eps = side / cells / 4
    dzdx = (shape.height(x + eps, y, side) - shape.height(x - eps, y, side)) / (2 * eps)
    dzdy = (shape.height(x, y + eps, side) - shape.height(x, y - eps, side)) / (2 * eps)
    normals = np.stack([-dzdx, -dzdy, np.ones_like(z)], axis=-1)
    normals = (normals / np.linalg.norm(normals, axis=-1, keepdims=True)).reshape(-1, 3).astype(np.float32)
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b, c, d = index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]
    triangles = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]).astype(np.uint32)
    body = sapien.render.RenderBodyComponent()
    body.attach(sapien.render.RenderShapeTriangleMesh(vertices, triangles, normals, uvs, material))
    entity.add_component(body)


class SceneDressing:
    """The conditions' lights, surfaces, props and bystander in a sapien scene."""

    def __init__(self, scene, conditions: SceneConditions, table_top: float, table_centre_x: float,
                 sheet_centre: np.ndarray) -> None:
        self.scene = scene
        self.conditions = conditions
        self.table_top = table_top
        self.table_centre_x = table_centre_x
        self.sheet_centre = np.asarray(sheet_centre, dtype=np.float64)
        self.rng = np.random.default_rng([conditions.seed, 151])
        self.lights: list = []
        self._arm_in = False
        self._arm_pose: np.ndarray | None = None
        self.bystander_arm = None

    # ---------------------------------------------------------------- lights
    def add_lights(self) -> None:
        c = self.conditions
        self.scene.set_ambient_light(list(c.ambient))
        for light in c.lights:
            if light.kind == "directional":
                if light.shadow:
                    entity = self.scene.add_directional_light(
                        list(light.vector), list(light.colour), shadow=True,
                        position=[float(self.sheet_centre[0]), float(self.sheet_centre[1]), self.table_top],
                        shadow_scale=1.5, shadow_near=-3.0, shadow_far=3.0, shadow_map_size=1024)
                else:
                    entity = self.scene.add_directional_light(list(light.vector), list(light.colour))
            elif light.kind == "point":
                entity = self.scene.add_point_light(list(light.vector), list(light.colour))
            else:
                direction = light.direction or (0.0, 0.0, -1.0)
                entity = self.scene.add_spot_light(list(light.vector), list(direction), math.radians(25), math.radians(50),
                                                   list(light.colour))
            self.lights.append(entity)

    # ---------------------------------------------------------------- surfaces
    def surface_material(self, which: str, roughness: float):
        """Material of the table ('table') or floor ('floor'): plain in the lab, else a procedural texture."""
        c = self.conditions
        kind = c.table_texture if which == "table" else c.floor_texture
        colour = c.table_colour if which == "table" else c.floor_colour
        texture = None if kind == "plain" else surface_texture(kind, colour, c.texture_seed + (0 if which == "table" else 1))
        return _material(colour, roughness, texture)

    def add_surfaces(self, table_depth: float, table_width: float) -> None:
        """Textured table top, floor and wall (nothing in the lab, whose surfaces are plain)."""
        import sapien

        c = self.conditions
        if c.table_texture != "plain":
            builder = self.scene.create_actor_builder()
            builder.add_plane_visual(sapien.Pose(q=FACE_UP), [1.0, table_depth / 2, table_width / 2],
                                     self.surface_material("table", 0.6))
            top = builder.build_static(name="table_top")
            top.set_pose(sapien.Pose([self.table_centre_x, 0.0, self.table_top + 0.0002]))
        if c.floor_texture != "plain":
            builder = self.scene.create_actor_builder()
            builder.add_plane_visual(sapien.Pose(q=FACE_UP), [1.0, 3.0, 3.0], self.surface_material("floor", 0.9))
            builder.build_static(name="floor_cover").set_pose(sapien.Pose([0.5, 0.0, 0.001]))
        if c.wall_texture != "none":
            texture = surface_texture(c.wall_texture, c.wall_colour, c.texture_seed + 2)
            builder = self.scene.create_actor_builder()
            # a plane facing -x (towards the robot), 6 m wide and 3 m high, behind the table
            builder.add_plane_visual(sapien.Pose(q=[0.0, 0.0, 0.0, 1.0]), [1.0, 3.0, 1.5], _material(c.wall_colour, 0.9, texture))
            builder.build_static(name="wall").set_pose(sapien.Pose([2.2, 0.0, 1.5]))

    # ---------------------------------------------------------------- clutter
    def add_props(self) -> None:
        for index, prop in enumerate(self.conditions.props):
            self._add_prop(prop, index)

    def _add_prop(self, prop: Prop, index: int) -> None:
        import sapien

        builder = self.scene.create_actor_builder()
        s, colour = prop.scale, prop.colour
        if prop.kind == "cup":
            radius, half = 0.038 * s, 0.048 * s
            builder.add_cylinder_visual(sapien.Pose([0, 0, half], UPRIGHT), radius, half, _material(colour, 0.4))
            builder.add_cylinder_visual(sapien.Pose([0, 0, 2 * half - 0.006], UPRIGHT), radius * 0.88, 0.0045,
                                        _material((0.18, 0.10, 0.06), 0.2))  # coffee
            builder.add_box_visual(sapien.Pose([radius + 0.008, 0, half]), [0.008, 0.004, 0.02 * s], _material(colour, 0.4))
        elif prop.kind == "phone":
            builder.add_box_visual(sapien.Pose([0, 0, 0.004]), [0.074 * s, 0.036 * s, 0.004], _material(colour, 0.3))
            builder.add_box_visual(sapien.Pose([0, 0, 0.0082]), [0.068 * s, 0.032 * s, 0.0003], _material((0.03, 0.04, 0.07), 0.1))
        elif prop.kind == "pen":
            builder.add_cylinder_visual(sapien.Pose([0, 0, 0.005]), 0.005, 0.07 * s, _material(colour, 0.5))
            builder.add_cylinder_visual(sapien.Pose([0.075 * s, 0, 0.005]), 0.003, 0.006, _material((0.1, 0.1, 0.1), 0.5))
        elif prop.kind == "scrap":
            builder.add_box_visual(sapien.Pose([0, 0, 0.0004]), [0.04 * s, 0.028 * s, 0.0003], _material(colour, 0.95))
        else:  # a second sheet of paper (A4)
            builder.add_box_visual(sapien.Pose([0, 0, 0.0004]), [0.1485, 0.105, 0.0003], _material(colour, 0.95))
        actor = builder.build_static(name=f"prop_{index}_{prop.kind}")
        actor.set_pose(sapien.Pose([prop.x, prop.y, self.table_top], _yaw_quat(prop.yaw)))

    # ---------------------------------------------------------------- a second person
    def add_bystander(self) -> None:
        """A person standing beside the table (mostly out of the mouth camera's view) and their arm."""
        import sapien

        c = self.conditions
        if not c.bystander:
            return
        clothes, skin = c.bystander_colours
        self._side = 1.0  # on the robot's left, beyond the table: in the overview's background, not in front of it
        body = self.scene.create_actor_builder()
        body.add_capsule_visual(sapien.Pose([0, 0, 1.25], UPRIGHT), 0.17, 0.25, _material(clothes, 0.9))
        body.add_sphere_visual(sapien.Pose([0, 0, 1.68]), 0.11, _material(skin, 0.7))
        for leg in (-0.09, 0.09):
            body.add_capsule_visual(sapien.Pose([0, leg, 0.45], UPRIGHT), 0.07, 0.38, _material((0.15, 0.16, 0.2), 0.9))
        body.build_static(name="bystander").set_pose(sapien.Pose([0.9, self._side * 0.9, 0.0]))
        arm = self.scene.create_actor_builder()
        # local frame: origin at the fingertips, the arm running along +x back to the shoulder
        arm.add_box_visual(sapien.Pose([0.05, 0.0, 0.02]), [0.055, 0.04, 0.015], _material(skin, 0.8))
        arm.add_capsule_visual(sapien.Pose([0.25, 0.0, 0.07], [0.9877, 0, -0.1564, 0]), 0.036, 0.13, _material(skin, 0.8))
        arm.add_capsule_visual(sapien.Pose([0.5, 0.0, 0.16], [0.9877, 0, -0.1564, 0]), 0.045, 0.15, _material(clothes, 0.9))
        self.bystander_arm = arm.build_kinematic(name="bystander_arm")
        self._hide_arm()

    def _hide_arm(self) -> None:
        import sapien

        self.bystander_arm.set_pose(sapien.Pose([3.0, self._side * 3.0, -1.0]))
        self._arm_in = False

    def _place_arm(self, tip: np.ndarray, yaw: float) -> None:
        import sapien

        self.bystander_arm.set_pose(sapien.Pose([tip[0], tip[1], self.table_top + 0.01], _yaw_quat(yaw)))

    def before_frame(self, time: float) -> None:
        """Move what changes between frames: the main light's slow drift, the bystander's arm."""
        c = self.conditions
        if c.light_drift > 0 and self.lights:
            scale = 1.0 + c.light_drift * math.sin(2 * math.pi * time / c.light_drift_period + c.light_drift_phase)
            self.lights[0].set_color([v * scale for v in c.lights[0].colour])
        if self.bystander_arm is None:
            return
        if self._arm_in:
            if self.rng.random() < BYSTANDER_LEAVE:
                self._hide_arm()
                return
            self._arm_pose = self._arm_pose + np.array([*self.rng.normal(0.0, 0.006, 2), self.rng.normal(0.0, 0.03)])
            self._place_arm(self._arm_pose[:2], float(self._arm_pose[2]))
        elif self.rng.random() < c.bystander_arm_probability:
            # the person points at or rests a hand near the sheet, reaching from their side of the table
            tip = self.sheet_centre[:2] + np.array([self.rng.uniform(-0.05, 0.2), self._side * self.rng.uniform(0.08, 0.25)])
            yaw = self._side * float(self.rng.uniform(0.6, 1.4))
            self._arm_pose = np.array([tip[0], tip[1], yaw])
            self._arm_in = True
            self._place_arm(tip, yaw)
