"""One person's learning from play, kept in a folder: the reader's and the play's learners, game by game.

Folder layout (`ncbot robot play --learn --out DIR`: DIR/learning/PERSON; `ncbot robot serve --learn`: one per
participant, or one `pooled`; `ncbot learn LOGS --out DIR`: DIR):

    state.json          the commit point, written atomically after each game: games learned, each learner's counters
                        and current version, what every game taught (`per_game`)
    reader/             start.pt, reader.pt (the current classifier), game-NNNN.pt (every kept version),
                        examples/game-NNNN.npz (each game's settled cells)
    play/               start.pt, agent.pt (the current agent), game-NNNN.pt, transitions/game-NNNN.pt

A run that crashed resumes from state.json: files of a game it had not committed are ignored and rewritten.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.online.logged import LoggedGame
from ncbot.pipelines.online.play_learner import PlayLearner, PlayLearning
from ncbot.vision.online.adapt import ReaderLearner, ReaderLearning
from ncbot.vision.online.examples import View, settled_examples

STATE_NAME = "state.json"
FORMAT = "ncbot-learning/1"


@dataclass(frozen=True)
class LearnSettings:
    """What learns and how (the two learners' own settings)."""

    reader: ReaderLearning | None = field(default_factory=ReaderLearning)  # None: the reader stays as it is
    play: PlayLearning | None = None  # None: the play stays as it is (no agent checkpoint to learn from)

    @classmethod
    def default(cls, checkpoint: str | Path | None, every: int = 1, seed: int = 0,
                updates: int | None = None) -> "LearnSettings":
        """The reader learns (after every `every` games); the play too when there is an agent checkpoint (`updates`
        gradient steps a game; None: `PlayLearning`'s)."""
        play = None if checkpoint is None else \
            PlayLearning(seed=seed, **({} if updates is None else {"updates": updates}))
        return cls(ReaderLearning(every=every, seed=seed), play)


class PersonLearning:
    """The learners of one person (or of everyone, pooled) and what each game taught them."""

    def __init__(self, folder: Path, reader: ReaderLearner | None, play: PlayLearner | None,
                 per_game: list[dict[str, Any]], origin: dict[str, Any]) -> None:
        self.folder, self.reader, self.play, self.per_game, self.origin = folder, reader, play, per_game, origin

    @classmethod
    def open(cls, folder: str | Path, settings: LearnSettings, weights: str | Path | None = None,
             checkpoint: str | Path | None = None) -> "PersonLearning":
        """Resume the learning saved in `folder`, or start it from classifier `weights` (None: the shipped ones) and
        the agent `checkpoint` (None: the play does not learn)."""
        folder = Path(folder)
        state_path = folder / STATE_NAME
        if state_path.is_file():
            return cls._resume(folder, state_path)
        folder.mkdir(parents=True, exist_ok=True)
        reader = ReaderLearner.start(weights, settings.reader, folder / "reader") if settings.reader else None
        play = PlayLearner.start(checkpoint, settings.play, folder / "play") \
            if settings.play is not None and checkpoint is not None else None
        origin = {"weights": None if weights is None else str(weights),
                  "checkpoint": None if checkpoint is None else str(checkpoint)}
        learning = cls(folder, reader, play, [], origin)
        learning.commit()
        return learning

    @classmethod
    def _resume(cls, folder: Path, state_path: Path) -> "PersonLearning":
        try:
            state = json.loads(state_path.read_text(encoding="utf-8"))
            if state.get("format") != FORMAT:
                raise ValueError(f"format {state.get('format')!r}")
        except (OSError, ValueError) as error:
            raise ValueError(f"{state_path} is not a learning state written by ncbot ({str(error)[:80]}); expected "
                             f"the {STATE_NAME} of a learning folder") from None
        reader = play = None  # a resumed learner goes on with the settings it started with
        if state.get("reader") is not None:
            saved = ReaderLearning(**state["reader"]["settings"])
            reader = ReaderLearner.resume(folder / "reader", state["reader"], saved)
        if state.get("play") is not None:
            play = PlayLearner.resume(folder / "play", state["play"], PlayLearning(**state["play"]["settings"]))
        return cls(folder, reader, play, list(state.get("per_game", [])), dict(state.get("origin", {})))

    @property
    def games(self) -> int:
        """Games learned from so far (a resumed run continues after them)."""
        return len(self.per_game)

    def learn(self, views: list[View], moves: list[tuple[int, int]], robot_first: bool,
              game: LoggedGame | None, played: dict[str, Any] | None = None) -> dict[str, Any]:
        """Learn from one game: its looks at the sheet labelled by the settled `moves` ((cell, player), in order) for
        the reader, its logged transitions for the play; returns what it taught (kept in `per_game`, committed)."""
        from ncbot.robot_sim.settlement import labelled_moves

        index = self.games
        learned: dict[str, Any] = {"game": index, **(played or {})}
        if self.reader is not None:
            examples = settled_examples(views, labelled_moves(moves, robot_first), index)
            learned["reader"] = {**self.reader.add_game(examples).to_dict(), "views": len(views)}
        if self.play is not None and game is not None:
            learned["play"] = self.play.add_game(game).to_dict()
        self.per_game.append(learned)
        self.commit()
        return learned

    def commit(self) -> None:
        """state.json, atomically: the one file a resumed run trusts."""
        state = {"format": FORMAT, "origin": self.origin, "games": self.games,
                 "reader": None if self.reader is None else {**self.reader.state(), "settings": asdict(self.reader.settings)},
                 "play": None if self.play is None else {**self.play.state(), "settings": asdict(self.play.settings)},
                 "per_game": self.per_game}
        atomic_write_text(json.dumps(state, indent=1), self.folder / STATE_NAME)

    @property
    def reader_weights(self) -> str | None:
        """The updated classifier (the report's `learned_weights`)."""
        return None if self.reader is None else str(self.reader.weights_path)

    @property
    def play_weights(self) -> str | None:
        return None if self.play is None or self.play.folder is None else str(self.play.folder / "agent.pt")
