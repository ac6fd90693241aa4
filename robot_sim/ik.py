"""Position-only arm inverse kinematics: damped least squares on the link Jacobian, inside joint limits.

Pinocchio's own CLIK solver ignores joint limits and a 5-joint arm cannot meet an arbitrary orientation,
so for putting a pen tip on a point we solve for position only: dq = J^T (J J^T + lambda^2 I)^-1 e over the
chosen joints, clamping to limits at each iteration, and we report the position actually reached so callers
can refuse a target that is out of reach instead of drawing in the wrong place.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class IKResult:
    qpos: np.ndarray
    reached: np.ndarray
    error: float
    iterations: int

    @property
    def success(self) -> bool:
        return self.error <= 0.005


class PositionIK:
    """Solves for the joints `joint_names` so that link `link` reaches a world point."""

    def __init__(self, scene, link: str, joint_names: tuple[str, ...], damping: float = 0.05,
                 tolerance: float = 5e-4, max_iterations: int = 60) -> None:
        self.scene = scene
        self.model = scene.pinocchio
        self.link_index = scene.link_index[link]
        self.columns = np.array([scene.joint_index[name] for name in joint_names])
        self.lower = scene.limits[self.columns, 0]
        self.upper = scene.limits[self.columns, 1]
        self.damping = damping
        self.tolerance = tolerance
        self.max_iterations = max_iterations

    def position(self, q: np.ndarray) -> np.ndarray:
        self.model.compute_forward_kinematics(q)
        return np.asarray(self.model.get_link_pose(self.link_index).p, dtype=np.float64)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """3 x k position Jacobian in the world frame (the body-frame Jacobian rotated by the link's rotation)."""
        self.model.compute_forward_kinematics(q)
        rotation = self.model.get_link_pose(self.link_index).to_transformation_matrix()[:3, :3]
        self.model.compute_full_jacobian(q)
        local = self.model.get_link_jacobian(self.link_index, local=True)
        return rotation @ local[:3, self.columns]

    def solve(self, target: np.ndarray, q0: np.ndarray) -> IKResult:
        """Joint positions (full vector, other joints as in q0) that put the link at `target`."""
        target = np.asarray(target, dtype=np.float64)
        q = np.array(q0, dtype=np.float64)
        q[self.columns] = np.clip(q[self.columns], self.lower, self.upper)
        lam2 = self.damping ** 2
        error = target - self.position(q)
        iterations = 0
        for iterations in range(1, self.max_iterations + 1):
            if np.linalg.norm(error) < self.tolerance:
                break
            jac = self.jacobian(q)
            step = jac.T @ np.linalg.solve(jac @ jac.T + lam2 * np.eye(3), error)
            norm = np.linalg.norm(step)
            if norm > 0.3:  # keep each step inside the region where the linearisation holds
                step *= 0.3 / norm
            q[self.columns] = np.clip(q[self.columns] + step, self.lower, self.upper)
            error = target - self.position(q)
        reached = target - error
        return IKResult(q, reached, float(np.linalg.norm(error)), iterations)
