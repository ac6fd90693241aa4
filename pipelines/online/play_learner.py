"""Play that learns from play: the games' logged transitions feed the agent's own learner between games, mixed
with simulation, so the robot adapts to a person who plays otherwise than the simulated random user.

After each game (`PlayLearner.add_game`): its transitions, read back from the MCAP log (`ncbot.pipelines.online.
logged.game_transitions`), join the play buffer, and the person's moves refit a model of how they play
(`ncbot.pipelines.online.person_model`); `sim_frames` fresh env steps join the simulation buffer, half against that
model of the person and half against the run's own simulated user (so the agent keeps what it learnt there); then
`updates` gradient steps of the run's own update (loss, target network, optimiser, board symmetries), each on a
batch of which `play_share` comes from play and the rest from simulation. That is the bound on a game's compute.
The update is kept only if it is not worse where it can be checked: against the random user its task success
(on 3x3 exact, over every branch of the user's moves from both seats; else `gate_games` greedy test games from both
seats) may be at most `gate_tolerance` below the starting agent's, and against the model of the person (`gate_games`
test games, the same seeds every time) no lower than the agent's it would replace; otherwise the weights go back to
the last kept ones (`gate=False` keeps every update unchecked: to measure what the gate refuses).
Every kept version is saved as a final checkpoint (`game-NNNN.pt`, loadable by `ncbot robot play` / `ncbot eval`).
"""
from __future__ import annotations

import copy
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDict

from ncbot.pipelines.online import agent_parts
from ncbot.pipelines.online.logged import LoggedGame, game_transitions, settled_moves
from ncbot.pipelines.online.person_model import PersonModel, PersonMove, person_moves

START_NAME, CURRENT_NAME, GAMES_FOLDER = "start.pt", "agent.pt", "transitions"
GATE_SEED = 7_000_003  # the gate's test games: the same every time, apart from training and evaluation seeds


@dataclass(frozen=True)
class PlayLearning:
    """How play learns from play (docs/robot.md, "Learning from play"). The defaults were set before any study
    measured them and were not tuned on the persons the results are measured against."""

    updates: int = 100            # gradient steps after each game: the compute a game may take
    batch_size: int = 256
    play_share: float = 0.25      # of each batch: transitions of the games played
    sim_frames: int = 1024        # simulated env steps added per game: half against the person's model
    lr: float = 2e-4
    gate_games: int = 2000        # test games an update must pass (against the model of the person; the random user
    #                               on games other than 3x3, which is scored exactly)
    gate_tolerance: float = 0.0   # task success it may lose against the random user, from the starting agent's
    gate: bool = True             # False: every update is kept, unchecked (to measure what the gate refuses)
    play_buffer: int = 20_000
    sim_buffer: int = 50_000
    seed: int = 0

    def validate(self) -> None:
        if self.updates < 0 or self.batch_size < 2 or self.sim_frames < 1 or self.gate_games < 2:
            raise ValueError(f"play learning needs updates >= 0, batch_size >= 2, sim_frames >= 1, gate_games >= 2; "
                             f"got {self.updates}, {self.batch_size}, {self.sim_frames}, {self.gate_games}")
        if not 0.0 < self.play_share <= 1.0 or self.lr <= 0 or not 0.0 <= self.gate_tolerance <= 1.0:
            raise ValueError(f"play learning needs 0 < play_share <= 1, lr > 0, 0 <= gate_tolerance <= 1; got "
                             f"{self.play_share}, {self.lr}, {self.gate_tolerance}")


@dataclass
class PlayUpdate:
    """What one game taught the play (the report's `per_game`, key `play`)."""

    game: int
    transitions: int = 0          # this game's decisions learned from (0: a game the env did not end)
    person_moves: int = 0         # the person's moves the model of their play learned from
    updated: bool = False
    kept: bool | None = None
    gate_task_success: float | None = None   # of the updated agent against the random user
    start_task_success: float | None = None  # of the agent the robot started with, same games
    person_task_success: float | None = None  # of the updated agent against the model of the person
    kept_person_task_success: float | None = None  # of the agent it would replace, same games, same model
    cpu_seconds: float = 0.0
    weights: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class PlayLearner:
    """The robot's agent, learning from the games it plays; `policy` is what the robot plays with (in place)."""

    config: Any
    data: dict[str, Any]
    settings: PlayLearning = field(default_factory=PlayLearning)
    folder: Path | None = None
    games: int = 0
    updates: int = 0
    kept: int = 0

    def __post_init__(self) -> None:
        self.settings.validate()
        agent_parts.check_learnable(self.config)
        self.qnet, self.policies, self.learner = agent_parts.build_agent(self.config, self.data, self.settings.seed)
        self.learner.set_lr(self.settings.lr)
        self.play_rows = agent_parts.replay_buffer(self.settings.play_buffer, 1)
        self.sim_rows = agent_parts.replay_buffer(self.settings.sim_buffer, 1)
        self.person = PersonModel(self.config.env.game, self.config.env.free_move, self.settings.seed)
        self.person_moves: list = []
        self._simulations: list = []
        self._start_success: float | None = None
        self.current = START_NAME

    @property
    def policy(self) -> Any:
        """The greedy policy the robot plays with: its network is updated in place after each kept update."""
        return self.policies.greedy

    @classmethod
    def start(cls, checkpoint: str | Path, settings: PlayLearning, folder: str | Path | None = None) -> "PlayLearner":
        config, data = agent_parts.load_saved_agent(checkpoint)
        learner = cls(config, data, settings, Path(folder) if folder is not None else None)
        if learner.folder is not None:
            (learner.folder / GAMES_FOLDER).mkdir(parents=True, exist_ok=True)
            for name in (START_NAME, CURRENT_NAME):
                agent_parts.save_agent(learner.folder / name, config, data, learner.qnet, learned_games=0)
        return learner

    @classmethod
    def resume(cls, folder: str | Path, state: dict[str, Any], settings: PlayLearning) -> "PlayLearner":
        """The learner as `state()` described it: the weights it named, the transitions of its games (the
        optimiser's moments and the simulation stream start afresh)."""
        folder = Path(folder)
        config, data = agent_parts.load_saved_agent(folder / START_NAME)
        _, current = agent_parts.load_saved_agent(folder / str(state["current"]))
        learner = cls(config, data, settings, folder, **{key: int(state[key]) for key in ("games", "updates", "kept")})
        learner.qnet.load_state_dict(current["qnet"])
        learner.current = str(state["current"])
        for game in range(learner.games):
            learner._load_game(folder / GAMES_FOLDER / f"game-{game:04d}.pt")
        learner.person.fit(learner.person_moves)
        return learner

    def state(self) -> dict[str, Any]:
        return {"games": self.games, "updates": self.updates, "kept": self.kept, "current": self.current}

    # ------------------------------------------------------------------ learning
    def gate(self, opponent: Any = "random") -> float:
        """Task success of the current greedy agent against `opponent`: the random user on a 3x3 board exactly, over every
        branch of its moves from both seats (`ncbot.pipelines.evaluate.exact`); else, and against the model of the
        person, in the gate's test games."""
        if opponent == "random" and agent_parts.exact_applies(self.config.env.game):
            return agent_parts.exact_task_success(self.config, self.policy, GATE_SEED)
        result = agent_parts.test_games(self.config, self.policy, self.settings.gate_games, GATE_SEED, opponent)
        return float(result.task_success)

    def _simulate(self) -> None:
        """Half the frames against the model of the person (refitted each game, played in place), half against
        the run's own simulated user."""
        if not self._simulations:
            seed = self.settings.seed * 1_000_003 + self.games
            frames = max(1, self.settings.sim_frames // 2)
            self._simulations = [agent_parts.simulation(self.config, self.policies.explore, frames, seed + k, opponent)
                                 for k, opponent in enumerate((self.person, None))]
        for simulation in self._simulations:
            self.sim_rows.extend(agent_parts.buffer_rows(next(simulation), self.config))

    def learn_person(self, game: LoggedGame) -> int:
        """Refit the model of the person to all their moves so far; returns this game's moves."""
        moves = person_moves(settled_moves(game), game.summary.get("seat") == "first", self.config.env.game,
                             self.config.env.free_move)
        self.person_moves.extend(moves)
        self.person.fit(self.person_moves)
        return len(moves)

    def _batch(self, generator: torch.Generator) -> TensorDict:
        settings = self.settings
        n_play = max(1, round(settings.batch_size * settings.play_share))
        parts = [self._sample(self.play_rows, n_play, generator)]
        if settings.batch_size > n_play:
            parts.append(self._sample(self.sim_rows, settings.batch_size - n_play, generator))
        return torch.cat(parts)

    @staticmethod
    def _sample(buffer: Any, count: int, generator: torch.Generator) -> TensorDict:
        storage = buffer.storage
        rows = torch.randint(len(buffer), (count,), generator=generator)
        return storage[rows]

    def add_game(self, game: LoggedGame) -> PlayUpdate:
        """Learn from one logged game (a bounded update, kept only if it passes the gate)."""
        started = time.process_time()
        report = PlayUpdate(game=self.games)
        moves_before = len(self.person_moves)
        report.person_moves = self.learn_person(game)
        batch = game_transitions(game, self.data["n_features"], self.data["n_actions"])
        rows = None if batch is None else agent_parts.buffer_rows(batch, self.config)
        if rows is not None:
            report.transitions = len(rows)
            self.play_rows.extend(rows)
        if self.folder is not None:
            self._save_game(rows, self.person_moves[moves_before:])
        if report.transitions and self.settings.updates:
            self._update(report)
        self.games += 1
        report.cpu_seconds = round(time.process_time() - started, 3)
        return report

    def _save_game(self, rows: TensorDict | None, moves: list) -> None:
        """What a resumed learner needs of this game: its transitions and the person's moves (tensors only)."""
        saved = {"rows": None if rows is None else rows.to_dict(),
                 "person_boards": torch.stack([m.board for m in moves]) if moves else torch.zeros(0, dtype=torch.int8),
                 "person_legal": torch.stack([m.legal for m in moves]) if moves else torch.zeros(0, dtype=torch.bool),
                 "person_cells": torch.tensor([m.cell for m in moves], dtype=torch.long)}
        agent_parts.atomic_torch_save(saved, self.folder / GAMES_FOLDER / f"game-{self.games:04d}.pt")

    def _load_game(self, path: Path) -> None:
        saved = torch.load(path, map_location="cpu", weights_only=True)
        if saved["rows"] is not None:
            self.play_rows.extend(TensorDict.from_dict(saved["rows"], auto_batch_size=True, batch_dims=1))
        self.person_moves.extend(PersonMove(board, legal, int(cell)) for board, legal, cell in
                                 zip(saved["person_boards"], saved["person_legal"], saved["person_cells"]))

    def _update(self, report: PlayUpdate) -> None:
        gated = self.settings.gate
        with torch.random.fork_rng():
            torch.manual_seed(self.settings.seed * 100_003 + self.games)
            if gated and self._start_success is None:
                self._start_success = self.gate()
            report.kept_person_task_success = self.gate(self.person) if gated else None
            before = copy.deepcopy(self.learner.state_dict()), copy.deepcopy(self.qnet.state_dict())
            self._simulate()
            generator = torch.Generator().manual_seed(self.settings.seed * 100_003 + self.games)
            for _ in range(self.settings.updates):
                self.learner.update(self._batch(generator))
            self.updates += 1
            if gated:
                report.gate_task_success, report.person_task_success = self.gate(), self.gate(self.person)
        report.updated, report.start_task_success = True, self._start_success
        report.kept = not gated or (report.gate_task_success >= self._start_success - self.settings.gate_tolerance and
                                    report.person_task_success >= report.kept_person_task_success)
        if not report.kept:
            self.learner.load_state_dict(before[0])  # back to the last kept weights (network, target, optimiser)
            self.qnet.load_state_dict(before[1])
            return
        self.kept += 1
        if self.folder is not None:
            self.current = f"game-{report.game:04d}.pt"
            for name in (self.current, CURRENT_NAME):
                agent_parts.save_agent(self.folder / name, self.config, self.data, self.qnet, learned_games=self.games + 1)
            report.weights = str(self.folder / self.current)
