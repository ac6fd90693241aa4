"""Greedy test games against the simulated user, with the paper's metrics and a 95% interval for task success.

Each slot of the batched env counts exactly its FIRST game, so the statistics are not biased towards short
games (a slot that finishes early goes on playing, but those extra games are not counted; they may still appear
in the MCAP log as eval episodes).
"""
from __future__ import annotations

import math
from dataclasses import asdict, astuple, dataclass
from typing import Any

import torch

from ncbot.envs.core import OUTCOME_DRAW, OUTCOME_HUMAN_WON, OUTCOME_ROBOT_WON  # noqa: F401  (re-exported)
from ncbot.modules.policies.mask_rules import all_moves_negative

MAX_EVAL_BATCH = 4096


@dataclass
class EvalResult:
    """What `ncbot eval --json` prints. win/draw/loss/truncated are rates that add up to 1: truncated games ended
    at the act cap (`env.max_actions`) with the game unfinished, loss counts every other game not won or drawn.
    all_negative: the share of games that reached a state where every game move the robot was offered had a
    negative look-ahead reward (where the masks' fallback decides; docs/reproduction.md). `seats`, for games
    from both seats, holds the same metrics per seat ("robot_first", "robot_second")."""

    games: int
    win: float
    draw: float
    loss: float
    truncated: float
    all_negative: float
    task_success: float
    task_success_ci95: list[float]
    avg_reward: float  # per action, as the paper
    avg_return: float  # per game
    avg_length: float  # actions per game
    search_decisions: int | None = None  # with --search: robot game moves chosen by the search
    search_cpu_s_per_decision: float | None = None  # their process CPU seconds per move
    seats: dict[str, dict[str, Any]] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The metrics; the search's cost only when a search played."""
        return {key: value for key, value in asdict(self).items() if value is not None}


def wilson_interval(successes: int, trials: int, z: float = 1.96) -> list[float]:
    """Wilson score interval: well-behaved at rates of 0 or 1, unlike the normal approximation."""
    if trials == 0:
        return [0.0, 1.0]
    p = successes / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / (1 + z * z / trials)
    return [max(0.0, centre - half), min(1.0, centre + half)]


@dataclass
class GameRecords:
    """Per-game results of test games (one entry per counted game)."""

    outcomes: torch.Tensor  # outcome code (envs.core OUTCOME_*), 0 = no result
    returns: torch.Tensor
    lengths: torch.Tensor  # actions
    truncated: torch.Tensor  # bool: ended at the act cap
    all_negative: torch.Tensor  # bool: reached a state where every offered game move had a negative look-ahead

    @classmethod
    def cat(cls, parts: list["GameRecords"]) -> "GameRecords":
        return cls(*(torch.cat(column) for column in zip(*(astuple(part) for part in parts))))


def summarise(records: GameRecords) -> EvalResult:
    """Paper metrics, with the outcome broken down, from per-game records."""
    outcomes, returns, lengths = records.outcomes, records.returns, records.lengths
    games = int(outcomes.numel())
    wins = int((outcomes == OUTCOME_ROBOT_WON).sum())
    draws = int((outcomes == OUTCOME_DRAW).sum())
    truncated = int((records.truncated & (outcomes == 0)).sum())
    total_actions = float(lengths.sum())
    return EvalResult(
        games=games,
        win=wins / games,
        draw=draws / games,
        loss=(games - wins - draws - truncated) / games,
        truncated=truncated / games,
        all_negative=int(records.all_negative.sum()) / games,
        task_success=(wins + draws) / games,
        task_success_ci95=wilson_interval(wins + draws, games),
        avg_reward=float(returns.sum()) / max(total_actions, 1.0),
        avg_return=float(returns.mean()),
        avg_length=total_actions / games,
    )


@torch.no_grad()
def play_games(make_env, policy, games: int, *, logger=None, log_kwargs: dict[str, Any] | None = None,
               progress=None) -> GameRecords:
    """Play `games` greedy games on envs from `make_env(batch_size)`, counting each slot's first game. A policy
    whose network lives on a GPU reads each step there and hands its action back on the CPU (the env's device).
    `progress` (a `pipelines.progress.progress_bar`) is advanced by each counted game as it ends."""
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    from ncbot.modules.device import on_device
    from ncbot.pipelines.errors import raise_if_terminated

    if games <= 0:
        raise ValueError(f"games must be a positive number of test games, got {games}")
    parts: list[GameRecords] = []
    remaining = games
    act = on_device(policy)
    while remaining > 0:
        batch = min(remaining, MAX_EVAL_BATCH)
        env = make_env(batch)
        slot_outcome = torch.zeros(batch, dtype=torch.int64)
        slot_return = torch.zeros(batch)
        slot_length = torch.zeros(batch, dtype=torch.int64)
        slot_truncated = torch.zeros(batch, dtype=torch.bool)
        slot_negative = torch.zeros(batch, dtype=torch.bool)
        counting = torch.ones(batch, dtype=torch.bool)
        td = env.reset()
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            while counting.any():
                raise_if_terminated()
                if hasattr(policy, "searching"):  # a searching policy spends no search on uncounted games
                    policy.searching = counting
                slot_negative |= counting & all_moves_negative(td.get("action_mask"), td.get("lookahead_reward"), env.cells)
                td = act(td)
                td, next_root = env.step_and_maybe_reset(td)
                if logger is not None:  # only the counted games: a slot's later games would bias the log's results
                    logger.record_steps(td, env=env, active=counting.clone(), **(log_kwargs or {}))
                reward = td.get(("next", "reward")).reshape(batch)
                done = td.get(("next", "done")).reshape(batch)
                slot_return += torch.where(counting, reward, torch.zeros_like(reward))
                slot_length += counting.long()
                ended = counting & done
                slot_outcome[ended] = td.get(("next", "outcome")).reshape(batch)[ended].long()
                slot_truncated |= ended & td.get(("next", "truncated")).reshape(batch)
                counting &= ~done
                if progress is not None and (finished := int(ended.sum())):
                    progress.update(finished)
                td = next_root
        env.close()
        if hasattr(policy, "searching"):
            policy.searching = None
        parts.append(GameRecords(slot_outcome, slot_return, slot_length, slot_truncated, slot_negative))
        remaining -= batch
    return GameRecords.cat(parts)


def evaluate_agent(config, policy, *, games: int, first: str, seed: int, opponent: str | None = None,
                   logger=None, agent_name: str | None = None, progress=None) -> EvalResult:
    """Greedy games of a built policy against `opponent`; `first` (robot | human | alternate) says who opens.

    `alternate` plays half of the games robot-first, then half human-first; `seats` then holds each half under
    "robot_" + its `run_env.robot_seat` name.
    """
    from ncbot.modules.networks.recurrent import memory_env
    from ncbot.pipelines.run_env import check_first, make_run_env, robot_seat

    check_first(first)
    if games <= 0:
        raise ValueError(f"games must be a positive number of test games, got {games}")
    split = {"robot": [("robot", games)], "human": [("human", games)],
             "alternate": [("robot", (games + 1) // 2), ("human", games // 2)]}[first]
    per_seat: dict[str, GameRecords] = {}
    for offset, (opener, count) in enumerate(split):
        if count == 0:
            continue

        def make_env(batch_size: int, opener: str = opener, offset: int = offset):
            env = make_run_env(config.env, batch_size=batch_size, seed=seed + offset, first=opener,
                               opponent=opponent or config.eval.opponent)
            return memory_env(env, policy)  # a recurrent policy's hidden state runs through each game

        log_kwargs = {"phase": "eval", "agent": agent_name or config.agent.name, "seed": seed + offset}
        per_seat["robot_" + robot_seat(opener)] = play_games(make_env, policy, count, logger=logger,
                                                             log_kwargs=log_kwargs, progress=progress)
    result = summarise(GameRecords.cat(list(per_seat.values())))
    if len(per_seat) > 1:
        result.seats = {name: summarise(records).to_dict() for name, records in per_seat.items()}
    return result


def evaluate_checkpoint(checkpoint_path, *, games: int = 3000, opponent: str = "random", first: str = "alternate",
                        seed: int = 0, mcap_dir=None, search: int | None = None, value: str | None = None,
                        progress: bool = False) -> EvalResult:
    """`ncbot eval`: load a checkpoint and play greedy test games (optionally logged to MCAP in `mcap_dir`).

    `search` > 0 chooses the robot's game moves by MCTS guided by the Q-network with that many simulations;
    `value`: a value network file that scores the search's leaves (Ultimate); `progress`: show games done, rate and
    ETA on stderr (a bar on a terminal, a line every 10 % elsewhere).
    """
    if search is not None and search < 1:
        raise ValueError(f"--search must be a positive number of simulations, got {search}")
    from ncbot.pipelines.agents import load_agent, load_guided_agent

    if search:
        config, policy = load_guided_agent(checkpoint_path, search, seed, value=value)
    else:
        config, policy = load_agent(checkpoint_path)  # evaluate_agent carries a recurrent agent's hidden state
    from contextlib import nullcontext

    from ncbot.pipelines.progress import progress_bar

    if mcap_dir is None:
        episode_log = nullcontext()
    else:
        from ncbot.logs import EpisodeLogger

        episode_log = EpisodeLogger(mcap_dir, run_info={"command": "eval", "checkpoint": str(checkpoint_path)})
    with progress_bar(total=games, desc="eval", unit="game", disable=not progress) as bar, episode_log as logger:
        result = evaluate_agent(config, policy, games=games, first=first, seed=seed, opponent=opponent, logger=logger,
                                progress=bar)
    if search:
        result.search_decisions = policy.decisions
        result.search_cpu_s_per_decision = policy.cpu_seconds / max(policy.decisions, 1)
    return result
