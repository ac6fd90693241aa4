"""Topic names and JSON Schemas of ncbot's own MCAP channels.

Our channels are JSON with a registered JSON Schema: readable with any MCAP tool and in Foxglove's raw
message / plot panels, and within a few percent of protobuf in size once zstd has compressed a chunk
(see `logs/README.md` for the measurement). Foxglove's own types (images, transforms, joint states) are
written as protobuf because that is what Foxglove and rerun's MCAP importer display natively.
"""
from __future__ import annotations

import json
from typing import Any

from ncbot.envs.core import OUTCOME_NAMES

SCHEMA_VERSION = 1

EPISODE_TOPIC = "/episode"
EPISODE_STEPS_TOPIC = "/episode/steps"
STEP_TOPIC = "/step"
DIALOGUE_TOPIC = "/dialogue"
BOARD_TOPIC = "/board"
BOARD_IMAGE_TOPIC = "/board/image"
CAMERA_TOPIC = "/camera/bottom/compressed"
JOINT_STATES_TOPIC = "/joint_states"
TRANSFORM_TOPIC = "/tf"

#: The channels that identify a file as an ncbot episode log (a foreign MCAP has none of them).
NCBOT_TOPICS = (EPISODE_TOPIC, EPISODE_STEPS_TOPIC, STEP_TOPIC, DIALOGUE_TOPIC, BOARD_TOPIC)
#: How the steps of a phase are written: one message per action on /step, /dialogue, /board ("per_action"),
#: one columnar message per episode on /episode/steps ("packed"), or not at all ("none").
STEP_DETAIL_CHOICES = ("per_action", "packed", "none")

PHASES = ("train", "eval", "robot", "play")
#: Outcome names from the robot's point of view, indexed by the env's `outcome` code.
OUTCOMES = OUTCOME_NAMES  # the robot's view of outcome codes 0..3, defined once in envs.core

_INT_LIST = {"type": "array", "items": {"type": "integer"}}
_NUM_LIST = {"type": "array", "items": {"type": "number"}}

EPISODE_SCHEMA: dict = {
    "title": "ncbot.Episode",
    "description": "One finished game/dialogue, written after its last step.",
    "type": "object",
    "properties": {
        "episode": {"type": "integer", "description": "run-wide episode id"},
        "phase": {"enum": list(PHASES)},
        "game": {"type": "string", "description": "standard, ultimate or a declared game's name (docs/games.md)"},
        "agent": {"type": "string"},
        "seed": {"type": "integer"},
        "seat": {"enum": ["first", "second"], "description": "robot moved first or second"},
        "outcome": {"enum": list(OUTCOMES), "description": "robot's view; none = cut off without a result"},
        "return": {"type": "number", "description": "sum of rewards"},
        "length": {"type": "integer", "description": "robot actions (dialogue length)"},
        "task_success": {"type": "boolean", "description": "robot won or drew"},
        "truncated": {"type": "boolean", "description": "ended by the 100-action limit"},
        "epsilon": {"type": ["number", "null"]},
        "env_steps": {"type": ["integer", "null"], "description": "env steps of training so far"},
        "wall_time": {"type": "number", "description": "seconds since the logger opened"},
        "extra": {"type": "object", "description": "free-form additions (e.g. robot-sim figures)"},
    },
    "required": ["episode", "phase", "game", "agent", "seed", "seat", "outcome", "return", "length",
                 "task_success"],
}

STEP_SCHEMA: dict = {
    "title": "ncbot.Step",
    "description": "One robot decision. Action lists hold action ids; q holds Q-values of the ids in `mask` "
                   "in the same order. Features are sparse: `on` = indices equal to 1, `val` = [index, value] "
                   "pairs for the other non-zero features.",
    "type": "object",
    "properties": {
        "episode": {"type": "integer"},
        "step": {"type": "integer", "description": "0-based index of the action in its episode"},
        "who": {"enum": ["robot", "user"]},
        "act": {"type": "integer", "description": "dialogue act id"},
        "act_name": {"type": "string"},
        "mask": _INT_LIST,
        "A": {**_INT_LIST, "description": "look-ahead set A (winning actions, else all available)"},
        "A_hat": {**_INT_LIST, "description": "look-ahead set A_hat (available actions with negative reward)"},
        "q": {**_NUM_LIST, "description": "Q-values of the available actions, aligned with mask"},
        "reward": {"type": "number"},
        "on": _INT_LIST,
        "val": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
    },
    "required": ["episode", "step", "who", "act", "mask", "reward"],
}

DIALOGUE_SCHEMA: dict = {
    "title": "ncbot.DialogueTurn",
    "description": "One utterance: the robot's (with its robot command) or the user's (with ASR confidences).",
    "type": "object",
    "properties": {
        "episode": {"type": "integer"},
        "step": {"type": "integer"},
        "speaker": {"enum": ["robot", "user"]},
        "act": {"type": "integer"},
        "act_name": {"type": "string"},
        "text": {"type": "string"},
        "command": {"type": "string", "description": "bracketed robot command, e.g. who=rob, what=draw"},
        "move": {"type": "integer", "description": "cell taken with this turn, -1 none"},
        "words": {"type": "array", "items": {"type": "array"},
                  "description": "user words as [word, ASR confidence] pairs"},
        "heard": {"type": "string", "description": "real speech: what the recogniser heard (may be empty)"},
        "heard_words": {"type": "array", "items": {"type": "array"},
                        "description": "real speech: the recogniser's words as [word, confidence] pairs"},
        "snr_db": {"type": ["number", "null"], "description": "real speech: SNR of the background noise, null clean"},
        "audio": {"type": "array", "description": "real speech: this turn's utterances on /audio/robot or "
                  "/audio/user (foxglove.RawAudio, pcm-s16, 16 kHz mono), each with its text and where it is",
                  "items": {"type": "object", "properties": {
                      "topic": {"type": "string"}, "t": {"type": "number", "description": "message timestamp, s"},
                      "seconds": {"type": "number"}, "text": {"type": "string"}}}},
        "cell_answers": {"type": "array", "description": "real speech: the person's spoken answers to the robot's "
                         "questions about a move its camera missed (robot_sim.where), in order",
                         "items": {"type": "object", "properties": {
                             "question": {"type": "string"}, "said": {"type": "string"}, "heard": {"type": "string"},
                             "heard_words": {"type": "array", "items": {"type": "array"}},
                             "understood": {"type": "integer", "description": "to 'where': the cell the words name; to "
                                            "'did you say': 1 yes, 0 no; -1 neither"},
                             "snr_db": {"type": ["number", "null"]},
                             "t": {"type": "number", "description": "the answer's /audio/user timestamp, s"}}}},
    },
    "required": ["episode", "step", "speaker", "act"],
}

BOARD_SCHEMA: dict = {
    "title": "ncbot.Board",
    "description": "The board after a step: one digit per cell, row-major on the full grid "
                   "(0 empty, 1 robot, 2 human); 9 or 81 characters.",
    "type": "object",
    "properties": {
        "episode": {"type": "integer"},
        "step": {"type": "integer"},
        "cells": {"type": "string", "pattern": "^[012]+$"},
        "size": {"type": "integer", "description": "side length: 3 or 9"},
    },
    "required": ["episode", "step", "cells", "size"],
}

JSON_SCHEMAS: dict[str, dict] = {
    EPISODE_TOPIC: EPISODE_SCHEMA,
    STEP_TOPIC: STEP_SCHEMA,
    DIALOGUE_TOPIC: DIALOGUE_SCHEMA,
    BOARD_TOPIC: BOARD_SCHEMA,
}


def schema_bytes(schema: dict) -> bytes:
    """The schema as written into the MCAP Schema record (compact JSON)."""
    return json.dumps({"$schema": "https://json-schema.org/draft/2020-12/schema", **schema},
                      separators=(",", ":")).encode()


def checked_message(message: dict[str, Any], schema: dict) -> dict[str, Any]:
    """A copy of `message`; ValueError naming the keys `schema` requires that it lacks."""
    missing = [key for key in schema["required"] if key not in message]
    if missing:
        raise ValueError(f"{schema['title']} message is missing {', '.join(missing)}; required: "
                         f"{', '.join(schema['required'])}")
    return dict(message)


def check_phase(phase: str) -> None:
    """ValueError naming the phases unless `phase` is one of them."""
    if phase not in PHASES:
        raise ValueError(f"phase must be one of {', '.join(PHASES)}, got {phase!r}")
