"""Everything the dialogue env precomputes: its flat step tables, its metadata (action and feature names) and specs.

Why tables: the env's step is a chain of 1-D ``index_select`` reads (the fastest gather on CPU) keyed by small
integers -- the act type, the "stage" of a game, the last (system act, user act) pair -- instead of ~12
whole-batch ops that rebuild the dialogue phase and context every step. This module builds those tables once
per env from the dialogue model (``ncbot.envs.dialogue``) and the engine; ``ncbot.envs.dialogue_env`` only reads them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from torchrl.data import Bounded, Categorical, Composite, Unbounded

import ncbot.envs.dialogue as dlg
from ncbot.envs.core import REWARD_ILLEGAL, REWARD_WIN, ROBOT
from ncbot.envs.readings import Readings

# Dialogue flags, kept multiplied by 8 so that ``engine.status`` (outcome * 2 + marks % 2, 0..7) + flags is the
# game's "stage" (0..63): all the phase depends on, one integer per game, and the index of the phase table.
ROBOT_FIRST, AGREED, CLOSED = 8, 16, 32
N_STAGES = 64
N_USER = 1 + len(dlg.USER_ACTS)  # values of the last user act: 0 none, else user act + 1


@dataclass(frozen=True)
class StepTables:
    """The env's flat step tables, each keyed by small integers (see the module doc); built once per env.

    Utterance id ``silence`` (one past the last) stands for silence inside the step; it is reported as -1. The
    ``code_*`` tables exist for an engine whose board code indexes a table of its legal squares and look-ahead
    (``engine.rows_by_code``): one row gather per question. ``act_lookahead`` exists for the others, whose move
    rewards are written into it every step (``engine.write_move_rewards``)."""

    silence: int
    act_type: torch.Tensor  # (A,) the act type of every action (0: a move)
    asks_move: torch.Tensor  # (types,) bool: the acts the user answers with its move (the set's shape)
    utterance_acts: torch.Tensor  # (U + 1,) the user act of each utterance (silence: -1)
    utterance_word_columns: torch.Tensor  # (U + 1, W) the feature columns of each utterance's words (padded)
    said_features: torch.Tensor  # (1 + types, C + V + 1) the commands + words of each said act type
    utterance_out: torch.Tensor  # (U + 1,) the utterance id reported (silence: -1)
    utterance_is_move: torch.Tensor  # (U + 1,) bool
    asr_scaled: bool  # ASR confidences are not the uniforms themselves
    stage_phase: torch.Tensor  # (N_STAGES,) the dialogue phase of every stage
    filter_table: torch.Tensor  # (talks * N_STAGES, A) bool: the act filter by talk * N_STAGES + stage
    said_flags: torch.Tensor  # (1 + types,) flags an accepted act sets
    talk_flags: torch.Tensor  # (talks,) flags a (system act, user reply) pair sets
    user_turn: torch.Tensor  # (types * phases,) bool: the user moves after (act type, phase)
    code_legal: torch.Tensor | None  # (codes, A) bool: legal acts by board code (dialogue acts all legal)
    code_rewards: torch.Tensor | None  # (codes, A) float32: the robot's one-step reward by board code
    code_wins: torch.Tensor | None  # (codes, A) bool: set A (win_set) by board code
    code_empty: torch.Tensor | None  # (codes, A) bool: taken_squares="misread": a believed board's empty squares
    act_lookahead: torch.Tensor | None  # (talks * N_STAGES, A) the look-ahead row before the moves' rewards


def step_tables(model: dlg.DialogueModel, engine: Any, n_actions: int, asr: tuple[float, float],
                readings: Readings) -> StepTables:
    """The env's step tables for ``model``, ``engine`` and the ``readings`` (``win_set``, ``taken_squares``)."""
    cells = engine.cells
    n_utt = len(model.utterance_texts)
    asks_move = torch.zeros(len(dlg.SYSTEM_TYPES), dtype=torch.bool)
    asks_move[list(model.user_moves_after)] = True  # the acts the user answers with its move (the set's shape)
    # the words of each utterance as column indices (padded with V, a spare column): ASR confidences are
    # drawn for these few words only (torch.rand costs ~10 ns per number, (B, V) draws dominated the step)
    words = torch.cat([model.utterance_words, torch.zeros(1, len(model.words))]) > 0
    width = max(1, int(words.sum(1).max()))
    order = torch.sort(words.to(torch.uint8), dim=1, descending=True, stable=True).indices[:, :width]
    present = torch.arange(width).unsqueeze(0) < words.sum(1, keepdim=True)
    # user words live in columns C.. of a (B, C + V) block whose first C (command) columns stay 0, so one
    # maximum with the robot's last act's commands + words row gives the whole tail of the observation
    n_commands = model.template_commands.shape[1]
    # the commands + words of each said act type (row 0: nothing said), plus the spare column the padding hits
    system_features = torch.cat([model.template_commands, model.template_words], dim=1)
    # phase of every stage (see ROBOT_FIRST); the filter by (talk = last system act * N_USER + last user act,
    # stage): one row gather per step instead of ~12 ops that build the phase and the context
    stage = torch.arange(N_STAGES)
    stage_phase = torch.tensor([
        dlg.phase_of(bool(flags & AGREED), bool(flags & CLOSED), status // 2, (status % 2 == 0) == bool(flags & ROBOT_FIRST))
        for status, flags in zip((stage % 8).tolist(), (stage // 8 * 8).tolist())
    ])
    allowed = model.filter_allowed.flatten(0, 2)  # (contexts, types) -> (contexts, actions)
    by_phase = torch.cat([allowed[:, :1].expand(-1, cells), allowed[:, 1:]], dim=1)
    n_talk = (1 + len(dlg.SYSTEM_TYPES)) * N_USER
    rows = (torch.arange(n_talk).unsqueeze(1) * len(dlg.PHASES) + stage_phase.unsqueeze(0)).reshape(-1)
    filter_table = by_phase.index_select(0, rows).contiguous()  # row talk * N_STAGES + stage
    # flags an accepted act sets (by act type + 1), and those a (system act, user reply) pair sets (by talk)
    said_flags = torch.zeros(1 + len(dlg.SYSTEM_TYPES), dtype=torch.int64)
    said_flags[dlg.REPLY_YES + 1], said_flags[dlg.CLOSING + 1] = AGREED, CLOSED
    talk_flags = torch.zeros(n_talk, dtype=torch.int64)
    talk_flags[(dlg.REQUEST_PLAY + 1) * N_USER + dlg.USER_YES + 1] = AGREED
    return StepTables(
        silence=n_utt,
        act_type=torch.cat([torch.zeros(cells, dtype=torch.int64), torch.arange(1, len(dlg.SYSTEM_TYPES))]),
        asks_move=asks_move,
        utterance_acts=torch.cat([model.utterance_acts, torch.tensor([-1])]),
        utterance_word_columns=torch.where(present, order + n_commands, n_commands + len(model.words)),
        said_features=torch.cat([system_features, torch.zeros(len(system_features), 1)], dim=1),
        utterance_out=torch.cat([torch.arange(n_utt), torch.tensor([-1])]),  # silence is reported as -1
        utterance_is_move=torch.cat([model.utterance_acts == dlg.USER_MOVE, torch.tensor([False])]),
        asr_scaled=tuple(asr) != (0.0, 1.0),  # else confidences are the uniforms themselves
        stage_phase=stage_phase,
        filter_table=filter_table,
        said_flags=said_flags,
        talk_flags=talk_flags,
        # the user moves after (act type, phase) = a move or "your turn" while it is the user's turn
        user_turn=(asks_move.unsqueeze(1) & (torch.arange(len(dlg.PHASES)) == dlg.USER_TO_MOVE)).reshape(-1),
        **_lookahead_tables(engine, n_actions, filter_table, readings),
    )


def _lookahead_tables(engine: Any, n_actions: int, filter_table: torch.Tensor, readings: Readings) -> dict[str, Any]:
    """The look-ahead's tables: by board code where the engine tabulates its codes (``rows_by_code``), else the row
    the moves' rewards are written into (allowed dialogue acts 0, the rest and every square -5)."""
    cells = engine.cells
    if not hasattr(engine, "rows_by_code"):
        acts = torch.where(filter_table, 0.0, REWARD_ILLEGAL)
        acts[:, :cells] = REWARD_ILLEGAL
        return {"code_legal": None, "code_rewards": None, "code_wins": None, "code_empty": None,
                "act_lookahead": acts.contiguous()}
    legal, rewards = engine.rows_by_code(ROBOT)
    talk_acts = n_actions - cells  # padded to all actions: dialogue acts legal, their reward 0
    code_rewards = torch.cat([rewards, torch.zeros(len(rewards), talk_acts)], dim=1).contiguous()
    if readings.win_set == "wins_and_threats":
        code_wins = (code_rewards == REWARD_WIN).contiguous()  # winning_actions = mask & this row
    else:  # win_set="wins": only the squares that win the game now
        wins = engine.winning_rows_by_code(ROBOT)
        code_wins = torch.cat([wins, torch.zeros(len(wins), talk_acts, dtype=torch.bool)], dim=1).contiguous()
    code_empty = None
    if readings.misread:  # the believed board's empty squares, by its code (a believed line does not stop the game)
        empty = engine.empty_rows_by_code()
        code_empty = torch.cat([empty, torch.ones(len(empty), talk_acts, dtype=torch.bool)], dim=1)
    return {"code_legal": torch.cat([legal, torch.ones(len(legal), talk_acts, dtype=torch.bool)], dim=1).contiguous(),
            "code_rewards": code_rewards, "code_wins": code_wins, "code_empty": code_empty, "act_lookahead": None}


def reply_tables(model: dlg.DialogueModel, silence: int, utterance_is_move: torch.Tensor,
                 user_turn: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(contexts,) reply counts and the flat (contexts * (K + 1)) utterance ids of the simulated user, where
    context = act type * phases + phase.

    Column 0 of a context without replies holds silence, and column K repeats column K - 1, so the pick
    ``floor(u * count)`` needs neither the ``count > 0`` test nor a clamp: same utterances as reading
    ``reply_options`` with ``min(pick, K - 1)`` and silencing contexts without replies. A move utterance in
    a context where the user does not move (an act the data never shows; ``ncbot play`` can set one) is
    silence too, as the user says nothing it cannot do.
    """
    options, counts = model.reply_options, model.reply_counts
    flat = options.reshape(-1, options.shape[-1])
    replies = torch.cat([flat, flat[:, -1:]], dim=1)
    replies[counts.reshape(-1) == 0, 0] = silence
    moves_without_move = utterance_is_move[replies] & ~user_turn.unsqueeze(1)
    replies[moves_without_move] = silence
    return counts.reshape(-1).clone(), replies.reshape(-1).contiguous()


@dataclass(frozen=True)
class EnvDescription:
    """What the env's actions and features are: the tables ``ncbot env describe`` prints and the logs name."""

    action_names: tuple[str, ...]
    templates: tuple[str, ...]  # the robot's line of each action
    robot_commands: tuple[str, ...]  # the bracketed command of each action
    user_act_names: tuple[str, ...]
    words: tuple[str, ...]
    feature_names: tuple[str, ...]

    @property
    def n_actions(self) -> int:
        return len(self.action_names)

    @property
    def n_features(self) -> int:
        return len(self.feature_names)


def describe(model: dlg.DialogueModel, cells: int, temporal: bool, threat_names: list[str] | None = None) -> EnvDescription:
    """The env's actions and features: moves first, then the dialogue acts; the mark features, commands, words,
    the temporal features (``temporal``) and the game's threat planes (``threat_names``, env option
    ``threat_features``)."""
    action_names = dlg.action_names(cells)
    width = len(str(cells - 1))
    names = [f"robot_move[{c:0{width}d}]" for c in range(cells)]
    names += [f"human_move[{c:0{width}d}]" for c in range(cells)]
    names += [f"command[{c}]" for c in dlg.ROBOT_COMMANDS]
    names += [f"word[{w}]" for w in model.words]
    if temporal:
        names += [f"time[{c:0{width}d}]" for c in range(cells)]
    names += threat_names or []
    return EnvDescription(
        action_names=tuple(action_names),
        templates=(model.templates[0],) * cells + tuple(model.templates[1:]),
        robot_commands=(dlg.TYPE_COMMANDS[0],) * cells + tuple(dlg.TYPE_COMMANDS[1:]),
        user_act_names=tuple(dlg.USER_ACTS),
        words=tuple(model.words),
        feature_names=tuple(names),
    )


@dataclass(frozen=True)
class EnvSpecs:
    """The env's TorchRL specs."""

    observation: Composite
    action: Categorical
    reward: Unbounded
    done: Composite


def make_specs(batch: int, cells: int, n_actions: int, n_features: int, n_utterances: int) -> EnvSpecs:
    """The env's observation, action, reward and done specs."""
    shape = torch.Size([batch])

    def flag(width: int) -> Categorical:
        return Categorical(2, shape=(batch, width), dtype=torch.bool)

    def ints(low: int, high: int, width: int = 1, dtype=torch.int64) -> Bounded:
        return Bounded(low=low, high=high, shape=(batch, width), dtype=dtype)

    observation = Composite(
        observation=Bounded(low=0.0, high=1.0, shape=(batch, n_features), dtype=torch.float32),
        action_mask=flag(n_actions),
        dialogue_mask=flag(n_actions),
        lookahead_reward=Bounded(low=-5.0, high=5.0, shape=(batch, n_actions), dtype=torch.float32),
        winning_actions=flag(n_actions),
        board=ints(0, 2, cells, torch.int8),
        outcome=ints(0, 3, 1, torch.int8),
        robot_first=flag(1),
        turn=Unbounded(shape=(batch, 1), dtype=torch.int64),
        user_act=ints(-1, len(dlg.USER_ACTS) - 1),
        user_move=ints(-1, cells - 1),
        user_utterance=ints(-1, n_utterances - 1),
        shape=shape,
    )
    return EnvSpecs(observation=observation, action=Categorical(n_actions, shape=shape, dtype=torch.int64),
                    reward=Unbounded(shape=(batch, 1), dtype=torch.float32),
                    done=Composite(done=flag(1), terminated=flag(1), truncated=flag(1), shape=shape))
