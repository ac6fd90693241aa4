"""Everything the dialogue env precomputes: its flat step tables, its metadata (action and feature names) and specs.

Why tables: the env's step is a chain of 1-D ``index_select`` reads (the fastest gather on CPU) keyed by small
integers -- the act type, the "stage" of a game, the last (system act, user act) pair -- instead of ~12
whole-batch ops that rebuild the dialogue phase and context every step. This module builds those tables once
per env from the dialogue model (``ncbot.envs.dialogue``) and the engine; ``ncbot.envs.dialogue_env`` only reads them.
"""
from __future__ import annotations

from typing import Any

import torch
from torchrl.data import Bounded, Categorical, Composite, Unbounded

import ncbot.envs.dialogue as dlg
from ncbot.envs.core import REWARD_ILLEGAL, REWARD_WIN, ROBOT

# Dialogue flags, kept multiplied by 8 so that ``engine.status`` (outcome * 2 + marks % 2, 0..7) + flags is the
# game's "stage" (0..63): all the phase depends on, one integer per game, and the index of the phase table.
ROBOT_FIRST, AGREED, CLOSED = 8, 16, 32
N_STAGES = 64
N_USER = 1 + len(dlg.USER_ACTS)  # values of the last user act: 0 none, else user act + 1


def step_tables(model: dlg.DialogueModel, engine: Any, n_actions: int, asr: tuple[float, float]) -> dict[str, Any]:
    """The env's step tables by attribute name (the env sets each as ``self.<name>``).

    Utterance id ``U`` (one past the last) stands for silence inside the step; it is reported as -1.
    """
    cells = engine.cells
    n_utt = len(model.utterance_texts)
    t: dict[str, Any] = {"_silence": n_utt}
    t["_act_type"] = torch.cat([torch.zeros(cells, dtype=torch.int64), torch.arange(1, len(dlg.SYSTEM_TYPES))])
    asks_move = torch.zeros(len(dlg.SYSTEM_TYPES), dtype=torch.bool)
    asks_move[list(model.user_moves_after)] = True  # the acts the user answers with its move (the set's shape)
    t["_asks_move"] = asks_move
    t["_utterance_acts"] = torch.cat([model.utterance_acts, torch.tensor([-1])])
    # the words of each utterance as column indices (padded with V, a spare column): ASR confidences are
    # drawn for these few words only (torch.rand costs ~10 ns per number, (B, V) draws dominated the step)
    words = torch.cat([model.utterance_words, torch.zeros(1, len(model.words))]) > 0
    width = max(1, int(words.sum(1).max()))
    order = torch.sort(words.to(torch.uint8), dim=1, descending=True, stable=True).indices[:, :width]
    present = torch.arange(width).unsqueeze(0) < words.sum(1, keepdim=True)
    # user words live in columns C.. of a (B, C + V) block whose first C (command) columns stay 0, so one
    # maximum with the robot's last act's commands + words row gives the whole tail of the observation
    n_commands = model.template_commands.shape[1]
    t["_utterance_word_columns"] = torch.where(present, order + n_commands, n_commands + len(model.words))
    # the commands + words of each said act type (row 0: nothing said), plus the spare column the padding hits
    system_features = torch.cat([model.template_commands, model.template_words], dim=1)
    t["_said_features"] = torch.cat([system_features, torch.zeros(len(system_features), 1)], dim=1)
    t["_utterance_out"] = torch.cat([torch.arange(n_utt), torch.tensor([-1])])  # silence is reported as -1
    t["_utterance_is_move"] = torch.cat([model.utterance_acts == dlg.USER_MOVE, torch.tensor([False])])
    t["_asr_scaled"] = tuple(asr) != (0.0, 1.0)  # else confidences are the uniforms themselves
    # phase of every stage (see ROBOT_FIRST); the filter by (talk = last system act * N_USER + last user act,
    # stage): one row gather per step instead of ~12 ops that build the phase and the context
    stage = torch.arange(N_STAGES)
    stage_phase = torch.tensor([
        dlg.phase_of(bool(flags & AGREED), bool(flags & CLOSED), status // 2, (status % 2 == 0) == bool(flags & ROBOT_FIRST))
        for status, flags in zip((stage % 8).tolist(), (stage // 8 * 8).tolist())
    ])
    t["_stage_phase"] = stage_phase
    allowed = model.filter_allowed.flatten(0, 2)  # (contexts, types) -> (contexts, actions)
    by_phase = torch.cat([allowed[:, :1].expand(-1, cells), allowed[:, 1:]], dim=1)
    n_talk = (1 + len(dlg.SYSTEM_TYPES)) * N_USER
    rows = (torch.arange(n_talk).unsqueeze(1) * len(dlg.PHASES) + stage_phase.unsqueeze(0)).reshape(-1)
    t["_filter_table"] = by_phase.index_select(0, rows).contiguous()  # row talk * N_STAGES + stage
    # flags an accepted act sets (by act type + 1), and those a (system act, user reply) pair sets (by talk)
    said_flags = torch.zeros(1 + len(dlg.SYSTEM_TYPES), dtype=torch.int64)
    said_flags[dlg.REPLY_YES + 1], said_flags[dlg.CLOSING + 1] = AGREED, CLOSED
    t["_said_flags"] = said_flags
    talk_flags = torch.zeros(n_talk, dtype=torch.int64)
    talk_flags[(dlg.REQUEST_PLAY + 1) * N_USER + dlg.USER_YES + 1] = AGREED
    t["_talk_flags"] = talk_flags
    # the user moves after (act type, phase) = a move or "your turn" while it is the user's turn
    t["_user_turn"] = (asks_move.unsqueeze(1) & (torch.arange(len(dlg.PHASES)) == dlg.USER_TO_MOVE)).reshape(-1)
    t["_code_legal"] = t["_code_rewards"] = t["_code_wins"] = t["_act_lookahead"] = None
    if engine.game == "standard":  # 3x3: legal squares and look-ahead rewards are one row per board code
        legal, rewards = engine.rows_by_code(ROBOT)
        talk_acts = n_actions - cells  # padded to all actions: dialogue acts legal, their reward 0
        t["_code_legal"] = torch.cat([legal, torch.ones(len(legal), talk_acts, dtype=torch.bool)], dim=1).contiguous()
        code_rewards = torch.cat([rewards, torch.zeros(len(rewards), talk_acts)], dim=1).contiguous()
        t["_code_rewards"] = code_rewards
        if engine.win_set == "wins_and_threats":
            t["_code_wins"] = (code_rewards == REWARD_WIN).contiguous()  # winning_actions = mask & this row
        else:  # win_set="wins": only the squares that win the game now
            wins = engine.winning_rows_by_code(ROBOT)
            t["_code_wins"] = torch.cat([wins, torch.zeros(len(wins), talk_acts, dtype=torch.bool)], dim=1).contiguous()
    else:  # Ultimate: the look-ahead row before the moves' rewards are written in: allowed acts 0, else -5
        acts = torch.where(t["_filter_table"], 0.0, REWARD_ILLEGAL)
        acts[:, :cells] = REWARD_ILLEGAL
        t["_act_lookahead"] = acts.contiguous()
    return t


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


def describe(model: dlg.DialogueModel, cells: int, temporal: bool, threat_features: bool = False) -> dict[str, Any]:
    """The env's metadata attributes: action names, templates, robot commands, user acts, words, feature names."""
    action_names = dlg.action_names(cells)
    width = len(str(cells - 1))
    names = [f"robot_move[{c:0{width}d}]" for c in range(cells)]
    names += [f"human_move[{c:0{width}d}]" for c in range(cells)]
    names += [f"command[{c}]" for c in dlg.ROBOT_COMMANDS]
    names += [f"word[{w}]" for w in model.words]
    if temporal:
        names += [f"time[{c:0{width}d}]" for c in range(cells)]
    if threat_features:
        from ncbot.envs.threat_features import threat_names

        names += threat_names(cells)
    return {
        "action_names": action_names,
        "n_actions": len(action_names),
        "templates": [model.templates[0]] * cells + list(model.templates[1:]),
        "robot_commands": [dlg.TYPE_COMMANDS[0]] * cells + list(dlg.TYPE_COMMANDS[1:]),
        "user_act_names": list(dlg.USER_ACTS),
        "words": list(model.words),
        "feature_names": names,
        "n_features": len(names),
    }


def make_specs(batch: int, cells: int, n_actions: int, n_features: int, n_utterances: int) -> dict[str, Any]:
    """The env's observation, action, reward and done specs (by spec attribute name)."""
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
    return {
        "observation_spec": observation,
        "action_spec": Categorical(n_actions, shape=shape, dtype=torch.int64),
        "reward_spec": Unbounded(shape=(batch, 1), dtype=torch.float32),
        "done_spec": Composite(done=flag(1), terminated=flag(1), truncated=flag(1), shape=shape),
    }
