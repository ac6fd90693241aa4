"""Name tables the logger needs to turn action ids into dialogue text, taken from the env once.

The env owns these tables (`env.action_names`, `env.templates`, `env.robot_commands`, `env.user_act_names`,
`env.feature_names`); the logger copies them so that it can run without the env (generic names) and so a
reader can show a dialogue from the file alone (they are stored as MCAP metadata `ncbot.names`).
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass
class NameTables:
    """Names of actions, their utterances and robot commands, user acts and features (all optional)."""

    action_names: list[str] = field(default_factory=list)
    templates: list[str] = field(default_factory=list)
    robot_commands: list[str] = field(default_factory=list)
    user_act_names: list[str] = field(default_factory=list)
    feature_names: list[str] = field(default_factory=list)

    @classmethod
    def from_env(cls, env: Any) -> "NameTables":
        """Copy whichever tables the env (or its base env under transforms) offers."""
        base = getattr(env, "base_env", env)

        def table(name: str) -> list[str]:
            value = getattr(env, name, None)
            if value is None:
                value = getattr(base, name, None)
            return [str(item) for item in value] if value is not None else []

        return cls(table("action_names"), table("templates"), table("robot_commands"),
                   table("user_act_names"), table("feature_names"))

    def action_name(self, act: int) -> str:
        return self.action_names[act] if 0 <= act < len(self.action_names) else f"act{act}"

    def template(self, act: int) -> str:
        return self.templates[act] if 0 <= act < len(self.templates) else ""

    def robot_command(self, act: int) -> str:
        return self.robot_commands[act] if 0 <= act < len(self.robot_commands) else ""

    def user_act_name(self, act: int) -> str:
        return self.user_act_names[act] if 0 <= act < len(self.user_act_names) else f"user_act{act}"

    def user_word_columns(self) -> list[tuple[int, str]]:
        """Feature columns that hold user words (their value is the ASR confidence), as (index, word)."""
        columns = []
        for index, name in enumerate(self.feature_names):
            lowered = name.lower()
            for prefix in ("user_word:", "user_word=", "usr_word:", "user:", "uword:"):
                if lowered.startswith(prefix):
                    columns.append((index, name[len(prefix):]))
                    break
        return columns

    def to_metadata(self) -> dict[str, str]:
        """MCAP metadata values must be strings: one JSON list per table."""
        return {key: json.dumps(value) for key, value in asdict(self).items()}

    @classmethod
    def from_metadata(cls, metadata: dict[str, str]) -> "NameTables":
        known = {key: json.loads(value) for key, value in metadata.items() if key in cls.__dataclass_fields__}
        return cls(**known)
