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
"""
from __future__ import annotations

import inspect
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from envs import dialogue as dlg
from envs.engine import FREE_MOVE_CHOICES, make_engine, uniform_choice  # noqa: F401 (uniform_choice: re-exported)

GAME_CHOICES = ("standard", "ultimate")
STARTS_CHOICES = ("robot", "human", "alternate", "random")
ILLEGAL_ACT_REWARD = -5.0  # the paper's penalty for a repeated move, applied to every refused act (ours)
ROBOT, USER = 1, 2
# Dialogue flags, kept multiplied by 8 so that ``engine.status`` (outcome * 2 + marks % 2, 0..7) + flags is the
# game's "stage" (0..63): all the phase depends on, one integer per game, and the index of the phase table.
ROBOT_FIRST, AGREED, CLOSED = 8, 16, 32
N_STAGES = 64
N_USER = 1 + len(dlg.USER_ACTS)  # values of the last user act: 0 none, else user act + 1


class DialogueGameEnv(EnvBase):
    """Batched Noughts & Crosses dialogue env (3x3 or Ultimate); build it with ``envs.make_env``.

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
        starts: str = "robot",
        opponent: Any = "random",
        asr_confidence: tuple[float, float] = (0.0, 1.0),
        max_actions: int = 100,
    ) -> None:
        batch = _check_batch(batch_size)
        if game not in GAME_CHOICES:
            raise ValueError(f"game must be one of {', '.join(GAME_CHOICES)}; got {game!r}")
        if free_move not in FREE_MOVE_CHOICES:
            raise ValueError(f"free_move must be one of {', '.join(FREE_MOVE_CHOICES)}; got {free_move!r}")
        if starts not in STARTS_CHOICES:
            raise ValueError(f"starts must be one of {', '.join(STARTS_CHOICES)}; got {starts!r}")
        low, high = _check_confidence(asr_confidence)
        if not isinstance(max_actions, int) or max_actions < 1:
            raise ValueError(f"max_actions must be a positive int, got {max_actions!r}")
        super().__init__(batch_size=torch.Size([batch]), device="cpu")
        self.game, self.free_move, self.temporal, self.starts = game, free_move, bool(temporal), starts
        self.asr_low, self.asr_high, self.max_actions = low, high, max_actions
        self.engine = make_engine(game, free_move)
        self.cells = self.engine.cells
        self.model = dlg.build_dialogue_model(game)
        self.opponent, self._opponent_params = self._resolve_opponent(opponent, seed)
        self._describe()
        self._make_specs(batch)
        self._rng = torch.Generator().manual_seed(int(seed))
        self._action_rng = torch.Generator().manual_seed(int(seed) + 1)
        self._make_tables()
        self._all_games = torch.arange(batch)
        self._init_state(batch)
        self.set_seed(int(seed))

    # ------------------------------------------------------------------ construction helpers
    def _resolve_opponent(self, opponent: Any, seed: int) -> tuple[Any, set[str]]:
        """None for the inline uniform-random user; else an object with ``select`` (by name or given).

        Also returns which optional keywords its ``select`` takes: ``owners`` (Ultimate subgrid owners) and
        ``rows`` (the batch indices of the games that move, for opponents that hold per-game input such as
        ``envs.external_opponent.ExternalOpponent``).
        """
        if isinstance(opponent, str):
            if opponent == "random":
                return None, set()
            from envs.opponents import make_opponent, opponent_choices

            try:
                opponent = make_opponent(opponent, game=self.game, free_move=self.free_move, seed=seed)
            except (KeyError, ValueError) as error:
                raise ValueError(f"opponent {opponent!r} unknown or invalid ({error}); choices: {', '.join(opponent_choices())}") from None
        if not callable(getattr(opponent, "select", None)):
            raise ValueError(f"opponent must be a name (e.g. 'random') or an object with a select(...) method, got {opponent!r}")
        params = set(inspect.signature(opponent.select).parameters) & {"owners", "rows"}
        return opponent, params

    def _make_tables(self) -> None:
        """Flat look-up tables for the step (index_select on 1-D tables is the fastest gather on CPU).

        Utterance id ``U`` (one past the last) stands for silence inside the step; it is reported as -1.
        """
        model, cells = self.model, self.cells
        n_utt = len(model.utterance_texts)
        self._silence = n_utt
        self._reply_key: tuple | None = None  # what _reply_tables last derived its tables from
        self._act_type = torch.cat([torch.zeros(cells, dtype=torch.int64), torch.arange(1, len(dlg.SYSTEM_TYPES))])
        self._asks_move = torch.zeros(len(dlg.SYSTEM_TYPES), dtype=torch.bool)
        self._asks_move[[dlg.MOVE, dlg.REQUEST_USER_MOVE]] = True
        self._utterance_acts = torch.cat([model.utterance_acts, torch.tensor([-1])])
        # the words of each utterance as column indices (padded with V, a spare column): ASR confidences are
        # drawn for these few words only (torch.rand costs ~10 ns per number, (B, V) draws dominated the step)
        words = torch.cat([model.utterance_words, torch.zeros(1, len(model.words))]) > 0
        width = max(1, int(words.sum(1).max()))
        order = torch.sort(words.to(torch.uint8), dim=1, descending=True, stable=True).indices[:, :width]
        present = torch.arange(width).unsqueeze(0) < words.sum(1, keepdim=True)
        # user words live in columns C.. of a (B, C + V) block whose first C (command) columns stay 0, so one
        # maximum with the robot's last act's commands + words row gives the whole tail of the observation
        n_commands = model.template_commands.shape[1]
        self._utterance_word_columns = torch.where(present, order + n_commands, n_commands + len(model.words))
        # the commands + words of each said act type (row 0: nothing said), plus the spare column the padding hits
        system_features = torch.cat([model.template_commands, model.template_words], dim=1)
        self._said_features = torch.cat([system_features, torch.zeros(len(system_features), 1)], dim=1)
        self._utterance_out = torch.cat([torch.arange(n_utt), torch.tensor([-1])])  # silence is reported as -1
        self._utterance_is_move = torch.cat([model.utterance_acts == dlg.USER_MOVE, torch.tensor([False])])
        self._asr_scaled = (self.asr_low, self.asr_high) != (0.0, 1.0)  # else confidences are the uniforms themselves
        # phase of every stage (see ROBOT_FIRST); the filter by (talk = last system act * N_USER + last user act,
        # stage): one row gather per step instead of ~12 ops that build the phase and the context
        stage = torch.arange(N_STAGES)
        self._stage_phase = torch.tensor([
            dlg.phase_of(bool(flags & AGREED), bool(flags & CLOSED), status // 2, (status % 2 == 0) == bool(flags & ROBOT_FIRST))
            for status, flags in zip((stage % 8).tolist(), (stage // 8 * 8).tolist())
        ])
        allowed = model.filter_allowed.flatten(0, 2)  # (contexts, types) -> (contexts, actions)
        by_phase = torch.cat([allowed[:, :1].expand(-1, cells), allowed[:, 1:]], dim=1)
        n_talk = (1 + len(dlg.SYSTEM_TYPES)) * N_USER
        rows = (torch.arange(n_talk).unsqueeze(1) * len(dlg.PHASES) + self._stage_phase.unsqueeze(0)).reshape(-1)
        self._filter_table = by_phase.index_select(0, rows).contiguous()  # row talk * N_STAGES + stage
        # flags an accepted act sets (by act type + 1), and those a (system act, user reply) pair sets (by talk)
        self._said_flags = torch.zeros(1 + len(dlg.SYSTEM_TYPES), dtype=torch.int64)
        self._said_flags[dlg.REPLY_YES + 1], self._said_flags[dlg.CLOSING + 1] = AGREED, CLOSED
        self._talk_flags = torch.zeros(n_talk, dtype=torch.int64)
        self._talk_flags[(dlg.REQUEST_PLAY + 1) * N_USER + dlg.USER_YES + 1] = AGREED
        # the user moves after (act type, phase) = a move or "your turn" while it is the user's turn
        self._user_turn = (self._asks_move.unsqueeze(1) & (torch.arange(len(dlg.PHASES)) == dlg.USER_TO_MOVE)).reshape(-1)
        self._code_legal = self._code_rewards = self._code_wins = None
        if self.game == "standard":  # 3x3: legal squares and look-ahead rewards are one row per board code
            legal, rewards = self.engine.rows_by_code(ROBOT)
            talk_acts = self.n_actions - cells  # padded to all actions: dialogue acts legal, their reward 0
            self._code_legal = torch.cat([legal, torch.ones(len(legal), talk_acts, dtype=torch.bool)], dim=1).contiguous()
            self._code_rewards = torch.cat([rewards, torch.zeros(len(rewards), talk_acts)], dim=1).contiguous()
            self._code_wins = (self._code_rewards == 5.0).contiguous()  # winning_actions = mask & this row

    def _describe(self) -> None:
        cells, model = self.cells, self.model
        self.action_names = dlg.action_names(cells)
        self.n_actions = len(self.action_names)
        self.templates = [dlg.TEMPLATES[0]] * cells + list(dlg.TEMPLATES[1:])
        self.robot_commands = [dlg.TYPE_COMMANDS[0]] * cells + list(dlg.TYPE_COMMANDS[1:])
        self.user_act_names = list(dlg.USER_ACTS)
        self.words = list(model.words)
        width = len(str(cells - 1))
        names = [f"robot_move[{c:0{width}d}]" for c in range(cells)]
        names += [f"human_move[{c:0{width}d}]" for c in range(cells)]
        names += [f"command[{c}]" for c in dlg.ROBOT_COMMANDS]
        names += [f"word[{w}]" for w in model.words]
        if self.temporal:
            names += [f"time[{c:0{width}d}]" for c in range(cells)]
        self.feature_names = names
        self.n_features = len(names)

    def _make_specs(self, batch: int) -> None:
        cells, actions, n_utt = self.cells, self.n_actions, len(self.model.utterance_texts)
        shape = torch.Size([batch])

        def flag(width: int) -> Categorical:
            return Categorical(2, shape=(batch, width), dtype=torch.bool)

        def ints(low: int, high: int, width: int = 1, dtype=torch.int64) -> Bounded:
            return Bounded(low=low, high=high, shape=(batch, width), dtype=dtype)

        self.observation_spec = Composite(
            observation=Bounded(low=0.0, high=1.0, shape=(batch, self.n_features), dtype=torch.float32),
            action_mask=flag(actions),
            dialogue_mask=flag(actions),
            lookahead_reward=Bounded(low=-5.0, high=5.0, shape=(batch, actions), dtype=torch.float32),
            winning_actions=flag(actions),
            board=ints(0, 2, cells, torch.int8),
            outcome=ints(0, 3, 1, torch.int8),
            robot_first=flag(1),
            turn=Unbounded(shape=(batch, 1), dtype=torch.int64),
            user_act=ints(-1, len(dlg.USER_ACTS) - 1),
            user_move=ints(-1, cells - 1),
            user_utterance=ints(-1, n_utt - 1),
            shape=shape,
        )
        self.action_spec = Categorical(actions, shape=shape, dtype=torch.int64)
        self.reward_spec = Unbounded(shape=(batch, 1), dtype=torch.float32)
        self.done_spec = Composite(done=flag(1), terminated=flag(1), truncated=flag(1), shape=shape)

    def _init_state(self, batch: int) -> None:
        self.boards = self.engine.new(batch)
        self.d = _Dialogues()
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
        self._fresh_rows = (self.d.mask[0].clone(), self.d.dialogue_mask[0].clone(), self.d.lookahead[0].clone())
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
            from envs.rules import make_game

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
        """Recompute the mask and look-ahead of the current state (after a step)."""
        cells = self.cells
        context = self.d.talk * N_STAGES + self._stage(self.d.flags)
        dialogue_mask = self._filter_table.index_select(0, context)  # (B, A): moves = "GameMove allowed"
        if self._code_legal is not None:
            code = self.boards.codes[:, 0]
            mask = dialogue_mask & self._code_legal.index_select(0, code)
            lookahead = torch.where(mask, self._code_rewards.index_select(0, code), ILLEGAL_ACT_REWARD)
            self.d.mask, self.d.dialogue_mask, self.d.lookahead = mask, dialogue_mask, lookahead
            return
        legal = self.engine.legal(self.boards) & dialogue_mask[:, :cells]  # the filter allows moves only on the robot's turn
        mask = torch.cat([legal, dialogue_mask[:, cells:]], dim=1)
        can_move = legal.any(1)
        if bool(can_move.any()):
            # moves' rewards padded with 0 for the other acts: allowed entries keep them, the rest get -5
            rewards = torch.nn.functional.pad(self.engine.move_rewards(self.boards, ROBOT, can_move), (0, self.n_actions - cells))
            lookahead = torch.where(mask, rewards, ILLEGAL_ACT_REWARD)
        else:
            lookahead = torch.where(mask, 0.0, ILLEGAL_ACT_REWARD)
        self.d.mask, self.d.dialogue_mask, self.d.lookahead = mask, dialogue_mask, lookahead

    def _observation(self) -> torch.Tensor:
        boards = self.boards
        parts = [self.engine.mark_features(boards), self.d.words[:, :-1]]
        if self.temporal:
            parts.append(torch.div(boards.move_order, boards.n_marks.clamp(min=1).unsqueeze(1)))
        return torch.cat(parts, dim=1)

    def _output(self, reward: torch.Tensor | None = None, reset_rows: torch.Tensor | None = None) -> TensorDict:
        """The TensorDict of the current state with done flags (and ``reward`` after a step); fresh tensors.

        ``reset_rows`` (int64 indices): only these games changed since the last output (a partial reset), so the
        observation and winning actions are the last ones with the fresh-dialogue row pasted in (2 ops
        instead of ~10; a fresh dialogue's observation does not depend on anything random).
        """
        mask = self.d.mask
        if reset_rows is None:
            if self._code_wins is not None:  # 3x3: the moves worth +5 are one row per board code
                winning = mask & self._code_wins.index_select(0, self.boards.codes[:, 0])
            else:
                winning = mask & (self.d.lookahead == 5.0)
            observation = self._observation()
            terminated = (self.d.flags >= CLOSED).unsqueeze(1)  # CLOSED is the highest flag
            truncated = (self.d.turn >= self.max_actions) & ~terminated
            done = terminated | truncated
        else:
            fresh_observation, fresh_winning = self._fresh_features
            observation = _paste_rows(self.d.observation, reset_rows, fresh_observation)
            winning = _paste_rows(self.d.winning_actions, reset_rows, fresh_winning)
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
                "board": self.boards.board.clone(),  # resets (and the Ultimate engine) change boards in place
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

    def _step_proc_data(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        """Skip TorchRL's per-key completion of the step output when it has nothing to do.

        Why exact: ``_step`` always emits ``reward`` (B, 1) and the three done keys in their spec shapes, so
        the generic pass (reshape the reward to its spec, add missing done keys) changes nothing; only the
        optional type checks (``run_type_checks``) go through it. ``tests/test_env_speed.py`` compares both.
        """
        if self.run_type_checks:
            return super()._step_proc_data(next_tensordict)
        return next_tensordict

    def _reset_proc_data(self, tensordict: TensorDictBase | None, tensordict_reset: TensorDictBase) -> TensorDictBase:
        """Merge the reset output into the input TensorDict with one update instead of a per-key ``where``.

        Why this is exact: the env is stateful and ``_reset`` returns every game's current state, so for the
        games not reset its values equal the input's (the previous step's output); TorchRL's generic path
        (``where(~_reset, input, reset_output)`` over every key, ~2 ms at batch 1024 with our 16 keys) would
        pick the same numbers. Keys the env does not emit (e.g. a policy's outputs) are padded with 0 on the
        reset rows exactly as TorchRL does. ``_reset`` never leaves a reset game done, so the done check is
        skipped too.
        """
        if tensordict is None:
            return tensordict_reset
        reset = tensordict.pop("_reset", None)
        emitted = set(tensordict_reset.keys())
        others = [key for key in tensordict.keys() if key not in emitted]  # e.g. "action", a policy's outputs
        padded: dict[str, Any] = {}
        if others and reset is not None and not bool(reset.all()):
            keep = ~reset.reshape(self.batch_size)
            for key in others:
                value = tensordict.get(key)
                if isinstance(value, torch.Tensor):
                    condition = keep.reshape(keep.shape + (1,) * (value.ndim - keep.ndim))
                    padded[key] = torch.where(condition, value, torch.zeros((), dtype=value.dtype))
                else:  # a nested TensorDict: TorchRL's own padding
                    padded[key] = value.where(keep, value.empty(), pad=0)
        if type(tensordict) is TensorDict and not tensordict.is_locked and tensordict.batch_size == self.batch_size:
            # a plain dict update: every value was built by the env with this batch size and device, so the
            # per-key validation of TensorDict.update (~40 µs a key) has nothing to find
            tensordict._tensordict.update(tensordict_reset._tensordict)
            tensordict._tensordict.update(padded)
            return tensordict
        return tensordict.update(tensordict_reset).update(padded)

    def _reset_rows(self, index: torch.Tensor) -> None:
        """Start new dialogues in the games ``index`` (int64 (N,)); the others keep their state.

        Why indices rather than a bool column: a broadcast ``where`` / ``masked_fill`` over (B, F) costs
        ~0.5 ns per element (15-50 µs at batch 1024), ``index_fill_`` / an index copy a few µs.
        """
        boards = self.boards
        # in place: the engine's tensors never leave the env (outputs copy them), so nobody else holds them
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
        if self.starts in ("robot", "human"):
            robot = self.starts == "robot"
            self.d.robot_first = self.d.robot_first.index_fill(0, index, robot)
            self.d.flags.index_fill_(0, index, ROBOT_FIRST if robot else 0)
        else:
            if self.starts == "alternate":
                first = self.d.episodes.index_select(0, index) % 2 == 0
                self.d.episodes.index_add_(0, index, torch.ones_like(index))
            else:  # one draw per game, reset or not (the random stream does not depend on which games reset)
                first = (torch.rand(self.batch_size, generator=self._rng) < 0.5).index_select(0, index)
            self.d.robot_first = self.d.robot_first.index_copy(0, index, first.unsqueeze(1))
            self.d.flags.index_copy_(0, index, first.long() * ROBOT_FIRST)
        mask, dialogue_mask, lookahead = self._fresh_rows
        self.d.mask = _paste_rows(self.d.mask, index, mask)
        self.d.dialogue_mask = _paste_rows(self.d.dialogue_mask, index, dialogue_mask)
        self.d.lookahead = _paste_rows(self.d.lookahead, index, lookahead)

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
        accepted = self.d.mask.gather(1, index).squeeze(1)
        reward = self.d.lookahead.gather(1, index)
        said = (act_type + 1) * accepted  # the accepted act's type + 1, 0 if refused: the new "last system act"

        robot_moves = said == dlg.MOVE + 1
        if bool(robot_moves.any()):
            self.engine.play(self.boards, action, ROBOT, robot_moves)
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
            user_move = torch.where(user_moves, cells_taken, -1)
        else:
            user_move = torch.full_like(action, -1)
        user_act = self._utterance_acts.index_select(0, utterance)
        talk = said * N_USER + (user_act + 1)  # 0 for a refused act (silence)
        flags = flags | self._talk_flags.index_select(0, talk)

        # the commands and words of the robot's act, with the user's words at their ASR confidence (the larger
        # of the two where both said a word); refused acts leave the last ones (rare with a masked policy)
        columns = self._utterance_word_columns.index_select(0, utterance)
        confidence = torch.rand(columns.shape, generator=self._rng)
        if self._asr_scaled:
            confidence = confidence * (self.asr_high - self.asr_low) + self.asr_low
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

    def _reply_tables(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(contexts,) reply counts and the flat (contexts * (K + 1)) utterance ids of the simulated user, where
        context = act type * phases + phase, derived from ``self.model`` (read each step: ``ncbot play`` swaps
        in or edits its tables to make the user say what a person typed; rebuilt when they change).

        Column 0 of a context without replies holds silence, and column K repeats column K - 1, so the pick
        ``floor(u * count)`` needs neither the ``count > 0`` test nor a clamp: same utterances as reading
        ``reply_options`` with ``min(pick, K - 1)`` and silencing contexts without replies. A move utterance in
        a context where the user does not move (an act the data never shows; ``ncbot play`` can set one) is
        silence too, as the user says nothing it cannot do.
        """
        options, counts = self.model.reply_options, self.model.reply_counts
        key = (options, counts, options._version, counts._version)  # holds the tensors: identity checks stay valid
        last = self._reply_key
        if last is None or last[0] is not options or last[1] is not counts or last[2:] != key[2:]:
            flat = options.reshape(-1, options.shape[-1])
            replies = torch.cat([flat, flat[:, -1:]], dim=1)
            replies[counts.reshape(-1) == 0, 0] = self._silence
            moves_without_move = self._utterance_is_move[replies] & ~self._user_turn.unsqueeze(1)
            replies[moves_without_move] = self._silence
            self._reply_key, self._replies = key, (counts.reshape(-1).clone(), replies.reshape(-1).contiguous())
        return self._replies

    def _user_cells(self, rows: torch.Tensor) -> torch.Tensor:
        """(B,) the user's square in ``rows`` (other rows: meaningless): uniform among legal ones, or the opponent's choice."""
        if self.opponent is None:
            # picks outside ``rows`` are discarded by the caller; each row draws one number either way, so
            # leaving the other rows unmasked changes neither the moves nor the random stream (one op less)
            return self.engine.random_legal(self.boards, self._rng)
        legal = self.engine.legal(self.boards) & rows.unsqueeze(1)
        index = rows.nonzero().squeeze(1)
        boards = self.boards
        kwargs: dict[str, Any] = {"rows": index} if "rows" in self._opponent_params else {}
        if "owners" in self._opponent_params and self.game == "ultimate":
            kwargs["owners"] = boards.owners[index].to(torch.int8)
        chosen = torch.as_tensor(
            self.opponent.select(boards.board[index], boards.last_move[index], legal[index], USER, self._rng, **kwargs)
        ).reshape(-1).long()
        if chosen.shape[0] != index.shape[0] or not bool(legal[index].gather(1, chosen.clamp(0, self.cells - 1).unsqueeze(1)).all()):
            raise ValueError(f"opponent {self.opponent!r} returned an illegal or malformed move {chosen.tolist()}")
        cells = torch.zeros(rows.shape[0], dtype=torch.int64)
        cells[index] = chosen
        return cells

    def rand_action(self, tensordict: TensorDictBase | None = None) -> TensorDictBase:
        """A uniformly random action among those the mask allows (never a masked one)."""
        if tensordict is None:
            tensordict = TensorDict(batch_size=self.batch_size)
        mask = tensordict.get("action_mask", None)
        if mask is None:
            mask = self.d.mask
        tensordict.set("action", uniform_choice(mask, self._action_rng))
        return tensordict

    def _set_seed(self, seed: int | None) -> None:
        seed = 0 if seed is None else int(seed)
        self._rng.manual_seed(seed)
        self._action_rng.manual_seed(seed + 1)


class _Dialogues:
    """Per-game dialogue state and the current mask / look-ahead, each a tensor with the batch first.

    A plain object (not attributes of the env): EnvBase is an nn.Module, whose attribute setting costs
    ~20 µs, and the step replaces these tensors every call.
    """

    flags: torch.Tensor  # (B,) ROBOT_FIRST | AGREED (the user agreed to play) | CLOSED (the robot said goodbye)
    talk: torch.Tensor  # (B,) last accepted system act type + 1 (0: none), times N_USER, + last user act + 1 (0: none / silence)
    robot_first: torch.Tensor  # (B, 1) bool
    episodes: torch.Tensor  # (B,) dialogues started (counted for starts="alternate" only)
    turn: torch.Tensor  # (B, 1) actions taken in this dialogue
    user_act: torch.Tensor  # (B, 1) the user's act in the last step (-1 none)
    user_move: torch.Tensor  # (B, 1) the user's square in the last step (-1 none)
    user_utterance: torch.Tensor  # (B, 1) id of the user's utterance in the last step (-1 none)
    words: torch.Tensor  # (B, C + V + 1) the observation's commands + words (last column: spare, hit by padding)
    mask: torch.Tensor  # (B, A) action_mask
    dialogue_mask: torch.Tensor  # (B, A) the act filter alone
    lookahead: torch.Tensor  # (B, A) one-step reward of every action
    observation: torch.Tensor  # (B, F) the observation of the last output (reused by partial resets)
    winning_actions: torch.Tensor  # (B, A) the winning actions of the last output
    done_flags: tuple[torch.Tensor, torch.Tensor, torch.Tensor]  # (B, 1) terminated, truncated, done of the last output


def _paste_rows(values: torch.Tensor, index: torch.Tensor, row: torch.Tensor) -> torch.Tensor:
    """A copy of ``values`` (B, F) with ``row`` (F,) in the rows ``index``: 3-4x faster than a broadcast ``where``."""
    return values.index_put((index,), row)


def _check_batch(batch_size: Any) -> int:
    if isinstance(batch_size, int):
        batch_size = (batch_size,)
    try:
        dims = tuple(int(b) for b in batch_size)
    except TypeError:
        raise ValueError(f"batch_size must be an int or a 1-tuple like (64,), got {batch_size!r}") from None
    if len(dims) != 1 or dims[0] < 1:
        raise ValueError(f"batch_size must be a 1-tuple with a positive size like (64,), got {batch_size!r}")
    return dims[0]


def _check_confidence(bounds: Any) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"asr_confidence must be (low, high) of a uniform distribution in [0, 1], got {bounds!r}") from None
    if not 0.0 <= low <= high <= 1.0:
        raise ValueError(f"asr_confidence must satisfy 0 <= low <= high <= 1, got {bounds!r}")
    return low, high
