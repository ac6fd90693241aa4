"""Typed run configuration, grouped by concern like TorchRL's sota configs, loaded from YAML and validated by pydantic.

Every hyper-parameter is named and documented here, in one place (CleanRL style). Validation is pydantic's
(strict types, `extra="forbid"`, range constraints on the fields); `ncbot.pipelines.config.files.load_config` reads a
YAML file with `section.key=value` overrides and raises `ValueError` with ONE line naming the bad key and what is
allowed (`ncbot.pipelines.config.errors`); the CLI turns that into exit code 2.

Importing this module stays light (pydantic and yaml, no torch): the CLI and tools read configs without paying
for torch.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, field_validator, model_validator

GAMES = ("standard", "ultimate")
AGENTS = ("dqn_original", "dqn_variant", "proposed")


def _yaml_number(value: Any) -> Any:
    """YAML 1.1 reads 5e-4 (no dot) as a string: accept it where a number is expected."""
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


Number = Annotated[float, BeforeValidator(_yaml_number), Field(allow_inf_nan=False)]  # finite: nan/inf is a typo
Positive = Annotated[int, Field(gt=0)]
# Upper bounds: far above any run this project makes, far below what exhausts memory or overflows (a typo such as
# env.batch_size=100000000000 is one line at start-up, not an allocation error minutes later); docs/reliability.md.
MAX_BATCH = 65_536  # env games in parallel, sampled transitions per update
MAX_WIDTH = 4_096  # units of one hidden layer (paper: 100 / 150)
MAX_LAYERS = 16
MAX_FRAMES = 10_000_000_000  # env frames of one run (paper: 400K)
EveryFrames = Annotated[int, Field(gt=0, le=MAX_FRAMES)]  # a period in env frames: longer than any run is a typo
MAX_SEED = 2**32 - 1
MAX_GAMES = 10_000_000  # test games of one evaluation: hours of CPU already
Fraction = Annotated[Number, Field(ge=0.0, le=1.0)]
DEVICE_PATTERN = re.compile(r"auto|cpu|cuda(:[0-9]{1,3})?")  # train.device


class Section(BaseModel):
    """One YAML section: strict types (no "3" for 3, no 1.5 for an int), unknown keys rejected."""

    model_config = ConfigDict(extra="forbid", strict=True)


class DialogueSubset(Section):
    """Learn the act filter and the simulated user from a seeded subset of k example dialogues (`ncbot reproduce
    budget`); the vocabulary stays the whole set's, so the network's input size does not depend on k."""

    # null = every dialogue of the set (the default, bit-identical to no subset); up to 12 = a seeded draw from the
    # set's dozen; 13-24 = the dozen plus k - 12 of our authored dialogues (dialogues=paper only)
    k: Annotated[int, Field(gt=0, le=24)] | None = None
    seed: Annotated[int, Field(ge=0, le=MAX_SEED)] = 0  # which k dialogues are drawn


class EnvConfig(Section):
    """The dialogue game the robot learns (envs.make_env)."""

    game: str = "standard"  # standard | ultimate | a shipped declared game (four, connect_four) | a game YAML file
    temporal: bool = True  # the paper's 9/81 temporal features
    free_move: Literal["anywhere", "open_subgrids"] = "anywhere"  # ultimate rule variant
    batch_size: Annotated[int, Field(gt=0, le=MAX_BATCH)] = 128  # games played in parallel by one batched env
    first: Literal["robot", "human", "alternate", "random"] = "alternate"  # who opens the training games
    opponent: str = "random"  # envs.opponents name of the simulated user's move policy
    max_steps: Annotated[int, Field(gt=0, le=10_000)] = 100  # actions per dialogue before truncation (paper: 100)
    # The paper's ambiguous readings (envs.core, docs/env.md "Readings"; pipelines/configs/paper/ set the ones
    # closest to the text). taken_squares: "moves ... allowed from the subset of those not taken yet (to the robot's
    # knowledge)" vs "-5 ... a repeated (already taken) action": never (only untaken squares offered) | refused
    # (taken squares offered too, refused at -5 with nothing changed) | misread (the robot misreads a user move
    # with probability misread_rate; a square really taken is refused at -5 and the sheet is read again) | offered
    # (misread, and the squares the robot knows are taken are offered too: the -5 payable without look-ahead masks)
    taken_squares: Literal["never", "refused", "misread", "offered"] = "never"
    misread_rate: Annotated[Number, Field(gt=0.0, lt=1.0)] | None = None  # required with misread / offered, else unset
    # what winning_actions (Algorithm 2's set A) holds: every +5 move | only "action(s) leading to win ... the game"
    win_set: Literal["wins_and_threats", "wins"] = "wins_and_threats"
    # "+5 win or about to win": about to win paid on every move after which a winning square stands | only on the
    # move that creates it
    about_to: Literal["standing", "created"] = "standing"
    # example dialogues the act filter, vocabulary and simulated user are learnt from: compact (ours: the user answers
    # a robot move with its own) | paper ("your turn" before every user move, "Nice. Let me start."; ~14 acts on 3x3)
    dialogues: Literal["compact", "paper"] = "compact"
    dialogue_subset: DialogueSubset | None = None  # the data budget: learn from k of those dialogues; null = all

    @field_validator("game")
    @classmethod
    def _known_game(cls, game: str) -> str:
        """A built-in name, a shipped declaration or a game YAML file (docs/games.md); a file becomes its absolute
        path, so a run folder's config names the same game from anywhere."""
        from ncbot.envs.core import check_game

        return check_game(game)

    @property
    def subset(self) -> tuple[int, int] | None:
        """The env's ``dialogue_subset`` option: None (every dialogue) or (k, seed)."""
        chosen = self.dialogue_subset
        return None if chosen is None or chosen.k is None else (chosen.k, chosen.seed)

    @property
    def threats(self) -> bool:
        """The env's ``threat_features`` option (beyond the paper): the observation ends with threat planes."""
        return bool(self.options.get("threat_features", False))
    # what the robot hears of the simulated user: uniform (the words said, uniform random confidences) | channel
    # (words and confidences sampled from the ASR channel model fitted on TTS -> noise -> pocketsphinx round trips,
    # docs/speech.md) at an SNR drawn per utterance in asr_snr_db, in asr_noise; asr_channel: None = shipped model
    asr: Literal["uniform", "channel"] = "uniform"
    asr_snr_db: Annotated[list[float], Field(min_length=2, max_length=2)] = Field(default_factory=lambda: [10.0, 30.0])
    asr_noise: Literal["white", "babble"] = "babble"
    asr_channel: str | None = None
    options: dict[str, Any] = Field(default_factory=dict)  # extra keyword arguments for envs.make_env

    @model_validator(mode="after")
    def _snr_order(self) -> EnvConfig:
        if self.asr_snr_db[0] > self.asr_snr_db[1]:
            raise ValueError(f"env.asr_snr_db must be [low, high] with low <= high, got {list(self.asr_snr_db)}")
        if self.dialogues == "compact" and self.subset is not None and self.subset[0] > 12:
            raise ValueError(f"env.dialogue_subset.k must be <= 12 with env.dialogues: compact (a dozen example "
                             f"dialogues per game; 13-24 exist for dialogues: paper), got {self.subset[0]}")
        if (self.taken_squares in ("misread", "offered")) != (self.misread_rate is not None):
            raise ValueError(f"env.misread_rate must be set (a number in (0, 1)) with env.taken_squares: misread or offered and "
                             f"unset otherwise; got taken_squares {self.taken_squares!r}, misread_rate {self.misread_rate!r}")
        if self.asr_channel is not None and not Path(self.asr_channel).is_file():
            raise ValueError(f"env.asr_channel {self.asr_channel!r} is not a file (an ASR channel model: python -m ncbot.speech.fit)")
        return self


class AgentConfig(Section):
    """Which learner: the paper's three agents, each with its own look-ahead masks, or `uniform`: no learning, a
    uniform choice inside the greedy mask of `lookahead` (default Proposed's one-step masks), the baseline that
    shows what learning adds (pipelines/train/uniform.py)."""

    name: Literal["dqn_original", "dqn_variant", "proposed", "uniform"] = "proposed"
    lookahead: str | None = None  # mask rule override (modules.masks); None = the agent's own rule
    # where the greedy mask falls back when every action of set A has a negative look-ahead reward (the paper leaves
    # it open; modules.mask_rules): available = set A | untaken = set A without the squares taken to the robot's
    # knowledge ("moves ... allowed from the subset of those not taken yet (to the robot's knowledge)")
    all_negative: Literal["available", "untaken"] = "available"
    # paper: 3 x 100 (or 150 on ultimate)
    hidden: Annotated[list[Annotated[int, Field(gt=0, le=MAX_WIDTH)]], Field(min_length=1, max_length=MAX_LAYERS)] = \
        Field(default_factory=lambda: [100, 100, 100])
    # a recurrent Q-network (modules/recurrent.py): the MLP of `hidden`, then a GRU or LSTM of `memory_size` units
    # whose state runs through each dialogue, learnt from replayed slices of dialogues (buffer.sequence_length);
    # none = the paper's feed-forward network. Why: the paper names recurrent networks as the comparison its
    # temporal features leave open
    memory: Literal["none", "gru", "lstm"] = "none"
    memory_size: Annotated[int, Field(gt=0, le=MAX_WIDTH)] = 128


class CollectorConfig(Section):
    """How experience is gathered (TorchRL Collector) and how exploration anneals."""

    frames_per_batch: Annotated[int, Field(gt=0, le=2**20)] = 1024  # env frames (robot actions) per collected batch
    total_frames: Annotated[int, Field(gt=0, le=MAX_FRAMES)] = 100_000  # training length in frames (paper: 400K steps)
    init_random_frames: Annotated[int, Field(ge=0, le=MAX_FRAMES)] = 1_000  # burn-in: updates start once the buffer holds this many frames
    eps_init: Fraction = 1.0
    eps_end: Fraction = 0.005  # paper: minimum epsilon 0.005
    annealing_frames: Annotated[int, Field(gt=0, le=MAX_FRAMES)] = 20_000  # frames over which epsilon decays linearly


class BufferConfig(Section):
    """Experience replay (TensorDictReplayBuffer over LazyTensorStorage)."""

    size: Annotated[int, Field(gt=0, le=10_000_000)] = 10_000  # paper: 10,000
    batch_size: Annotated[int, Field(gt=0, le=MAX_BATCH)] = 128  # sampled transitions per update (paper: 2)
    # each sampled transition seen under a random rotation/reflection of the board (modules/symmetry.py): none | d4
    augment: Literal["none", "d4"] = "none"
    # prioritised replay (Schaul et al. 2016; modules/prioritized_sampler.py, TorchRL's PrioritizedSampler
    # contract): rows drawn in proportion to |TD error| ** alpha, the loss weighted by (p / p_min) ** -beta. Why: on
    # Ultimate a loss to the random user is rare, so a uniform buffer replays its surprising last steps as rarely.
    # Measured on ultimate.yaml: robot second worse, not better (docs/ultimate.md); on 3x3 it cuts
    # the mid-training robot-second losses 4-5x and is on in default.yaml (docs/learning.md).
    # With agent.memory: slices drawn by R2D2's sequence priority (modules/prioritized_slices.py, docs/memory.md).
    prioritized: bool = False
    alpha: Fraction = 0.6
    beta: Fraction = 0.4
    # agent.memory only (modules/recurrent.py): slices of this many steps of one dialogue are replayed (batch_size
    # counts their steps and must be a multiple); the first burn_in steps of a slice that starts inside a dialogue
    # only rebuild the hidden state from the stored one and carry no loss (R2D2's burn-in)
    sequence_length: Annotated[int, Field(gt=0, le=1_000)] = 16
    burn_in: Annotated[int, Field(ge=0, le=1_000)] = 4


class OptimConfig(Section):
    """Adam on the Q-network; the paper does not state these, so they are ours."""

    lr: Annotated[Number, Field(gt=0)] = 1e-3
    updates_per_batch: Annotated[int, Field(gt=0, le=10_000)] = 8  # gradient updates per collected batch
    max_grad_norm: Number = 10.0
    weight_decay: Number = 0.0
    # matrix products of the learner's forward/backward: fp32, or bf16 (CPU autocast, float32 weights, gradients and
    # loss kept); bf16 changes the numbers of a seed, hence off by default (docs/learner-speed.md)
    precision: Literal["fp32", "bf16"] = "fp32"


class ScheduleConfig(Section):
    """Learning-rate schedule over the training frames (optim.lr is the start value)."""

    # decay lr linearly to this (> 0, <= optim.lr) by collector.total_frames; quiets Q near convergence
    lr_end: Annotated[Number, Field(gt=0)] | None = None


class LossConfig(Section):
    """Competitive DQN target and error."""

    gamma: Fraction = 0.7  # paper: 0.7
    reward: Literal["paper", "outcome"] = "paper"  # what the learner trains on (modules.rewards); metrics use paper
    # outcome reward for a lost game (paper scale: -5). Against the random user a -5 loss is worth risking for a
    # likelier fast win (exact expectimax robot-second: 0.9291 wins, 0.0042 losses); <= -15 makes the optimum
    # loss-free (0.9164 wins, zero losses), which is what task success 1.000 asks for.
    loss_reward: Annotated[Number, Field(lt=0)] = -5.0  # used with reward: outcome only
    loss_function: Literal["l2", "huber"] = "l2"  # paper: squared error
    double_dqn: bool = False
    target_update: Literal["hard", "soft"] = "hard"  # paper: hard copy every C updates
    target_period: Positive = 50  # C, in gradient updates (hard)
    tau: Fraction = 0.005  # soft update rate
    # n-step returns (modules/transitions.py, TorchRL's MultiStepTransform): the target sums up to n discounted
    # rewards, then bootstraps with gamma**k (k = the steps the window really spans, fewer at a game's end);
    # 1 = the paper's one-step target. Why: Ultimate's outcome reward reaches the opening ~16 decisions back.
    n_step: Annotated[int, Field(gt=0, le=1_000)] = 1
    # which next actions the TD target maximises over (modules/bootstrap.py): every available one (the paper) or
    # only the agent's greedy set, the actions it can actually play; untrained actions outside it inflate targets
    bootstrap: Literal["available", "greedy"] = "available"


class TrainConfig(Section):
    """Run-level settings."""

    seed: Annotated[int, Field(ge=0, le=MAX_SEED)] = 0
    # stop after this many finished training dialogues, frames ignored; None = frames
    episodes: Annotated[int, Field(gt=0, le=10**9)] | None = None
    # stop at collector.total_frames or after this many finished training games, whichever comes first (the paper:
    # "400K learning steps or 20K games, whatever occurred first"); None = frames only
    max_games: Annotated[int, Field(gt=0, le=10**9)] | None = None
    eval_every_frames: EveryFrames = 10_000  # periodic greedy evaluation (logged with its wall time)
    num_threads: Annotated[int, Field(gt=0, le=1_024)] = 1  # torch threads: small tensors are fastest on one thread
    # where the networks, loss, target network, optimiser and replay storage live: auto (CUDA when torch sees a GPU,
    # else cpu) | cpu | cuda | cuda:N; the env always runs on the CPU. A seed's numbers are reproducible per device
    # (a GPU draws its own random streams and sums in another order): modules/device.py, docs/device.md
    device: str = "auto"

    @field_validator("device")
    @classmethod
    def _device_spelling(cls, value: str) -> str:
        """auto | cpu | cuda | cuda:N, checked here without torch; whether the machine has it: at the run's start."""
        if not DEVICE_PATTERN.fullmatch(value):
            raise ValueError(f"config key 'train.device' must be auto, cpu, cuda or cuda:N (N a GPU index), "
                             f"got {value!r}")
        return value


class EvalConfig(Section):
    """Greedy test games against the simulated user (paper: 3000)."""

    games: Annotated[int, Field(gt=0, le=MAX_GAMES)] = 3000  # final evaluation
    periodic_games: Annotated[int, Field(gt=0, le=MAX_GAMES)] = 500  # each periodic evaluation during training
    first: Literal["robot", "human", "alternate"] = "alternate"  # who opens the test games
    opponent: str = "random"


class LoggerConfig(Section):
    """What a run records besides checkpoints."""

    mcap: bool = True  # every episode to MCAP (logs package)
    progress: bool = True  # progress bar on a terminal, a plain line every ~10 % when piped (pipelines/progress.py)
    # scalars (train/loss, train/epsilon, ..., eval/task_success, ...) through TorchRL's loggers into the run folder:
    # csv (RUN/scalars/scalars/*.csv) | tensorboard | wandb | mlflow (each when installed) | none
    backend: Literal["csv", "tensorboard", "wandb", "mlflow", "none"] = "csv"


class CheckpointConfig(Section):
    """Periodic checkpoints (atomic write + rename) that `--resume` continues from."""

    every_frames: EveryFrames = 10_000
    keep: Annotated[int, Field(gt=0, le=1_000)] = 2  # periodic checkpoints kept on disk
    save_buffer: bool = True  # include the replay buffer so a resumed run continues with the same experience


class SelfPlayConfig(Section):
    """Self-play option of a run (section ``selfplay``; pipelines/train/selfplay.py): the user's moves by frozen snapshots."""

    enabled: bool = False
    pool_size: Annotated[int, Field(gt=0, le=1_000)] = 5  # frozen snapshots kept; the oldest is dropped when a new one arrives
    snapshot_every_frames: EveryFrames = 5_000  # a snapshot of the learning Q-network every this many frames
    random_share: Fraction = 0.2  # share of the user's moves still made by the paper's uniformly random user
    epsilon: Fraction = 0.05  # random moves of a snapshot (keeps self-play games diverse)


class SearchTargetsConfig(Section):
    """Targets improved by search (section ``search_targets``; modules/search_targets.py): expert iteration into Q.

    After ``start_frames``, ``rows_per_batch`` robot game moves of every collected batch are searched by the
    Q-guided MCTS of the current network (``simulations`` each); the searched move is kept as a label and each
    update adds ``weight`` x DQfD's large-margin loss on a batch of labels (Q of the searched move above the moves
    the search valued ``gap`` below it, or above every move of the greedy mask, by ``margin``). Why: search distilled into the
    network (AlphaZero / expert iteration distil search into the network). Measured on ultimate.yaml: robot second worse
    with every teacher tried (docs/ultimate.md)."""

    enabled: bool = False
    simulations: Annotated[int, Field(gt=0, le=100_000)] = 32
    rows_per_batch: Annotated[int, Field(gt=0, le=100_000)] = 16  # searched robot moves per collected batch
    seat: Literal["both", "second"] = "both"  # label moves from every game, or only from robot-second games
    start_frames: Annotated[int, Field(ge=0, le=10**10)] = 1_000_000  # the network should be worth searching first
    weight: Annotated[Number, Field(ge=0)] = 1.0  # of the margin loss, beside the TD loss
    margin: Annotated[Number, Field(gt=0)] = 1.0  # l(a_E, a) of DQfD, in Q units (the paper's rewards are +-5)
    # the margin holds against moves the search valued below the searched one by more than this (win probability);
    # null: against every move of the greedy mask (DQfD as published)
    gap: Fraction | None = 0.1
    buffer_size: Annotated[int, Field(gt=0, le=10_000_000)] = 50_000  # labels kept (the newest)
    batch_size: Annotated[int, Field(gt=0, le=MAX_BATCH)] = 128  # labels per update
    # Ultimate: a value network (ncbot train-value, for the run's free-move rule) scores the search's leaves
    # instead of Q + random playouts; its training time belongs to the run's budget
    value: str | None = None


class RunConfig(Section):
    """One training run: every section of the YAML file (pydantic copies each default section per instance)."""

    env: EnvConfig = EnvConfig()
    agent: AgentConfig = AgentConfig()
    collector: CollectorConfig = CollectorConfig()
    buffer: BufferConfig = BufferConfig()
    optim: OptimConfig = OptimConfig()
    schedule: ScheduleConfig = ScheduleConfig()
    loss: LossConfig = LossConfig()
    train: TrainConfig = TrainConfig()
    eval: EvalConfig = EvalConfig()
    logger: LoggerConfig = LoggerConfig()
    checkpoint: CheckpointConfig = CheckpointConfig()
    selfplay: SelfPlayConfig = SelfPlayConfig()
    search_targets: SearchTargetsConfig = SearchTargetsConfig()

    @model_validator(mode="after")
    def _check_across_sections(self) -> RunConfig:
        """The checks one field cannot express alone."""
        lr_end = self.schedule.lr_end
        if lr_end is not None and lr_end > self.optim.lr:
            raise ValueError(f"config key 'schedule.lr_end' must be > 0 and <= optim.lr ({self.optim.lr}), got {lr_end}")
        if self.agent.memory != "none":
            self._check_memory()
        if self.agent.lookahead is not None:
            from ncbot.modules.masks import LOOKAHEAD_RULES  # torch: only when an override needs checking

            if self.agent.lookahead not in LOOKAHEAD_RULES:
                raise ValueError(f"config key 'agent.lookahead' must be one of {sorted(LOOKAHEAD_RULES)} or null, "
                                 f"got {self.agent.lookahead!r}")
            if self.agent.lookahead.startswith("k") and self.env.game not in GAMES:
                raise ValueError(f"config key 'agent.lookahead' {self.agent.lookahead!r} searches 3x3 and Ultimate only; "
                                 f"the declared game {self.env.game!r} takes none, variant or one_step")
        return self

    def _check_memory(self) -> None:
        """What a recurrent agent (agent.memory) cannot be combined with yet, each a one-line reason."""
        memory, buffer = self.agent.memory, self.buffer
        if buffer.burn_in >= buffer.sequence_length:
            raise ValueError(f"config key 'buffer.burn_in' must be < buffer.sequence_length ({buffer.sequence_length}) "
                             f"with agent.memory={memory}, got {buffer.burn_in}")
        if buffer.batch_size % buffer.sequence_length:
            raise ValueError(f"config key 'buffer.batch_size' must be a multiple of buffer.sequence_length "
                             f"({buffer.sequence_length}) with agent.memory={memory}, got {buffer.batch_size}")
        unsupported = [
            ("agent.name", self.agent.name == "uniform", "a learning agent", "the uniform agent has no network"),
            ("loss.n_step", self.loss.n_step != 1, "1", "the slice's unroll gives the one-step target"),
            ("optim.precision", self.optim.precision != "fp32", "fp32", "the recurrent unroll runs in float32"),
            ("selfplay.enabled", self.selfplay.enabled, "false", "snapshots play the user as an MLP"),
            ("search_targets.enabled", self.search_targets.enabled, "false", "the search reads Q as an MLP"),
        ]
        for key, clash, allowed, why in unsupported:
            if clash:
                raise ValueError(f"config key '{key}' must be {allowed} with agent.memory={memory} ({why})")

    @property
    def lookahead(self) -> str:
        """The mask rule this run uses: the override, else the agent's own."""
        from ncbot.modules.masks import AGENT_LOOKAHEAD

        return self.agent.lookahead or AGENT_LOOKAHEAD[self.agent.name]

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (checkpoints and config.yaml store it)."""
        return self.model_dump()


# --- loading -----------------------------------------------------------------------------------------------------
