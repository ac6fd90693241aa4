"""When the robot may act on a cell it heard: accept it, confirm it aloud, or ask the person to touch it on the
tablet on its chest, decided by how sure the recogniser was (`AnswerThresholds`).

Why three ways: a confidently heard cell costs nothing more; a doubtful one is worth one question ("top left, is
that right?"); a cell heard as nothing, taken, or too doubtful to confirm is not asked again and again in the
same noise: the tablet settles it with one touch. The robot never moves on a cell it did not hear (or see
touched): a cell is taken only when heard at least `accept` sure, or at least `confirm` sure and then confirmed
by a "yes" heard at least `yes` sure.
A phrase's confidence is its least sure word's (pocketsphinx's posterior): "top left" heard as "top" 0.95 "left"
0.40 is a 0.40 answer.
The thresholds are chosen on tuning voices, talkers and rooms only (``python -m ncbot.speech.tune_answers``,
apart from every voice, talker and room the figures are measured on) and kept in
`speech/data/answer_thresholds.json` with the command and sets that chose them.
"""
from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ncbot.fileio.atomic import atomic_write_text

FORMAT = "ncbot-answer-thresholds/1"
DEFAULT_THRESHOLDS = Path(__file__).with_name("data") / "answer_thresholds.json"


@dataclass(frozen=True)
class AnswerThresholds:
    """`accept`: a cell heard at least this sure is taken without a question; `confirm`: at least this sure (and
    below `accept`) it is confirmed aloud, below it the robot asks again or turns to the tablet; `yes`: the least
    confidence of a "yes" that confirms; `asks`: questions "where did you draw?" before the tablet."""

    accept: float
    confirm: float
    yes: float
    asks: int = 1
    meta: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if not 0.0 <= self.confirm <= self.accept <= 1.01 or not 0.0 <= self.yes <= 1.01:
            raise ValueError(f"answer thresholds need 0 <= confirm <= accept <= 1.01 and 0 <= yes <= 1.01 (1.01: "
                             f"never); got accept {self.accept}, confirm {self.confirm}, yes {self.yes}")
        if not 1 <= self.asks <= 5:
            raise ValueError(f"answer thresholds: asks must be 1-5 questions; got {self.asks}")

    def save(self, path: str | Path = DEFAULT_THRESHOLDS) -> Path:
        return atomic_write_text(json.dumps({"format": FORMAT, **asdict(self)}, indent=2) + "\n", path)

    @classmethod
    def load(cls, path: str | Path = DEFAULT_THRESHOLDS) -> AnswerThresholds:
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"answer thresholds {path} not found: choose them with "
                                    f"`python -m ncbot.speech.tune_answers`")
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as error:
            raise ValueError(f"{path} is not a JSON file of answer thresholds ({error})") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ValueError(f"{path} is not an answer thresholds file of format {FORMAT}")
        try:
            return cls(float(data["accept"]), float(data["confirm"]), float(data["yes"]), int(data["asks"]),
                       dict(data.get("meta", {})))
        except (KeyError, TypeError) as error:
            raise ValueError(f"{path}: answer thresholds need accept, confirm, yes and asks ({error})") from None


def phrase_confidence(confidences: Sequence[float]) -> float:
    """A heard phrase's confidence: its least sure word's (0 when nothing was heard)."""
    return float(min(confidences)) if len(confidences) else 0.0
