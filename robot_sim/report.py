"""What one robot game did (`GameRecord`, judged on the true board) and the JSON report of `ncbot robot play`."""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ncbot.fileio import atomic_write_text
from ncbot.robot_sim.game_config import RobotPlayConfig


@dataclass
class GameRecord:
    """What happened in one game, judged on the true board."""

    index: int
    outcome: str                      # win | draw | loss | unfinished (robot's view of the true game)
    robot_first: bool
    actions: int
    misrecognised_moves: int = 0
    unseen_moves: int = 0
    human_moves: int = 0
    robot_moves: int = 0
    robot_move_seconds: list[float] = field(default_factory=list)
    #: CPU time of the process (all threads, incl. lavapipe's) per robot move: the cost without other jobs' load.
    robot_move_cpu_seconds: list[float] = field(default_factory=list)
    dialogue_act_seconds: list[float] = field(default_factory=list)
    human_turn_seconds: list[float] = field(default_factory=list)
    frames: int = 0
    snapshot: str | None = None
    ik_failures: int = 0
    #: Largest distance (m) between where the robot believed its target cell was and where it really was.
    cell_localisation_error: float = 0.0
    #: Robot moves whose fresh mark the robot's own look at the sheet did not read.
    own_mark_misreads: int = 0
    #: The scene this game was played in (`SceneConditions.summary()`).
    conditions: dict[str, Any] = field(default_factory=dict)
    #: Camera frames kept for misrecognised or unseen moves (with --out).
    evidence: list[str] = field(default_factory=list)
    #: Where a robot move's wall time went: rendering frames, and synthesising its utterance.
    robot_move_render_seconds: list[float] = field(default_factory=list)
    robot_move_tts_seconds: list[float] = field(default_factory=list)
    #: Real speech (`speech: real`): utterances spoken per speaker, and what the recogniser made of the person's.
    utterances: dict[str, int] = field(default_factory=dict)
    robot_tts_seconds: float = 0.0
    asr_words: int = 0
    asr_word_errors: int = 0
    asr_confidences: list[float] = field(default_factory=list)
    #: The person's replies understood as the utterance said (speech.understand).
    asr_understood: int = 0
    person_tts_seconds: list[float] = field(default_factory=list)
    asr_seconds: list[float] = field(default_factory=list)
    #: CPU seconds of each decode (steadier than wall time on a shared machine).
    asr_cpu_seconds: list[float] = field(default_factory=list)
    #: Unseen moves asked about aloud (robot_sim.where): the person's answers heard, their words and word errors,
    #: moves settled by an answer, those of them in a cell the person did not draw in, and moves the answers did
    #: not settle (the robot then looked again).
    cell_answers: int = 0
    cell_answer_words: int = 0
    cell_answer_word_errors: int = 0
    cell_answer_cpu_seconds: list[float] = field(default_factory=list)
    cells_from_answers: int = 0
    misheard_cells: int = 0
    answer_fallbacks: int = 0
    #: Looks at the sheet after settled moves: (scene seconds, moves made by then); and the game's (cell, player)
    #: moves as both sides agreed on them at its end (`robot_sim.settlement`).
    view_times: list[tuple[float, int]] = field(default_factory=list)
    settled_moves: list[tuple[int, int]] | None = None
    #: What the robot learned from this game (`ncbot robot play --learn`), else None.
    learned: dict[str, Any] | None = None
    #: How answered cells were settled (robot_sim.where): taken as heard, confirmed aloud, touched on the tablet;
    #: confirmations asked; "where did you draw?" asked again; a dialogue act the robot said again at once (for any
    #: reason: also after the person's "no thank you" heard right) and, of those, the ones said again right after
    #: a reply the robot did not understand as said (heard as nothing or as another utterance: real speech only).
    cells_accepted: int = 0
    confirmations: int = 0
    tablet_fallbacks: int = 0
    where_repeats: int = 0
    dialogue_repeats: int = 0
    dialogue_asked_again: int = 0
    #: Pepper's array (`ears: array`): CPU seconds of each reply's enhancement, what aimed each beam (camera | doa)
    #: and how far each beam was from the person's true direction (degrees).
    enhancement_cpu_seconds: list[float] = field(default_factory=list)
    steered_by: dict[str, int] = field(default_factory=dict)
    beam_errors_deg: list[float] = field(default_factory=list)


def count_repeat(record: GameRecord, repeat: bool, understood: bool) -> None:
    """Count a dialogue act said again at once; asked again (the robot did not understand) when the reply before it
    was not understood as said."""
    record.dialogue_repeats += int(repeat)
    record.dialogue_asked_again += int(repeat and not understood)


def games_report(records: list[GameRecord], config: RobotPlayConfig) -> dict[str, Any]:
    """The JSON report of `ncbot robot play` (the headline keys first, then details)."""
    moves = [s for r in records for s in r.robot_move_seconds]
    moves_cpu = [s for r in records for s in r.robot_move_cpu_seconds]
    acts = [s for r in records for s in r.dialogue_act_seconds]
    human = [s for r in records for s in r.human_turn_seconds]

    def mean(values: list[float]) -> float | None:
        return round(float(np.mean(values)), 3) if values else None

    real = config.speech == "real"  # with text speech nothing is heard: the ASR keys are null
    array = real and config.ears == "array"
    asr_cpu = [s for r in records for s in r.asr_cpu_seconds]
    enhance_cpu = [s for r in records for s in r.enhancement_cpu_seconds]
    said = sum(r.asr_words for r in records)
    heard = [c for r in records for c in r.asr_confidences]
    replies = sum(r.utterances.get("user", 0) for r in records)
    answer_words = sum(r.cell_answer_words for r in records)

    return {
        "games": len(records),
        "wins": sum(r.outcome == "win" for r in records),
        "draws": sum(r.outcome == "draw" for r in records),
        "losses": sum(r.outcome == "loss" for r in records),
        "misrecognised_moves": sum(r.misrecognised_moves for r in records),
        "seconds_per_robot_turn": mean(moves),
        "conditions": config.conditions,
        "unfinished": sum(r.outcome == "unfinished" for r in records),
        "unseen_moves": sum(r.unseen_moves for r in records),
        "speech": config.speech,
        "asr_word_error_rate": round(sum(r.asr_word_errors for r in records) / said, 4) if real and said else None,
        "asr_mean_confidence": round(float(np.mean(heard)), 4) if real and heard else None,
        "asr_utterances": replies if real else None,
        "asr_understood_rate": round(sum(r.asr_understood for r in records) / replies, 4) if real and replies else None,
        "robot_utterances": sum(r.utterances.get("robot", 0) for r in records) if real else None,
        "cell_answers": sum(r.cell_answers for r in records) if real else None,
        "cell_answer_word_error_rate": (round(sum(r.cell_answer_word_errors for r in records) / answer_words, 4)
                                        if real and answer_words else None),
        "cells_from_answers": sum(r.cells_from_answers for r in records) if real else None,
        "misheard_cells": sum(r.misheard_cells for r in records) if real else None,
        "answer_fallbacks": sum(r.answer_fallbacks for r in records) if real else None,
        "hearing": config.ears if real else None,
        "answers": config.answers if real else None,
        "cells_accepted": sum(r.cells_accepted for r in records) if real else None,
        "confirmations": sum(r.confirmations for r in records) if real else None,
        "tablet_fallbacks": sum(r.tablet_fallbacks for r in records),
        "repeated_questions": sum(r.where_repeats + r.dialogue_repeats for r in records),
        "where_repeats": sum(r.where_repeats for r in records),
        "dialogue_repeats": sum(r.dialogue_repeats for r in records),
        "asked_again": sum(r.where_repeats + r.dialogue_asked_again for r in records),
        "enhancement": config.enhancement if array else None,
        "steered_by_camera": sum(r.steered_by.get("camera", 0) for r in records) if array else None,
        "steered_by_doa": sum(r.steered_by.get("doa", 0) for r in records) if array else None,
        "beam_error_deg": mean([e for r in records for e in r.beam_errors_deg]) if array else None,
        "enhancement_cpu_seconds_per_utterance": mean(enhance_cpu) if array else None,
        "enhancement_to_asr_cpu": (round(float(np.mean(enhance_cpu)) / max(float(np.mean(asr_cpu)), 1e-9), 3)
                                   if array and enhance_cpu and asr_cpu else None),
        "render_seconds_per_robot_turn": mean([s for r in records for s in r.robot_move_render_seconds]),
        "tts_seconds_per_robot_turn": mean([s for r in records for s in r.robot_move_tts_seconds]) if real else None,
        "person_tts_seconds_per_utterance": mean([s for r in records for s in r.person_tts_seconds]) if real else None,
        "asr_seconds_per_utterance": mean([s for r in records for s in r.asr_seconds]) if real else None,
        "asr_cpu_seconds_per_utterance": mean(asr_cpu) if real else None,
        "human_moves": sum(r.human_moves for r in records),
        "robot_moves": sum(r.robot_moves for r in records),
        "own_mark_misread": sum(r.own_mark_misreads for r in records),
        "max_seconds_per_robot_turn": round(max(moves), 3) if moves else None,
        "cpu_seconds_per_robot_turn": mean(moves_cpu),
        "load_average": round(os.getloadavg()[0], 2),
        "seconds_per_dialogue_act": mean(acts),
        "seconds_per_human_turn": mean(human),
        "frames": sum(r.frames for r in records),
        "ik_failures": sum(r.ik_failures for r in records),
        "max_cell_localisation_error_mm": round(1000 * max((r.cell_localisation_error for r in records), default=0.0), 2),
        "game": config.game,
        "agent": config.agent_name,
        "seed": config.seed,
        "snapshots": [r.snapshot for r in records if r.snapshot],
        "evidence": [path for r in records for path in r.evidence],
        "game_conditions": [r.conditions for r in records],
        "per_game": [per_game(r) for r in records],
        "learned_weights": None,  # set by a run that learns from play (ncbot.pipelines.online)
    }


def per_game(record: GameRecord) -> dict[str, Any]:
    """One game of the report's `per_game`: its outcome, the moves it misread or missed, what was learned from it."""
    return {"game": record.index, "outcome": record.outcome, "human_moves": record.human_moves,
            "misrecognised_moves": record.misrecognised_moves, "unseen_moves": record.unseen_moves,
            "handwriting": record.conditions.get("handwriting"), "learned": record.learned}


def annotated_snapshot(image_bgr: np.ndarray, record: GameRecord) -> np.ndarray:
    """The game's last camera frame with its outcome written across the top (the `game-NNN.png` snapshot)."""
    import cv2

    image = image_bgr.copy()
    text = f"game {record.index}: {record.outcome}  misrecognised {record.misrecognised_moves}"
    cv2.rectangle(image, (0, 0), (image.shape[1], 30), (32, 32, 32), -1)
    cv2.putText(image, text, (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return image


def write_report(report: dict[str, Any], out_dir: str | Path) -> Path:
    """`report.json` in `out_dir`, written atomically."""
    return atomic_write_text(json.dumps(report, indent=2), Path(out_dir) / "report.json")
