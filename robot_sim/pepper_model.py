"""Pepper's kinematic description built from primitives, written as a URDF.

Pepper's own meshes come under a restrictive licence, so the model is made of boxes, cylinders and spheres
placed with Pepper's published joint origins and limits (Aldebaran / pepper_description). The real robot's
tree has the torso as root with the legs hanging below it; a wheeled robot in a simulator needs the base as
root, so the leg chain (KneePitch, HipPitch, HipRoll) is inverted exactly: each inverted joint rotates about
the negated axis at the child end, followed by a fixed offset, so every link frame lands where it would on
the real robot. A virtual holonomic base (prismatic x, prismatic y, revolute yaw) stands in for the three
omni wheels, as qibullet does.

`write_pepper_urdf(path, meshes_dir=None)` writes the file; the packaged copy is `assets/pepper.urdf`
(regenerate with `ncbot robot urdf`). With `meshes_dir` pointing at licensed Pepper meshes
(`<Link>.dae`/`.stl`/`.obj` files named after the links), those replace the primitive visuals.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from ncbot.fileio import atomic_write_text

PACKAGED_URDF = Path(__file__).parent / "assets" / "pepper.urdf"

#: Height of the Tibia frame above the floor at the zero pose (torso 0.820 m - 0.139 - 0.079 - 0.268).
TIBIA_HEIGHT = 0.334
#: Where the mouth camera (CameraBottom) sits on the Head link and how far it is pitched down.
CAMERA_BOTTOM_XYZ = (0.0926, 0.0, 0.0618)
CAMERA_BOTTOM_PITCH = math.radians(40.0)
#: Fingertip / pen point past the wrist (Pepper's hand: about 0.14 m).
TOOL_OFFSET_FROM_WRIST = 0.14
WHEEL_RADIUS = 0.07

BASE_JOINTS = ("base_x", "base_y", "base_yaw")
HEAD_JOINTS = ("HeadYaw", "HeadPitch")
LEG_JOINTS = ("HipRoll", "HipPitch", "KneePitch")
ARM_JOINTS = {
    side: tuple(f"{side}{name}" for name in ("ShoulderPitch", "ShoulderRoll", "ElbowYaw", "ElbowRoll", "WristYaw"))
    for side in ("L", "R")
}
HAND_JOINTS = ("LHand", "RHand")
TOOL_LINKS = {"L": "l_tool", "R": "r_tool"}

WHITE = (0.93, 0.93, 0.95, 1.0)
GREY = (0.35, 0.35, 0.38, 1.0)
DARK = (0.08, 0.08, 0.10, 1.0)
BLUE = (0.15, 0.35, 0.85, 1.0)


@dataclass
class Visual:
    """One primitive visual of a link: kind box|cylinder|sphere, its size and pose in the link frame."""

    kind: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rgba: tuple[float, float, float, float] = WHITE


@dataclass
class Joint:
    """A URDF joint: the child link hangs at `xyz`/`rpy` in the parent frame and moves about `axis`."""

    name: str
    kind: str  # revolute | prismatic | continuous | fixed
    parent: str
    child: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 2.0
    effort: float = 100.0


@dataclass
class Link:
    name: str
    mass: float = 0.05
    visuals: list[Visual] = field(default_factory=list)


def _arm(side: str) -> tuple[list[Link], list[Joint]]:
    """One arm with Pepper's origins; the right arm mirrors y and the roll limits."""
    s = 1.0 if side == "L" else -1.0
    low = side.lower()
    roll_lo, roll_hi = (0.00872665, 1.56207) if side == "L" else (-1.56207, -0.00872665)
    elbow_lo, elbow_hi = (-1.56207, -0.00872665) if side == "L" else (0.00872665, 1.56207)
    half_pi = (0.0, math.pi / 2, 0.0)  # cylinder z-axis turned onto the link's x-axis
    links = [
        Link(f"{side}Shoulder", 0.3, [Visual("sphere", (0.055,), rgba=WHITE)]),
        Link(f"{side}Bicep", 0.3, [Visual("cylinder", (0.045, 0.17), (0.09, s * 0.008, 0.0), half_pi)]),
        Link(f"{side}Elbow", 0.1, [Visual("sphere", (0.042,), rgba=GREY)]),
        Link(f"{side}ForeArm", 0.25, [Visual("cylinder", (0.038, 0.14), (0.075, 0.0, 0.0), half_pi)]),
        Link(f"{low}_wrist", 0.1, [Visual("cylinder", (0.033, 0.03), (0.0, 0.0, 0.0), half_pi, GREY)]),
        Link(f"{low}_gripper", 0.15, [
            Visual("box", (0.07, 0.06, 0.025), (0.04, 0.0, 0.0)),
            Visual("box", (0.05, 0.012, 0.012), (0.095, s * 0.018, -0.005)),
            # A pen held in the hand, ending at the tool point.
            Visual("cylinder", (0.005, 0.045), (TOOL_OFFSET_FROM_WRIST - 0.025 - 0.0225, 0.0, 0.0), half_pi, BLUE),
        ]),
        Link(TOOL_LINKS[side], 0.01),
    ]
    joints = [
        Joint(f"{side}ShoulderPitch", "revolute", "torso", f"{side}Shoulder", (-0.057, s * 0.14974, 0.08682),
              axis=(0, 1, 0), lower=-2.08567, upper=2.08567, velocity=7.34, effort=5.4),
        Joint(f"{side}ShoulderRoll", "revolute", f"{side}Shoulder", f"{side}Bicep", axis=(0, 0, 1),
              lower=roll_lo, upper=roll_hi, velocity=9.23, effort=2.7),
        Joint(f"{side}ElbowYaw", "revolute", f"{side}Bicep", f"{side}Elbow", (0.1812, s * 0.015, 0.00013),
              (0.0, -0.157079, 0.0), axis=(1, 0, 0), lower=-2.08567, upper=2.08567, velocity=7.34, effort=5.4),
        Joint(f"{side}ElbowRoll", "revolute", f"{side}Elbow", f"{side}ForeArm", axis=(0, 0, 1),
              lower=elbow_lo, upper=elbow_hi, velocity=9.23, effort=2.7),
        Joint(f"{side}WristYaw", "revolute", f"{side}ForeArm", f"{low}_wrist", (0.15, 0.0, 0.0), axis=(1, 0, 0),
              lower=-1.82387, upper=1.82387, velocity=17.4, effort=0.2),
        Joint(f"{side}Hand", "revolute", f"{low}_wrist", f"{low}_gripper", (0.025, 0.0, 0.0), axis=(1, 0, 0),
              lower=0.02, upper=0.98, velocity=12.6, effort=0.14),
        Joint(f"{low}_tool_fixed", "fixed", f"{low}_gripper", TOOL_LINKS[side],
              (TOOL_OFFSET_FROM_WRIST - 0.025, 0.0, 0.0)),
    ]
    return links, joints


def pepper_description() -> tuple[list[Link], list[Joint]]:
    """Links and joints of the primitive Pepper, root `world` fixed, base on virtual x/y/yaw joints."""
    links = [
        Link("world", 0.01),
        Link("base_x_link", 0.5),
        Link("base_y_link", 0.5),
        Link("base_footprint", 10.0, [
            # Omni-wheel base: a low skirt and three wheels of radius 0.07 m.
            Visual("cylinder", (0.24, 0.12), (0.0, 0.0, 0.13), rgba=WHITE),
            Visual("cylinder", (0.22, 0.05), (0.0, 0.0, 0.045), rgba=DARK),
            *[
                Visual("sphere", (WHEEL_RADIUS,), (0.17 * math.cos(a), 0.17 * math.sin(a), WHEEL_RADIUS), rgba=DARK)
                for a in (0.0, 2.0 * math.pi / 3, 4.0 * math.pi / 3)
            ],
        ]),
        Link("Tibia", 3.0, [Visual("cylinder", (0.17, 0.16), (0.0, 0.0, -0.05))]),
        Link("KneePitch_link", 0.01),
        Link("Pelvis", 3.0, [Visual("cylinder", (0.13, 0.27), (0.0, 0.0, -0.13))]),
        Link("HipPitch_link", 0.01),
        Link("Hip", 1.0, [Visual("cylinder", (0.12, 0.08), (0.0, 0.0, -0.04), rgba=GREY)]),
        Link("HipRoll_link", 0.01),
        Link("torso", 5.0, [
            Visual("box", (0.17, 0.27, 0.24), (-0.03, 0.0, 0.04)),
            Visual("box", (0.01, 0.20, 0.13), (0.056, 0.0, 0.03), rgba=DARK),  # the chest tablet
        ]),
        Link("Neck", 0.3, [Visual("cylinder", (0.035, 0.06), (0.0, 0.0, -0.03), rgba=GREY)]),
        Link("Head", 1.5, [
            Visual("sphere", (0.09,), (0.0, 0.0, 0.08)),
            Visual("sphere", (0.018,), (0.075, 0.035, 0.10), rgba=BLUE),   # eyes
            Visual("sphere", (0.018,), (0.075, -0.035, 0.10), rgba=BLUE),
        ]),
        Link("CameraBottom_frame", 0.01),
    ]
    joints = [
        Joint("base_x", "prismatic", "world", "base_x_link", axis=(1, 0, 0), lower=-5.0, upper=5.0, velocity=0.55),
        Joint("base_y", "prismatic", "base_x_link", "base_y_link", axis=(0, 1, 0), lower=-5.0, upper=5.0,
              velocity=0.55),
        Joint("base_yaw", "revolute", "base_y_link", "base_footprint", axis=(0, 0, 1), lower=-math.pi,
              upper=math.pi, velocity=1.0),
        Joint("base_to_tibia", "fixed", "base_footprint", "Tibia", (0.0, 0.0, TIBIA_HEIGHT)),
        # Leg chain inverted: rotate about the negated axis, then the fixed offset of the real joint.
        Joint("KneePitch", "revolute", "Tibia", "KneePitch_link", axis=(0, -1, 0), lower=-0.514872,
              upper=0.514872, velocity=2.93, effort=27.7),
        Joint("KneePitch_offset", "fixed", "KneePitch_link", "Pelvis", (0.0, 0.0, 0.268)),
        Joint("HipPitch", "revolute", "Pelvis", "HipPitch_link", axis=(0, -1, 0), lower=-1.03847, upper=1.03847,
              velocity=2.93, effort=19.8),
        Joint("HipPitch_offset", "fixed", "HipPitch_link", "Hip", (0.0, 0.0, 0.079)),
        Joint("HipRoll", "revolute", "Hip", "HipRoll_link", axis=(-1, 0, 0), lower=-0.514872, upper=0.514872,
              velocity=2.27, effort=10.2),
        Joint("HipRoll_offset", "fixed", "HipRoll_link", "torso", (-2e-05, 0.0, 0.139)),
        Joint("HeadYaw", "revolute", "torso", "Neck", (-0.038, 0.0, 0.1699), axis=(0, 0, 1), lower=-2.08567,
              upper=2.08567, velocity=7.34, effort=5.4),
        Joint("HeadPitch", "revolute", "Neck", "Head", axis=(0, 1, 0), lower=-0.706858, upper=0.637045,
              velocity=9.23, effort=2.7),
        Joint("CameraBottom_fixed", "fixed", "Head", "CameraBottom_frame", CAMERA_BOTTOM_XYZ,
              (0.0, CAMERA_BOTTOM_PITCH, 0.0)),
    ]
    for side in ("L", "R"):
        arm_links, arm_joints = _arm(side)
        links += arm_links
        joints += arm_joints
    return links, joints


def _fmt(values: tuple[float, ...]) -> str:
    return " ".join(f"{v:.6g}" for v in values)


def _geometry(visual: Visual) -> str:
    if visual.kind == "box":
        return f'<box size="{_fmt(visual.size)}"/>'
    if visual.kind == "cylinder":
        return f'<cylinder radius="{visual.size[0]:.6g}" length="{visual.size[1]:.6g}"/>'
    if visual.kind == "sphere":
        return f'<sphere radius="{visual.size[0]:.6g}"/>'
    raise ValueError(f"unknown primitive {visual.kind!r}; expected box, cylinder or sphere")


MESH_SUFFIXES = (".dae", ".stl", ".obj", ".glb")


def _find_mesh(meshes_dir: Path, link: str) -> Path | None:
    """A mesh file named after the link (case-insensitive: pepper_meshes ships `Torso.dae` for link `torso`)."""
    wanted = {f"{link}{suffix}".lower() for suffix in MESH_SUFFIXES}
    for candidate in sorted(meshes_dir.rglob("*")):
        if candidate.is_file() and candidate.name.lower() in wanted:
            return candidate
    return None


def pepper_urdf_text(meshes_dir: str | Path | None = None) -> str:
    """The URDF as a string; `meshes_dir` swaps primitive visuals for licensed meshes named after links."""
    mesh_root = Path(meshes_dir) if meshes_dir is not None else None
    if mesh_root is not None and not mesh_root.is_dir():
        raise FileNotFoundError(f"Pepper meshes folder {mesh_root} does not exist; expected a folder of <Link>.dae files")
    links, joints = pepper_description()
    lines = ['<?xml version="1.0"?>', "<!-- Generated by robot_sim/pepper_model.py: Pepper from primitives. -->",
             '<robot name="pepper_primitive">']
    for link in links:
        lines.append(f"  <link name={quoteattr(link.name)}>")
        inertia = max(link.mass * 0.002, 1e-5)
        lines.append(f'    <inertial><mass value="{link.mass:.6g}"/><origin xyz="0 0 0"/>'
                     f'<inertia ixx="{inertia:.6g}" iyy="{inertia:.6g}" izz="{inertia:.6g}" ixy="0" ixz="0" iyz="0"/>'
                     "</inertial>")
        mesh = _find_mesh(mesh_root, link.name) if mesh_root is not None else None
        if mesh is not None:
            lines.append(f'    <visual><geometry><mesh filename={quoteattr(str(mesh.resolve()))}/></geometry></visual>')
        else:
            for i, visual in enumerate(link.visuals):
                lines.append(f'    <visual name="{link.name}_{i}"><origin xyz="{_fmt(visual.xyz)}" rpy="{_fmt(visual.rpy)}"/>'
                             f"<geometry>{_geometry(visual)}</geometry>"
                             f'<material name="{link.name}_m{i}"><color rgba="{_fmt(visual.rgba)}"/></material></visual>')
        lines.append("  </link>")
    for joint in joints:
        lines.append(f"  <joint name={quoteattr(joint.name)} type={quoteattr(joint.kind)}>")
        lines.append(f'    <parent link="{joint.parent}"/><child link="{joint.child}"/>')
        lines.append(f'    <origin xyz="{_fmt(joint.xyz)}" rpy="{_fmt(joint.rpy)}"/>')
        if joint.kind != "fixed":
            lines.append(f'    <axis xyz="{_fmt(joint.axis)}"/>')
            lines.append(f'    <limit lower="{joint.lower:.6g}" upper="{joint.upper:.6g}" '
                         f'velocity="{joint.velocity:.6g}" effort="{joint.effort:.6g}"/>')
        lines.append("  </joint>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def write_pepper_urdf(path: str | Path = PACKAGED_URDF, meshes_dir: str | Path | None = None) -> Path:
    """Write the URDF atomically (`fileio`) and return its path."""
    return atomic_write_text(pepper_urdf_text(meshes_dir), path)


def joint_limits() -> dict[str, tuple[float, float]]:
    """(lower, upper) of every moving joint, by name."""
    _, joints = pepper_description()
    return {j.name: (j.lower, j.upper) for j in joints if j.kind != "fixed"}
