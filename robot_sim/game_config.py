"""What `ncbot robot play` can change: the robot game's configuration, checked before any scene is built."""
from __future__ import annotations

from dataclasses import dataclass, field

from ncbot.envs.core import FIRST_CHOICES
from ncbot.robot_sim.conditions import ConditionRanges, load_conditions
from ncbot.robot_sim.human import HumanConfig
from ncbot.robot_sim.scene import check_game

SPEECH_MODES = ("real", "text")
EARS = ("array", "mono")
ANSWER_POLICIES = ("confidence", "confirm")


@dataclass
class RobotPlayConfig:
    """Everything `ncbot robot play` can change; defaults are the paper's set-up on our simulator."""

    game: str = "standard"
    games: int = 1
    seed: int = 0
    #: Who opens each game (the env's option): robot (the paper's demo), human, alternate, random.
    first: str = "robot"
    free_move: str = "anywhere"
    camera_width: int = 640
    camera_height: int = 480
    #: Simulated seconds between two logged camera frames while the robot moves. Rendering is most of a turn's
    #: cost: 1.0 s gives ~5 frames per move (1.5-1.75 s wall per move on the shared 2-core machine), 0.5 s ~10
    #: (2.4-3.0 s). The human's turn is watched at `human.frame_period` regardless.
    robot_frame_period: float = 1.0
    human: HumanConfig = field(default_factory=HumanConfig)
    #: Ultimate: False = as in the paper, the robot points and says its move and the human draws it.
    ultimate_robot_draws: bool = False
    #: Frames the recogniser may take after the human withdrew before the move counts as unseen.
    max_perception_frames: int = 20
    #: Motion threshold tau of Algorithm 1 (gray levels). Rendered frames carry no sensor noise (a still scene
    #: gives 0), so a far lower tau than a real camera needs (vision's default 12) lets even a pen moving over
    #: the sheet count as "a hand is drawing".
    recogniser_tau: float = 1.5
    #: The robot accepts a move once the recogniser reported the same cell and mark this many frames in a row.
    confirm_frames: int = 2
    jpeg_quality: int = 80
    #: Also write every robot utterance as a WAV file under OUT/speech/ (with `speech: real`, or text mode when
    #: the TTS engine is installed).
    audio: bool = False
    #: real: the robot speaks its templates (espeak-ng), the simulated person answers with a flite voice over the
    #: conditions' background noise and the robot hears it through pocketsphinx (the env's `hearing`); every
    #: utterance's audio goes to the MCAP log. text: nothing is spoken or heard, the env's simulated ASR gives
    #: the words said at uniform random confidences (the training env's default). `ncbot robot play` defaults to
    #: real; this dataclass to text, so library callers (tests, `robot serve`) keep their behaviour unless asked.
    speech: str = "text"
    #: With real speech, what takes the person's voice in: array = Pepper's four head microphones in the game's
    #: room (speech.room, drawn from the conditions), then `enhancement`; mono = one microphone with the noise
    #: mixed into the reply (how the training channel model was fitted).
    ears: str = "array"
    #: The array's enhancement (`ncbot.speech.enhance.Enhancement` spec): none|ds|mvdr [+vad] [+postfilter] [+doa].
    enhancement: str = "mvdr+vad"
    #: How a cell said aloud after an unseen move is settled (robot_sim.where): confidence = accept, confirm or ask
    #: for a touch on the tablet, by the recogniser's confidence (`answer_thresholds`); confirm = confirm every cell,
    #: ask at most 3 times, then look again.
    answers: str = "confidence"
    #: The thresholds file of `answers: confidence` (None: the shipped speech/data/answer_thresholds.json).
    answer_thresholds: str | None = None
    agent_name: str = "lookahead"
    #: Folder of licensed Pepper meshes replacing the primitive visuals (see robot_sim.pepper_model).
    meshes_dir: str | None = None
    #: The field's conditions (robot_sim.conditions): lab, office, atrium, random, or a YAML file of ranges;
    #: drawn afresh for every game from its seed.
    conditions: str = "lab"
    #: The cell classifier the move recogniser reads with (`ncbot vision train --out W`); None: the shipped weights.
    weights: str | None = None

    def validate(self) -> None:
        check_game(self.game)
        if self.games < 1:
            raise ValueError(f"games must be at least 1; got {self.games}")
        if self.first not in FIRST_CHOICES:
            raise ValueError(f"first must be one of {', '.join(FIRST_CHOICES)}; got {self.first!r}")
        if self.speech not in SPEECH_MODES:
            raise ValueError(f"speech must be one of {', '.join(SPEECH_MODES)}; got {self.speech!r}")
        if self.ears not in EARS:
            raise ValueError(f"ears must be one of {', '.join(EARS)}; got {self.ears!r}")
        if self.answers not in ANSWER_POLICIES:
            raise ValueError(f"answers must be one of {', '.join(ANSWER_POLICIES)}; got {self.answers!r}")
        from ncbot.speech.enhance import Enhancement

        Enhancement.parse(self.enhancement)
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be in [1, 100]; got {self.jpeg_quality}")
        self.condition_ranges()

    def condition_ranges(self) -> ConditionRanges:
        """The conditions' ranges (a preset or the YAML file), checked."""
        return load_conditions(self.conditions)
