"""Robot games as the MCAP log holds them, turned back into what the learners take.

For the play learner: each logged robot decision (`/step`: the features it decided on, the act, the env's reward,
the available acts and the look-ahead sets A and A_hat) and the next decision's features make one transition; the
game's last step ends it with the game's outcome. The look-ahead keys are rebuilt from the logged sets (A_hat =
negative look-ahead reward, A = the winning acts when A is smaller than the available ones), which is all the mask
rules read. Features were logged as float16, so a transition read back differs from the live one by that rounding.

For the reader: the camera frames of a game and the times of the robot's looks after settled moves
(`/episode` extra `views`), with the moves both sides agreed on (`settled_moves`; older logs: the true boards).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict

from ncbot.envs.core import OUTCOME_NAMES

CAMERA_TOPIC = "/camera/bottom/compressed"


@dataclass
class LoggedGame:
    """One robot game read back from a log."""

    episode: int
    summary: dict[str, Any]
    steps: list[dict[str, Any]] = field(default_factory=list)
    frames: dict[float, bytes] = field(default_factory=dict)  # camera JPEGs by scene time (the last one at a time)
    boards: dict[int, str] = field(default_factory=dict)  # the board after each step (`/board`), by step

    @property
    def extra(self) -> dict[str, Any]:
        return self.summary.get("extra") or {}

    @property
    def finished(self) -> bool:
        """The env ended it (a cut-off game has outcome "none": nothing for the play learner)."""
        return self.summary.get("outcome") in ("win", "draw", "loss")


def _features(step: dict[str, Any], n_features: int) -> torch.Tensor:
    values = torch.zeros(n_features)
    for index in step.get("on", []):
        values[int(index)] = 1.0
    for index, value in step.get("val", []):
        values[int(index)] = float(value)
    return values


def _mask(indices: list[int], n_actions: int) -> torch.Tensor:
    mask = torch.zeros(n_actions, dtype=torch.bool)
    mask[torch.as_tensor(indices, dtype=torch.long)] = True
    return mask


def game_transitions(game: LoggedGame, n_features: int, n_actions: int) -> TensorDict | None:
    """The game's decisions as a (1, T) batch with the keys `ncbot.modules.transitions.prepare_transitions` reads
    (plus the next look-ahead keys of `loss.bootstrap: greedy`); None for a game the env did not end."""
    steps = sorted(game.steps, key=lambda step: step["step"])
    if not game.finished or not steps or any("on" not in step for step in steps):
        return None
    count = len(steps)
    observation = torch.stack([_features(step, n_features) for step in steps])
    masks = torch.stack([_mask(step["mask"], n_actions) for step in steps])
    lookahead = torch.stack([torch.where(_mask(step.get("A_hat", []), n_actions), -1.0, 0.0) for step in steps]).float()
    winning = torch.stack([_mask(step["A"], n_actions) if len(step.get("A", step["mask"])) < len(step["mask"])
                           else torch.zeros(n_actions, dtype=torch.bool) for step in steps])
    last = torch.zeros(count, dtype=torch.bool)
    last[-1] = True
    # the game is decided at the step whose board is the final one; the dialogue goes on (feedback, goodbye)
    boards = [game.boards.get(step["step"]) for step in steps]
    decided = boards.index(boards[-1]) if boards[-1] is not None else count - 1
    code = OUTCOME_NAMES.index(game.summary["outcome"])
    next_outcome = (torch.arange(count) >= decided).to(torch.int8)[:, None] * code
    outcome = (torch.arange(count) > decided).to(torch.int8)[:, None] * code
    truncated = bool(game.summary.get("truncated", False))

    def shifted(values: torch.Tensor) -> torch.Tensor:  # the next decision's values; zeros after the last
        return torch.cat([values[1:], torch.zeros_like(values[:1])])

    batch = TensorDict({
        "observation": observation, "action_mask": masks, "action": torch.tensor([step["act"] for step in steps]),
        "outcome": outcome,
        "next": {"observation": shifted(observation), "action_mask": shifted(masks),
                 "reward": torch.tensor([[float(step["reward"])] for step in steps]),
                 "done": last[:, None].clone(), "terminated": (last & (not truncated))[:, None],
                 "truncated": (last & truncated)[:, None], "outcome": next_outcome,
                 "lookahead_reward": shifted(lookahead), "winning_actions": shifted(winning)},
    }, batch_size=[count])
    return batch.unsqueeze(0)


def read_games(path: str | Path, progress: Any = None, frames: bool = True) -> Iterator[LoggedGame]:
    """The robot games of a log (a run folder or .mcap file), in order, with their steps and (`frames`) camera
    frames. A game's frames are those logged after the previous game's summary (one game at a time per logger)."""
    from ncbot.logs import schemas
    from ncbot.logs.reader import LogReader

    reader = LogReader(path, progress=progress)
    steps: dict[int, list[dict[str, Any]]] = {}
    images: dict[float, bytes] = {}
    topics = [schemas.EPISODE_TOPIC, schemas.STEP_TOPIC, schemas.BOARD_TOPIC] + ([CAMERA_TOPIC] if frames else [])
    boards: dict[int, dict[int, str]] = {}
    found = False
    for message in reader.messages(topics):
        if message.topic == CAMERA_TOPIC:
            stamp = message.data.timestamp
            images[round(stamp.seconds + stamp.nanos * 1e-9, 6)] = bytes(message.data.data)
        elif message.topic == schemas.STEP_TOPIC:
            steps.setdefault(int(message.data["episode"]), []).append(message.data)
        elif message.topic == schemas.BOARD_TOPIC:
            cells = message.data["cells"]
            boards.setdefault(int(message.data["episode"]), {})[int(message.data["step"])] = \
                cells if isinstance(cells, str) else "".join(str(v) for v in cells)
        elif message.data.get("phase") == "robot":
            found = True
            episode = int(message.data["episode"])
            yield LoggedGame(episode, message.data, steps.pop(episode, []), images, boards.pop(episode, {}))
            images = {}
    reader.require_ncbot()
    if not found:
        raise ValueError(f"{path} holds no robot games (phase robot); expected the log of `ncbot robot play --out` "
                         f"or `ncbot robot serve --out`")


def game_views(game: LoggedGame, grid) -> tuple[list, int]:
    """(views, frames not found) of a logged game: the robot's looks after settled moves, cut by the reader from
    the logged camera frames, as `ncbot.robot_sim.settlement.GameViews` cut them while the game was played."""
    import cv2

    from ncbot.vision.grid import extract_cells
    from ncbot.vision.online.examples import View

    views, missing = [], 0
    for time, moves in game.extra.get("views", []):
        jpeg = game.frames.get(round(float(time), 6))
        if jpeg is None:
            missing += 1
            continue
        image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
        try:
            views.append(View(extract_cells(image, grid).cell_images, int(moves)))
        except ValueError:
            missing += 1
    return views, missing


def settled_moves(game: LoggedGame) -> list[tuple[int, int]]:
    """The (cell, player) moves both sides agreed on; a log written before they were kept: the true boards'."""
    from ncbot.robot_sim.settlement import moves_from_boards

    if "settled_moves" in game.extra:
        return [(int(cell), int(player)) for cell, player in game.extra["settled_moves"]]
    return moves_from_boards(game.extra.get("true_boards", []))
