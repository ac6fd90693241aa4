"""What a serve session is configured with (`ServeConfig`), what its page shows (`Snapshot`), and its errors.

Why apart from the session: both are plain data the app, the CLI and the session read; the session's module keeps
the game thread and the person's requests.
"""
from __future__ import annotations

from dataclasses import dataclass, field

SEAT_CHOICES = ("robot", "human")  # who opens a browser game: the env's FIRST_CHOICES a person can pick
PERSON_SIDE = {"win": "loss", "loss": "win", "draw": "draw", "unfinished": "unfinished"}


class SessionError(ValueError):
    """A request this session cannot take (the message is sent to the client; nothing changed)."""


class SessionClosed(RuntimeError):
    """Raised inside the game thread when the session is closed while the robot waits for the person."""


@dataclass
class ServeConfig:
    """What `ncbot robot serve` can change."""

    game: str = "standard"
    checkpoint: str | None = None
    out: str = "runs/study"
    camera_width: int = 320
    camera_height: int = 240
    overview_width: int = 480
    overview_height: int = 360
    #: Sessions with no message for this long are closed and their log finished.
    idle_seconds: float = 300.0
    max_sessions: int = 8
    #: Minimum wall seconds between two frames pushed to a tab (the scene renders more often).
    frame_interval: float = 0.3
    audio: bool = True
    seed: int = 0
    #: The field's conditions (robot_sim.conditions): lab, office, atrium, random, or a YAML file of ranges.
    conditions: str = "lab"
    #: Seconds the robot waits for the person's answer to an utterance before it takes silence.
    answer_seconds: float = 30.0
    #: Sessions render at once (own scenes); False: one simulator lock for the whole process.
    parallel: bool = True
    #: Where the robot learns the person's moves: camera (the tablet on its chest when the camera misses one), or
    #: tablet (the person touches every move on the tablet: a study of the touch channel, the camera unused).
    moves: str = "camera"
    #: The cell classifier to read with (None: the shipped one); learn from the games (`ncbot.pipelines.online.
    #: serving`), per participant or `pooled`.
    weights: str | None = None
    learn: bool = False
    pooled: bool = False

    def perception(self) -> dict[str, int]:
        """The robot game's camera settings for `moves`: with tablet the camera never confirms a move (the frames
        in a row it needs out of reach, one still frame), so every move is asked for on the tablet."""
        return {"confirm_frames": 10**9, "max_perception_frames": 1} if self.moves == "tablet" else {}


@dataclass
class Snapshot:
    """What the page shows, sent whole on every change (so a reloaded tab is up to date at once)."""

    screen: str = "start"        # start | game | over | closed
    board: list[str] = field(default_factory=list)
    status: str = "Choose who opens, then press Start."
    robot_says: str = ""
    says_seq: int = 0
    your_turn: bool = False
    outcome: str | None = None   # the person's side: win | loss | draw | unfinished
    games: int = 0
    mark: str = ""
    legal: list[int] = field(default_factory=list)  # cells the person may click now (Ultimate: one small board)
    answering: bool = False      # the robot waits for the person's answer (buttons / typed words)
    acts: list[str] = field(default_factory=list)  # the answer buttons that make sense now (`data-act`)
    heard: str = ""              # what the robot understood of the person's last answer
    tablet: bool = False         # the robot asks the person to touch the cell they drew in on its chest tablet
