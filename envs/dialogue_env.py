"""The multimodal dialogue game as a batched TorchRL env: one episode is one conversation with a simulated user.

Why stateful and batched: EnvBase costs ~70 µs per call whatever the batch, so the env keeps B games as
tensors and advances all of them with whole-batch ops; the simulated user (its dialogue reply and, on its
turn, its game move) runs inside ``step``, so the learner sees the single-agent MDP of the paper.

Flow of a dialogue: greeting, name, play request (the user may decline, or ask to play itself), then the
game: on its turn the robot takes a square (GameMove) and the user answers at once with its own move;
when the user starts, the robot first says "your turn" (Request(userGameMove)). After the game: feedback
(win / loose / draw) and closing, which ends the episode. The act filter (Naive Bayes over the example
dialogues) and the legal squares form ``action_mask``; an act outside it is refused: -5, nothing changes
except the action count. See docs/env.md for rewards, features and every key.

This module is the TorchRL adapter and the step; what it reads is built elsewhere: the step tables, metadata and
specs in ``ncbot.envs.dialogue_tables``, the option checks in ``ncbot.envs.env_options``, the exact TorchRL shortcuts in
``ncbot.envs.env_speed``, the simulated user's half of a step in ``ncbot.envs.user_turn``. Who opens is the option
``first`` (``env.first``).

The paper's ambiguous readings are options (defaults = this project's first reading; the paper configs set the
readings closest to the text; docs/env.md "Readings"): ``taken_squares`` (never | refused | misread, with
``misread_rate``) decides whether and why the robot can choose a taken square, ``win_set`` what
``winning_actions`` holds, ``about_to`` when "about to win" pays, and ``dialogues="paper"`` learns the act filter, the vocabulary and the user from the paper-shaped example
dialogues ("your turn" before every user move). ``dialogue_subset=(k, seed)`` learns them from a seeded subset of
k example dialogues (the data-budget curve), with the whole set's vocabulary so the features keep their size.
"""
from __future__ import annotations

from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import EnvBase

import ncbot.envs.dialogue as dlg
from ncbot.envs.core import (
    BELIEF_READINGS, FIRST_CHOICES, GAME_CHOICES, HUMAN, REWARD_ILLEGAL, REWARD_WIN, ROBOT, USER,  # noqa: F401
    check_free_move, check_game,
)
from ncbot.envs.threat_features import threat_planes
from ncbot.envs.dialogue_tables import (  # noqa: F401  (flags re-exported for tests and tools)
    AGREED, CLOSED, N_STAGES, N_USER, ROBOT_FIRST, describe, make_specs, step_tables,
)
from ncbot.envs.engine import make_engine, uniform_choice  # noqa: F401 (uniform_choice: re-exported)
from ncbot.envs.engine.tables import uniform_choice_by_rows
from ncbot.envs.env_options import (
    check_batch, check_confidence, check_hearing, check_subset, check_taken_squares, first_of, resolve_opponent,
)
from ncbot.envs.env_speed import DialogueState, FastProcHooks, paste_rows
from ncbot.envs.misread import MisreadBoard
from ncbot.envs.user_turn import SimulatedUserTurn

ILLEGAL_ACT_REWARD = REWARD_ILLEGAL  # the paper's penalty for a repeated move, applied to every refused act (ours)


class DialogueGameEnv(FastProcHooks, MisreadBoard, SimulatedUserTurn, EnvBase):
    """Batched Noughts & Crosses dialogue env (3x3, Ultimate or a declared game); build it with ``ncbot.envs.make_env``.

    Metadata: ``action_names``, ``templates``, ``robot_commands`` (per action), ``feature_names``,
    ``user_act_names``, ``words``, ``n_actions``, ``n_features``, ``game``, ``cells``; ``user_utterance(id)``
    gives the text of a ``user_utterance`` id and ``describe_action(a)`` the robot's line for an action.
    """

    batch_locked = True

    def __init__(
        self,
        game: str = "standard",
        batch_size: int | tuple[int, ...] | torch.Size = (1,),
        temporal: bool = True,
        free_move: str = "anywhere",
        seed: int = 0,
        first: str = "robot",
        opponent: Any = "random",
        asr_confidence: tuple[float, float] = (0.0, 1.0),
        max_actions: int = 100,
        taken_squares: str = "never",
        misread_rate: float | None = None,
        win_set: str = "wins_and_threats",
        about_to: str = "standing",
        dialogues: str = "compact",
        hearing: Any = None,
        dialogue_subset: tuple[int, int] | None = None,
        threat_features: bool = False,
    ) -> None:
        batch = check_batch(batch_size)
        game = check_game(game)
        check_free_move(free_move)
        first = first_of(first)
        low, high = check_confidence(asr_confidence)
        if not isinstance(max_actions, int) or max_actions < 1:
            raise ValueError(f"max_actions must be a positive int, got {max_actions!r}")
        taken_squares, misread_rate = check_taken_squares(taken_squares, misread_rate)
        if not isinstance(threat_features, bool):
            raise ValueError(f"threat_features must be true or false, got {threat_features!r}")
        if threat_features and game not in GAME_CHOICES:
            raise ValueError(f"threat_features exist for the games {', '.join(GAME_CHOICES)} only; got game {game!r}")
        self.threat_features = threat_features  # beyond the paper: envs/threat_features.py
        super().__init__(batch_size=torch.Size([batch]), device="cpu")
        self.game, self.free_move, self.temporal, self.first = game, free_move, bool(temporal), first
        self.asr_low, self.asr_high, self.max_actions = low, high, max_actions
        self.taken_squares, self.misread_rate = taken_squares, misread_rate
        self._refused, self._misread = taken_squares == "refused", taken_squares in BELIEF_READINGS
        self._offer_taken = taken_squares == "offered"  # misread, and the squares known taken offered too
        self.dialogues = dlg.dialogue_set(dialogues).name
        self.dialogue_subset = check_subset(dialogue_subset)
        self.engine = make_engine(game, free_move, win_set=win_set, about_to=about_to)
        self.win_set, self.about_to = win_set, about_to
        self.cells = self.engine.cells
        self.model = dlg.build_dialogue_model(game, self.dialogues, self.dialogue_subset)
        self.opponent, self._opponent_params = resolve_opponent(opponent, game, free_move, seed)
        self.hearing = check_hearing(hearing)
        for name, value in describe(self.model, self.cells, self.temporal, threat_features).items():
            setattr(self, name, value)
        for name, spec in make_specs(batch, self.cells, self.n_actions, self.n_features, len(self.model.utterance_texts)).items():
            setattr(self, name, spec)
        self._rng = torch.Generator().manual_seed(int(seed))
        self._action_rng = torch.Generator().manual_seed(int(seed) + 1)
        for name, table in step_tables(self.model, self.engine, self.n_actions, (low, high)).items():
            setattr(self, name, table)
        if self._misread and self._code_legal is not None:  # 3x3: the believed board's empty squares, by its code
            empty = self.engine.empty_rows_by_code()
            self._code_empty = torch.cat([empty, torch.ones(len(empty), self.n_actions - self.cells, dtype=torch.bool)], dim=1)
        self._reply_key: tuple | None = None  # what _reply_tables last derived its tables from
        self._all_games = torch.arange(batch)
        self._init_state(batch)
        self.set_seed(int(seed))

    # ------------------------------------------------------------------ construction helpers
    def _init_state(self, batch: int) -> None:
        self.boards = self.engine.new(batch)
        # taken_squares="misread": the robot's knowledge of the board (what it observes); else the board itself
        self.belief = self.engine.new(batch) if self._misread else self.boards
        self.d = DialogueState()
        self.d.flags = torch.full((batch,), ROBOT_FIRST, dtype=torch.int64)
        self.d.talk = torch.zeros(batch, dtype=torch.int64)
        # the tensors handed out as (B, 1) keys are kept as columns (no unsqueeze per output)
        self.d.robot_first = torch.ones(batch, 1, dtype=torch.bool)
        self.d.episodes = torch.zeros(batch, dtype=torch.int64)
        self.d.turn = torch.zeros(batch, 1, dtype=torch.int64)
        self.d.user_act = torch.full((batch, 1), -1, dtype=torch.int64)
        self.d.user_move = torch.full((batch, 1), -1, dtype=torch.int64)
        self.d.user_utterance = torch.full((batch, 1), -1, dtype=torch.int64)
        self.d.words = torch.zeros(batch, self._said_features.shape[1])
        self._refresh()
        # every new dialogue starts in the same context: keep its mask rows to paste on resets
        self._fresh_rows = (self.d.mask[0].clone(), self.d.dialogue_mask[0].clone(), self.d.lookahead[0].clone(),
                            self.d.legal[0].clone(), None if self._act_lookahead is None else self.d.winning_moves[0].clone())
        if self._misread:
            self.d.misread = torch.zeros(batch, dtype=torch.bool)
        fresh = self._output()  # also fills d.observation / d.winning_actions, which partial resets reuse
        self._fresh_features = (fresh["observation"][0].clone(), fresh["winning_actions"][0].clone())

    # ------------------------------------------------------------------ metadata helpers
    def user_utterance(self, utterance_id: int) -> str:
        """Text of a ``user_utterance`` id ("" for -1, silence)."""
        utterance_id = int(utterance_id)
        if utterance_id == -1:
            return ""
        if not 0 <= utterance_id < len(self.model.utterance_texts):
            raise ValueError(f"utterance id {utterance_id} out of range: expected -1..{len(self.model.utterance_texts) - 1}")
        return self.model.utterance_texts[utterance_id]

    def describe_action(self, action: int) -> str:
        """The robot's template utterance with its bracketed command, e.g. "I take this one. [who=rob, what=draw, where=b2]"."""
        action = self._check_action_index(int(action))
        if action < self.cells:
            from ncbot.envs.rules import make_game

            where = make_game(self.game, self.free_move).cell_name(action)
            return f"{self.templates[action]} [who=rob, what=draw, where={where}]"
        return f"{self.templates[action]} [who=rob, what={self.robot_commands[action]}]"

    def _check_action_index(self, action: int) -> int:
        if not 0 <= action < self.n_actions:
            raise ValueError(f"action {action} is out of range: expected 0..{self.n_actions - 1} ({self.n_actions} dialogue acts of the {self.game} game)")
        return action

    # ------------------------------------------------------------------ dynamics
    def _stage(self, flags: torch.Tensor) -> torch.Tensor:
        """(B,) the stage (board status + dialogue ``flags``): ``_stage_phase`` gives the game phase."""
        return self.engine.status(self.boards) + flags

    def _refresh(self) -> None:
        """Recompute the mask and look-ahead of the current state (after a step).

        ``d.legal`` is what the step accepts; ``d.mask`` (``action_mask``) is what is offered: the same tensor
        unless ``taken_squares`` is ``refused``, which adds the taken squares on the robot's turn (look-ahead -5),
        or ``misread`` (``_refresh_misread``), which offers the squares legal on the robot's believed board.
        """
        if self._misread:
            self._refresh_misread()
            return
        cells = self.cells
        context = self.d.talk * N_STAGES + self._stage(self.d.flags)
        dialogue_mask = self._filter_table.index_select(0, context)  # (B, A): moves = "GameMove allowed"
        if self._code_legal is not None:
            code = self.boards.codes[:, 0]
            mask = dialogue_mask & self._code_legal.index_select(0, code)
            lookahead = torch.where(mask, self._code_rewards.index_select(0, code), REWARD_ILLEGAL)
        else:  # Ultimate: the look-ahead is written straight into the row of every act's reward
            moves = dialogue_mask[:, 0]  # the filter allows GameMove on every square or on none
            legal = self.engine.legal(self.boards, moves)
            mask = torch.cat([legal, dialogue_mask[:, cells:]], dim=1)
            lookahead = self._act_lookahead.index_select(0, context)  # allowed acts 0, the rest and every square -5
            winning = torch.zeros_like(mask)
            can_move = moves & (self.boards.outcome == 0)  # == legal.any(1): an unfinished game has a legal square
            if bool(can_move.any()):
                self.engine.write_move_rewards(lookahead, self.boards, ROBOT, can_move, winning)
            self.d.winning_moves = winning  # == lookahead == +5 (only a legal move can win)
        self.d.legal, self.d.dialogue_mask, self.d.lookahead = mask, dialogue_mask, lookahead
        self.d.mask = self._offered(mask, dialogue_mask) if self._refused else mask

    def _offered(self, legal: torch.Tensor, dialogue_mask: torch.Tensor) -> torch.Tensor:
        """``taken_squares="refused"``: the legal acts plus every taken square where the filter allows a move (the
        robot's turn only). Empty squares the rules forbid (Ultimate's redirect) stay out: they are not taken."""
        taken = torch.zeros_like(legal)
        taken[:, : self.cells] = (self.boards.board != 0) & dialogue_mask[:, : self.cells]
        return legal | taken

    def _observation(self) -> torch.Tensor:
        boards = self.belief  # what the robot knows of the board: the board itself unless taken_squares="misread"
        parts = [*self.engine.mark_parts(boards), self.d.words[:, :-1]]  # one cat makes every part float32
        if self.temporal:
            parts.append(torch.div(boards.move_order, boards.n_marks.clamp(min=1).unsqueeze(1)))
        if self.threat_features:
            parts.append(threat_planes(boards.board, boards.owners if self.game == "ultimate" else None))
        return torch.cat(parts, dim=1)

    def _output(self, reward: torch.Tensor | None = None, reset_rows: torch.Tensor | None = None) -> TensorDict:
        """The TensorDict of the current state with done flags (and ``reward`` after a step); fresh tensors.

        ``reset_rows`` (int64 indices): only these games changed since the last output (a partial reset), so the
        observation and winning actions are the last ones with the fresh-dialogue row pasted in (2 ops
        instead of ~10; a fresh dialogue's observation does not depend on anything random).
        """
        mask = self.d.mask
        if reset_rows is None:
            # a taken square offered (taken_squares="refused") never wins; "misread": the believed board's
            legal = self.d.mask if self._misread else self.d.legal
            if self._offer_taken:  # "offered": a square known taken is offered, never winning
                legal = torch.cat([legal[:, :self.cells] & (self.belief.board == 0), legal[:, self.cells:]], dim=1)
            if self._code_wins is not None:  # 3x3: the moves worth +5 (or that win: win_set) are one row per board code
                winning = legal & self._code_wins.index_select(0, self.belief.codes[:, 0])
            else:  # Ultimate: written with the look-ahead (_refresh)
                winning = self.d.winning_moves
            observation = self._observation()
            terminated = (self.d.flags >= CLOSED).unsqueeze(1)  # CLOSED is the highest flag
            truncated = (self.d.turn >= self.max_actions) & ~terminated
            done = terminated | truncated
        else:
            fresh_observation, fresh_winning = self._fresh_features
            observation = paste_rows(self.d.observation, reset_rows, fresh_observation)
            winning = paste_rows(self.d.winning_actions, reset_rows, fresh_winning)
            # a new dialogue is neither over nor cut short; the other games are as in the last output
            terminated, truncated, done = (flag.index_fill(0, reset_rows, False) for flag in self.d.done_flags)
        self.d.observation, self.d.winning_actions = observation, winning
        self.d.done_flags = (terminated, truncated, done)
        extra = {} if reward is None else {"reward": reward}
        # _new_unsafe skips per-key validation: every tensor here is built by the env with the right batch
        return TensorDict._new_unsafe(
            {
                **extra,
                "observation": observation,
                "action_mask": mask,
                "dialogue_mask": self.d.dialogue_mask,
                "lookahead_reward": self.d.lookahead,
                "winning_actions": winning,
                # resets (and the Ultimate engine) change boards in place; "misread": the robot's believed board
                "board": self.belief.board.clone(),
                "outcome": self.boards.outcome.to(torch.int8).unsqueeze(1),
                "robot_first": self.d.robot_first,
                "turn": self.d.turn,
                "user_act": self.d.user_act,
                "user_move": self.d.user_move,
                "user_utterance": self.d.user_utterance,
                "terminated": terminated,
                "truncated": truncated,
                "done": done,
            },
            batch_size=self.batch_size,
            device=self.device,  # without it EnvBase.step_and_maybe_reset moves (copies) the TensorDict to the env's device every call
        )

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDict:
        if tensordict is None or "_reset" not in tensordict.keys():
            self._reset_rows(self._all_games)
            return self._output()
        index = tensordict.get("_reset").reshape(-1).nonzero().squeeze(1)  # one sync answers "all / some / none"
        if index.shape[0] == self.batch_size[0]:
            self._reset_rows(index)
            return self._output()
        if index.shape[0]:
            self._reset_rows(index)
            return self._output(reset_rows=index)
        return self._output()

    def _reset_rows(self, index: torch.Tensor) -> None:
        """Start new dialogues in the games ``index`` (int64 (N,)); the others keep their state.

        Why indices rather than a bool column: a broadcast ``where`` / ``masked_fill`` over (B, F) costs
        ~0.5 ns per element (15-50 µs at batch 1024), ``index_fill_`` / an index copy a few µs.
        """
        boards = self.boards
        # in place: the engine's tensors never leave the env (outputs copy them), so nobody else holds them
        for boards in ((self.boards, self.belief) if self._misread else (boards,)):
            grids = [boards.board, boards.codes, boards.move_order, boards.n_marks, boards.outcome]
            if self.game == "ultimate":  # a 3x3 board has no subgrid owners (the column stays 0)
                grids.append(boards.owners)
            for grid in grids:
                grid.index_fill_(0, index, 0)
            boards.last_move.index_fill_(0, index, -1)
        # never handed out (outputs are built from them): changed in place
        self.d.words.index_fill_(0, index, 0.0)
        self.d.talk.index_fill_(0, index, 0)
        # the (B, 1) dialogue columns below are handed out in outputs: replaced, never changed in place
        self.d.turn = self.d.turn.index_fill(0, index, 0)
        self.d.user_act = self.d.user_act.index_fill(0, index, -1)
        self.d.user_move = self.d.user_move.index_fill(0, index, -1)
        self.d.user_utterance = self.d.user_utterance.index_fill(0, index, -1)
        if self.first in ("robot", "human"):
            robot = self.first == "robot"
            self.d.robot_first = self.d.robot_first.index_fill(0, index, robot)
            self.d.flags.index_fill_(0, index, ROBOT_FIRST if robot else 0)
        else:
            if self.first == "alternate":
                first = self.d.episodes.index_select(0, index) % 2 == 0
                self.d.episodes.index_add_(0, index, torch.ones_like(index))
            else:  # one draw per game, reset or not (the random stream does not depend on which games reset)
                first = (torch.rand(self.batch_size, generator=self._rng) < 0.5).index_select(0, index)
            self.d.robot_first = self.d.robot_first.index_copy(0, index, first.unsqueeze(1))
            self.d.flags.index_copy_(0, index, first.long() * ROBOT_FIRST)
        mask, dialogue_mask, lookahead, legal, winning = self._fresh_rows
        self.d.mask = paste_rows(self.d.mask, index, mask)
        self.d.dialogue_mask = paste_rows(self.d.dialogue_mask, index, dialogue_mask)
        self.d.lookahead = paste_rows(self.d.lookahead, index, lookahead)
        self.d.legal = paste_rows(self.d.legal, index, legal) if self.taken_squares != "never" else self.d.mask
        if self._misread:  # a new dialogue: belief == truth, one look-ahead
            self.d.true_lookahead = paste_rows(self.d.true_lookahead, index, lookahead)
            self.d.misread = self.d.misread.index_fill(0, index, False)
        if winning is not None:  # Ultimate: the winning moves are written with the look-ahead
            self.d.winning_moves = paste_rows(self.d.winning_moves, index, winning)

    def _step(self, tensordict: TensorDictBase) -> TensorDict:
        action = tensordict.get("action").reshape(-1).long()
        if action.shape[0] != self.batch_size[0]:
            raise ValueError(f"action must hold {self.batch_size[0]} entries (one per game), got shape {tuple(tensordict.get('action').shape)}")
        try:  # the table read doubles as the range check (index_select refuses indices outside the table)
            act_type = self._act_type.index_select(0, action)
        except IndexError:
            out_of_range = (action < 0) | (action >= self.n_actions)
            self._check_action_index(int(action[out_of_range][0]))
            raise
        index = action.unsqueeze(1)
        accepted = self.d.legal.gather(1, index).squeeze(1)  # an offered taken square is refused
        reward = (self.d.true_lookahead if self._misread else self.d.lookahead).gather(1, index)
        said = (act_type + 1) * accepted  # the accepted act's type + 1, 0 if refused: the new "last system act"
        reread = None  # taken_squares="misread": the games whose believed board becomes the true one this step

        robot_moves = said == dlg.MOVE + 1
        if bool(robot_moves.any()):
            self.engine.play(self.boards, action, ROBOT, robot_moves)
            if self._misread:
                reread = self._believe_robot_moves(action, robot_moves)
        flags = self.d.flags | self._said_flags.index_select(0, said)

        # The simulated user's reply: an utterance learnt for (act type, phase), and its move on its turn.
        silence = self._silence
        phase = self._stage_phase.index_select(0, self._stage(flags))
        counts, replies = self._reply_tables()
        context = act_type * len(dlg.PHASES) + phase
        count = counts.index_select(0, context)
        pick = (torch.rand(count.shape, generator=self._rng) * count).long()  # < count (see _reply_tables)
        utterance = replies.index_select(0, context * (self.model.reply_options.shape[-1] + 1) + pick)
        utterance = torch.where(accepted, utterance, silence)
        user_moves = accepted & self._user_turn.index_select(0, context)
        if bool(user_moves.any()):
            cells_taken = self._user_cells(user_moves)
            self.engine.play(self.boards, cells_taken, USER, user_moves)
            if self._misread:  # the robot reads the user's mark off the sheet, sometimes wrongly
                cells_taken, conflict = self._read_user_moves(cells_taken, user_moves)
                reread = conflict if reread is None else reread | conflict
            user_move = torch.where(user_moves, cells_taken, -1)
        else:
            user_move = torch.full_like(action, -1)
        if self._misread:
            if not bool(user_moves.any()):
                self.d.misread = torch.zeros_like(user_moves)
            # a refused game move: the robot chose a square it believed free; the sheet is read again
            refused_move = ~accepted & (act_type == dlg.MOVE)
            reread = refused_move if reread is None else reread | refused_move
            self._reread(reread)
        if self.hearing is None:  # uniform ASR: the robot hears the words said, at uniform random confidences
            user_act = self._utterance_acts.index_select(0, utterance)
            columns = self._utterance_word_columns.index_select(0, utterance)
            confidence = torch.rand(columns.shape, generator=self._rng)
            if self._asr_scaled:
                confidence = confidence * (self.asr_high - self.asr_low) + self.asr_low
        else:  # the hearing's words; the utterance it understood drives the dialogue, the one said the board
            user_act, columns, confidence = self._heard(utterance)
        talk = said * N_USER + (user_act + 1)  # 0 for a refused act (silence)
        flags = flags | self._talk_flags.index_select(0, talk)

        # the commands and words of the robot's act, with the user's words at their ASR confidence (the larger
        # of the two where both said a word); refused acts leave the last ones (rare with a masked policy)
        words = self._said_features.index_select(0, said).scatter_reduce_(1, columns, confidence, "amax")
        if not bool(accepted.all()):
            words = torch.where(accepted.unsqueeze(1), words, self.d.words)
            talk = torch.where(accepted, talk, self.d.talk)
        self.d.words, self.d.talk, self.d.flags = words, talk, flags
        self.d.user_act, self.d.user_move = user_act.unsqueeze(1), user_move.unsqueeze(1)
        self.d.user_utterance = self._utterance_out.index_select(0, utterance).unsqueeze(1)
        self.d.turn = self.d.turn + 1
        self._refresh()

        return self._output(reward)

    def rand_action(self, tensordict: TensorDictBase | None = None) -> TensorDictBase:
        """A uniformly random action among those the mask allows (never a masked one)."""
        if tensordict is None:
            tensordict = TensorDict(batch_size=self.batch_size)
        mask = tensordict.get("action_mask", None)
        if mask is None:
            mask = self.d.mask
        choose = uniform_choice_by_rows if mask.shape[-1] % 9 == 0 and mask.dim() == 2 else uniform_choice  # same numbers
        tensordict.set("action", choose(mask, self._action_rng))
        return tensordict

    def _set_seed(self, seed: int | None) -> None:
        seed = 0 if seed is None else int(seed)
        self._rng.manual_seed(seed)
        self._action_rng.manual_seed(seed + 1)
