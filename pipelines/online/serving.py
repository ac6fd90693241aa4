"""`ncbot robot serve --learn`: each browser session's games teach the robot, per person or pooled.

A person is named by the participant code typed on the start page (a later session with the same code resumes
their learning), else by the session's id; `--pooled` puts everyone's games into one learning. Learners of one
folder are shared by the sessions using it, and a game is learned from under the policy's lock, so no session's
robot decides while the agent it plays with is being updated.
"""
from __future__ import annotations

import contextlib
import re
import threading
from pathlib import Path
from typing import Any

from ncbot.pipelines.online.learning import LearnSettings, PersonLearning
from ncbot.pipelines.online.robot_games import LearningRunner

POOLED = "pooled"
_OPEN: dict[Path, PersonLearning] = {}
_OPEN_LOCK = threading.Lock()


def person_folder(out: str | Path, person: str) -> Path:
    """Where a person's learning lives in a study folder (a participant code made a safe folder name)."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", person).lstrip(".") or "_"
    return Path(out) / "learning" / name[:64]


def open_learning(out: str | Path, person: str, weights: str | None, checkpoint: str | None,
                  seed: int) -> PersonLearning:
    """The learning of `person` (resumed from the study folder, or started), shared by every session using it."""
    folder = person_folder(out, person)
    with _OPEN_LOCK:
        if folder not in _OPEN:
            _OPEN[folder] = PersonLearning.open(folder, LearnSettings.default(checkpoint, seed=seed), weights=weights,
                                                checkpoint=checkpoint)
        return _OPEN[folder]


def session_learning(config: Any, person: str, policy_lock: Any) -> "SessionLearning | None":
    """With `config.learn` (a `ServeConfig`): the session's learning for `person` (or the pooled one), else None.
    `policy_lock`: what every session's policy calls hold (None: the session holds the one simulator lock while it
    plays, so nothing else decides meanwhile)."""
    if not config.learn:
        return None
    learning = open_learning(config.out, POOLED if config.pooled else person, config.weights, config.checkpoint,
                             config.seed)
    return SessionLearning(learning, contextlib.nullcontext() if policy_lock is None else policy_lock)


class SessionLearning:
    """One session's side of learning: the person's policy to play with, and the hook after each game."""

    def __init__(self, learning: PersonLearning, lock: Any) -> None:
        self.learning, self.lock, self.hook = learning, lock, None

    @property
    def policy(self) -> Any:
        """The person's learning agent, or None when the play does not learn (no checkpoint)."""
        return None if self.learning.play is None else self.learning.play.policy

    def attach(self, runner: Any) -> None:
        self.hook = LearningRunner(self.learning, runner)

    def after_game(self, runner: Any, record: Any) -> None:
        with self.lock:
            self.hook.after_game(runner, record)
