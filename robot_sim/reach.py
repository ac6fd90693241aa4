"""Can the pen reach every cell of the sheet? Checked by IK before a declared game's sheet is used.

The drawing positions of a declared grid follow from its rows and columns (`ncbot.vision.sheet`), so nobody
placed them by hand: a grid whose corner cell the arm cannot reach from its drawing stand must be refused
up front with the cell's name, not discovered halfway through a game as a mark drawn in the wrong place.
"""
from __future__ import annotations

import numpy as np

from ncbot.robot_sim.ik import PositionIK
from ncbot.robot_sim.motion import REACH_OFFSET
from ncbot.robot_sim.pepper_model import ARM_JOINTS, BASE_JOINTS, TOOL_LINKS


def reach_errors(scene, arm: str = "R") -> np.ndarray:
    """(cells,) metres the pen tip stays short of each cell's centre, from the base stand `RobotMotion` drives to
    (`base_goal_for`) in the home posture: the same IK the drawing motion runs."""
    ik = PositionIK(scene, TOOL_LINKS[arm], ARM_JOINTS[arm])
    base = [scene.joint_index[name] for name in BASE_JOINTS]
    errors = []
    for cell in range(scene.canvas.cells):
        target = scene.cell_world(cell)
        q = scene.home.copy()
        q[base] = [target[0] - REACH_OFFSET[0], target[1] - REACH_OFFSET[1], 0.0]
        errors.append(ik.solve(target, q).error)
    return np.array(errors)


def check_reach(scene, cell_name, arm: str = "R") -> None:
    """One-line ValueError naming the first cell the pen cannot reach (IK error over 5 mm); `cell_name` names a
    cell index as the game does (`b3`)."""
    errors = reach_errors(scene, arm)
    far = np.flatnonzero(errors > 0.005)
    if len(far):
        cell = int(far[0])
        raise ValueError(f"cell {cell_name(cell)} is out of the arm's reach ({1000 * errors[cell]:.0f} mm short); "
                         "expected every cell of the sheet within reach (a grid with fewer rows or columns)")
