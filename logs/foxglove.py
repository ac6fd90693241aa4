"""Foxglove's own message types (protobuf), built from plain values: what Foxglove and rerun display natively.

`EpisodeLogger.log_camera` / `log_joint_states` / `log_transform` write these; the logger sets the timestamp and
the MCAP channel. protobuf and the Foxglove schemas load on first use, so importing `logs` stays light.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def compressed_image(image: bytes, image_format: str, frame_id: str) -> Any:
    """`foxglove.CompressedImage` of an encoded frame (JPEG/PNG bytes)."""
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage

    if not isinstance(image, (bytes, bytearray)) or not image:
        raise ValueError("log_camera needs the encoded image as non-empty bytes (e.g. cv2.imencode('.jpg', ...))")
    return CompressedImage(frame_id=frame_id, data=bytes(image), format=image_format)


def joint_states(names: Sequence[str], positions: Sequence[float], velocities: Sequence[float] | None = None,
                 efforts: Sequence[float] | None = None) -> Any:
    """`foxglove.JointStates`: one joint per name with its position (rad or m), velocity and effort if given."""
    from foxglove_schemas_protobuf.JointStates_pb2 import JointStates

    if len(names) != len(positions):
        raise ValueError(f"log_joint_states got {len(names)} names but {len(positions)} positions")
    joints = []
    for index, name in enumerate(names):
        joint = {"name": str(name), "position": float(positions[index])}
        if velocities is not None:
            joint["velocity"] = float(velocities[index])
        if efforts is not None:
            joint["effort"] = float(efforts[index])
        joints.append(joint)
    return JointStates(joints=joints)


def frame_transform(parent: str, child: str, translation: Sequence[float], rotation_xyzw: Sequence[float]) -> Any:
    """`foxglove.FrameTransform`: the child frame's pose in the parent frame."""
    from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform

    if len(translation) != 3 or len(rotation_xyzw) != 4:
        raise ValueError("log_transform needs translation (x, y, z) and rotation quaternion (x, y, z, w)")
    x, y, z = (float(v) for v in translation)
    qx, qy, qz, qw = (float(v) for v in rotation_xyzw)
    return FrameTransform(parent_frame_id=parent, child_frame_id=child, translation={"x": x, "y": y, "z": z},
                          rotation={"x": qx, "y": qy, "z": qz, "w": qw})
