"""Helpers the env tests share."""
from __future__ import annotations


def to_robot_move(env, td):
    """Step game 0 through the dialogue (the first allowed non-move act each time) until the robot may move."""
    for _ in range(20):
        if bool(td["action_mask"][0, : env.cells].any()):
            return td
        td["action"] = td["action_mask"][0].nonzero()[0]
        td = env.step(td)["next"]
    raise AssertionError("the robot never got a move")
