"""Name tables the logger needs to turn action ids into dialogue text, taken from the env once.

The env owns these tables (`env.action_names`, `env.templates`, `env.robot_commands`, `env.user_act_names`,
`env.feature_names`); the logger copies them so that it can run without the env (generic names) and so a
reader can show a dialogue from the file alone (they are stored as MCAP metadata `ncbot.names`).
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ncbot.envs.core import COLUMN_LETTERS  # light: plain constants

_GRIDLOC = re.compile(r"gridloc=(\d+)")
#: the paper's spelling of an act name -> what people read; the data, the env and the logs keep the paper's
#: `Provide(feedback=loose)` (Cuayahuitl 2019 names the act so), everything shown to a person says "lose"
SHOWN_SPELLING = {"feedback=loose": "feedback=lose"}


@dataclass
class NameTables:
    """Names of actions, their utterances and robot commands, user acts and features (all optional)."""

    action_names: list[str] = field(default_factory=list)
    templates: list[str] = field(default_factory=list)
    robot_commands: list[str] = field(default_factory=list)
    user_act_names: list[str] = field(default_factory=list)
    feature_names: list[str] = field(default_factory=list)
    user_utterances: list[str] = field(default_factory=list)
    game: str = ""  # the game's name (standard, ultimate or a declared game's); "" = unknown
    cols: int = 0  # columns of a declared game's board (cell names, board text); 0 = 3x3 or Ultimate

    @classmethod
    def from_env(cls, env: Any) -> "NameTables":
        """Copy whichever tables the env (or its base env under transforms) offers."""
        base = getattr(env, "base_env", env)

        def table(name: str) -> list[str]:
            value = getattr(env, name, None)
            if value is None:
                value = getattr(base, name, None)
            return [str(item) for item in value] if value is not None else []

        commands = table("robot_commands")
        describe = getattr(env, "describe_action", None) or getattr(base, "describe_action", None)
        if callable(describe):  # the full bracketed command, e.g. "who=rob, what=draw, where=b2"
            lines = [str(describe(act)) for act in range(len(table("action_names")))]
            commands = [line[line.rfind("[") + 1:-1] if line.endswith("]") else command
                        for line, command in zip(lines, commands or [""] * len(lines))]
        utterances: list[str] = []
        model = getattr(env, "model", None) or getattr(base, "model", None)
        if model is not None and getattr(model, "utterance_texts", None) is not None:
            utterances = [str(text) for text in model.utterance_texts]
        game, cols = "", 0
        if isinstance(getattr(base, "game", None), str):
            from ncbot.envs.games import make_game

            rules = getattr(base, "rules", None) or make_game(base.game)
            game, cols = rules.name, 0 if isinstance(rules.sheet_grid, int) else rules.cols
        return cls(table("action_names"), table("templates"), commands, table("user_act_names"),
                   table("feature_names"), utterances, game, cols)

    def action_name(self, act: int) -> str:
        """The act's name as a person reads it: GameMove(b2), not the dialogue data's GameMove(gridloc=4)."""
        if not 0 <= act < len(self.action_names):
            return f"act{act}"
        return self.readable(self.action_names[act])

    def readable(self, name: str) -> str:
        """An act name as a person reads it: GameMove(gridloc=4) -> GameMove(b2), Provide(feedback=loose) ->
        Provide(feedback=lose) (`SHOWN_SPELLING`)."""
        for paper, shown in SHOWN_SPELLING.items():
            name = name.replace(paper, shown)
        return _GRIDLOC.sub(lambda match: self.cell_name(int(match.group(1))), name)

    def cell_name(self, cell: int) -> str:
        """Cell index -> its name on the board (b2 style, as ``ncbot.envs.rules`` ``cell_name``); the board size follows
        from ``cols`` or, on a square board, the number of move acts (9 or 81)."""
        moves = sum(1 for name in self.action_names if _GRIDLOC.search(name)) or 9
        size = self.cols or math.isqrt(moves)
        return f"{COLUMN_LETTERS[cell % size]}{cell // size + 1}" if 0 <= cell < moves else str(cell)

    def template(self, act: int) -> str:
        return self.templates[act] if 0 <= act < len(self.templates) else ""

    def robot_command(self, act: int) -> str:
        return self.robot_commands[act] if 0 <= act < len(self.robot_commands) else ""

    def user_act_name(self, act: int) -> str:
        return self.user_act_names[act] if 0 <= act < len(self.user_act_names) else f"user_act{act}"

    def user_utterance(self, utterance: int) -> str:
        return self.user_utterances[utterance] if 0 <= utterance < len(self.user_utterances) else ""

    def word_columns(self) -> list[tuple[str, int]]:
        """(word, feature column) of each vocabulary word, in column order (the env names them `word[yes]`);
        a word the user said holds its ASR confidence there in the observation that follows."""
        cached = self.__dict__.get("_word_columns")
        if cached is None:
            cached = self.__dict__["_word_columns"] = [(name[5:-1], index) for index, name in enumerate(self.feature_names)
                                                       if name.startswith("word[") and name.endswith("]")]
        return cached

    def utterance_words(self) -> np.ndarray:
        """(utterances + 1, words) bool: which vocabulary words each user utterance contains; the last row
        (index -1) is silence. Lets the logger pick all ASR confidences of a batch with one numpy call."""
        cached = self.__dict__.get("_utterance_words")
        if cached is None:
            from ncbot.envs.dialogue import tokenize  # the env's own rule for turning text into word features

            position = {word: k for k, (word, _) in enumerate(self.word_columns())}
            cached = np.zeros((len(self.user_utterances) + 1, len(position)), bool)
            for row, text in enumerate(self.user_utterances):
                for word in tokenize(text):
                    if word in position:
                        cached[row, position[word]] = True
            self.__dict__["_utterance_words"] = cached
        return cached

    def to_metadata(self) -> dict[str, str]:
        """MCAP metadata values must be strings: one JSON list per table."""
        return {key: json.dumps(value) for key, value in asdict(self).items()}

    @classmethod
    def from_metadata(cls, metadata: dict[str, str]) -> "NameTables":
        known = {key: json.loads(value) for key, value in metadata.items() if key in cls.__dataclass_fields__}
        return cls(**known)
