"""The simulated human across the table: picks a cell, draws its mark stroke by stroke, withdraws.

The human's arm (forearm, hand and pen, simple primitives) comes in from the far side of the table, so while
drawing it hides part of the sheet from the robot's mouth camera, as a real player's hand does. The cell
comes from the same opponent models the dialogue env uses (`ncbot.envs.opponents`, random by default), applied to
the TRUE board, which the human sees; the robot only sees frames. Optional noise: a human who waits a
while before drawing, and a sheet nudged a little after a move.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ncbot.robot_sim.sheet import HUMAN_INK, MarkSpec

FrameSink = Callable[[np.ndarray, float], None]


def game_id(game) -> str:
    """How the env names the game of `game` (an `ncbot.envs.rules` game): standard, ultimate, or a declared
    game's id (a shipped name or a YAML file's path), so the opponent models play the same rules."""
    declaration = getattr(game, "declaration", None)
    return declaration.game if declaration is not None else game.name


@dataclass
class HumanConfig:
    """How the simulated person behaves."""

    #: Opponent model name (`ncbot.envs.opponents.make_opponent`): random, rule, minimax, mcts:N.
    opponent: str = "random"
    #: Frames rendered while the pen moves (the mark grows over these).
    drawing_frames: int = 6
    #: Simulated seconds between two frames of the human's turn.
    frame_period: float = 0.25
    #: Probability of waiting (arm away, nothing drawn) before drawing, and for how many frames.
    wait_probability: float = 0.0
    wait_frames: int = 4
    #: Probability that the sheet is nudged (up to `nudge_metres`, `nudge_degrees`) after the human's move.
    nudge_probability: float = 0.0
    nudge_metres: float = 0.01
    nudge_degrees: float = 3.0
    #: Mark size as a fraction of the cell, and pen width in millimetres (ranges sampled per mark).
    mark_size: tuple[float, float] = (0.55, 0.75)
    pen_mm: tuple[float, float] = (1.2, 2.0)
    #: Show the human's arm at all (False: marks appear without occlusion, for ablations).
    show_arm: bool = True
    #: Share of this person's moves they claim to have made in another cell when the game is settled
    #: (`ncbot.robot_sim.settlement.claim_moves`): wrong labels for a reader that learns from play.
    wrong_claims: float = 0.0


class SimulatedHuman:
    """Chooses moves on the true game state and acts them out in the scene, frame by frame."""

    def __init__(self, scene, game, config: HumanConfig | None = None, seed: int = 0, handwriting: str = "pen") -> None:
        self.scene = scene
        self.game = game
        self.config = config or HumanConfig()
        self.handwriting = handwriting  # the stroke model of every mark this person draws
        if self.config.drawing_frames < 1:
            raise ValueError(f"drawing_frames must be at least 1; got {self.config.drawing_frames}")
        if not 0.0 <= self.config.wrong_claims <= 1.0:
            raise ValueError(f"wrong_claims must be a share in [0, 1]; got {self.config.wrong_claims}")
        self.rng = np.random.default_rng(seed)
        self._claims_rng = np.random.default_rng([seed, 31])  # its own stream: the marks drawn stay the same
        self._opponent = self._make_opponent(seed)

    def _make_opponent(self, seed: int):
        if self.config.opponent == "random":
            return None
        try:
            from ncbot.envs.opponents import make_opponent
        except ImportError as error:  # pragma: no cover - the opponents package is part of ncbot
            raise ValueError(f"opponent {self.config.opponent!r} needs envs.opponents ({error}); use 'random'") from None
        free_move = getattr(self.game, "free_move", "anywhere")
        return make_opponent(self.config.opponent, game=game_id(self.game), free_move=free_move, seed=seed)

    def choose(self, state, human_mark: int) -> int:
        """The cell this person plays in the true game `state` (rules.State)."""
        legal = self.game.legal(state)
        if self._opponent is None:
            return int(legal[self.rng.integers(len(legal))])
        import torch

        cells = len(state.board)
        # Opponents see boards as 0 empty, 1 robot, 2 human (the env's convention).
        robot_mark = 3 - human_mark
        board = torch.tensor([[0 if v == 0 else (1 if v == robot_mark else 2) for v in state.board]], dtype=torch.int8)
        mask = torch.zeros(1, cells, dtype=torch.bool)
        mask[0, legal] = True
        last = torch.tensor([state.last_move], dtype=torch.int64)
        generator = torch.Generator().manual_seed(int(self.rng.integers(2**31)))
        cell = int(self._opponent.select(board, last, mask, 2, generator)[0])
        return cell if cell in legal else int(legal[self.rng.integers(len(legal))])

    def _pen_point(self, mark: MarkSpec, progress: float) -> np.ndarray:
        """Where the pen tip is when `progress` of the mark's length has been drawn."""
        strokes = mark.strokes(self.scene.grid, self.scene.canvas.px)
        points = np.concatenate([s.points for s in strokes])
        seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
        along = np.concatenate([[0.0], np.cumsum(seg)])
        u = np.interp(progress * along[-1], along, points[:, 0])
        v = np.interp(progress * along[-1], along, points[:, 1])
        return self.scene.canvas_to_world(u, v)

    def _frame(self, sink: FrameSink) -> None:
        self.scene.step(self.config.frame_period)
        sink(self.scene.render(), self.scene.time)

    def draw(self, cell: int, kind: str, sink: FrameSink, ink: tuple[int, int, int] | None = None,
             drawing_frames: int | None = None) -> MarkSpec:
        """Act out drawing `kind` in `cell`, sending every rendered frame to `sink`; returns the mark drawn.

        `ink` defaults to this person's pen (the scene's conditions: a blue ballpoint in the lab);
        `drawing_frames` overrides how many frames the pen-down part is rendered over (config default).
        """
        cfg = self.config
        ink = ink or tuple(getattr(getattr(self.scene, "conditions", None), "ink_bgr", HUMAN_INK))
        drawing_frames = drawing_frames or cfg.drawing_frames
        scene = self.scene
        sheet_mm = 1000.0 * self.scene.sheet_side
        mark = MarkSpec(cell, kind, int(self.rng.integers(2**31)), ink, float(self.rng.uniform(cfg.mark_size[0], cfg.mark_size[1])),
                        float(self.rng.uniform(cfg.pen_mm[0], cfg.pen_mm[1])) / sheet_mm, self.handwriting)
        yaw = float(self.rng.uniform(-0.35, 0.35))
        if cfg.wait_probability > 0 and self.rng.random() < cfg.wait_probability:
            for _ in range(cfg.wait_frames):
                self._frame(sink)
        start = self._pen_point(mark, 0.0)
        if cfg.show_arm:
            for lift, back in ((0.20, 0.18), (0.05, 0.04)):  # reach in from the far side, then over the cell
                scene.place_human_arm(start + np.array([back, 0.0, 0.0]), lift=lift, yaw=yaw)
                self._frame(sink)
        for k in range(1, drawing_frames + 1):
            progress = k / drawing_frames
            scene.canvas.draw(mark, progress)
            if cfg.show_arm:
                scene.place_human_arm(self._pen_point(mark, progress), lift=0.002, yaw=yaw)
            self._frame(sink)
        if cfg.show_arm:
            end = self._pen_point(mark, 1.0)
            scene.place_human_arm(end + np.array([0.12, 0.0, 0.0]), lift=0.15, yaw=yaw)
            self._frame(sink)
            scene.hide_human_arm()
        if cfg.nudge_probability > 0 and self.rng.random() < cfg.nudge_probability:
            scene.nudge_sheet(*(self.rng.uniform(-1, 1, 2) * cfg.nudge_metres),
                              float(np.deg2rad(self.rng.uniform(-1, 1) * cfg.nudge_degrees)))
        return mark

    def settle(self, moves: list[tuple[int, int]], cells: int) -> list[tuple[int, int]]:
        """The game's (cell, player) moves as this person agrees on them at its end (`wrong_claims` of theirs elsewhere)."""
        from ncbot.robot_sim.settlement import claim_moves

        return claim_moves(moves, cells, self.config.wrong_claims, self._claims_rng)

    def draw_for_robot(self, cell: int, kind: str, sink: FrameSink, ink: tuple[int, int, int]) -> MarkSpec:
        """Ultimate game as in the paper: the robot says its move and the human draws it for the robot.

        The robot knows this move (it chose it), so the drawing is only logged, over fewer frames; the robot's
        look at the sheet afterwards checks the mark landed.
        """
        return self.draw(cell, kind, sink, ink=ink, drawing_frames=2)
