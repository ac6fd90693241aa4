"""Greedy test games against the simulated user, with the paper's metrics and a 95% interval for task success.

Each slot of the batched env counts exactly its FIRST game, so the statistics are not biased towards short
games (a slot that finishes early goes on playing, but those extra games are not counted; they may still appear
in the MCAP log as eval episodes).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import torch

from envs.core import OUTCOME_DRAW, OUTCOME_HUMAN_WON, OUTCOME_ROBOT_WON  # noqa: F401  (re-exported)

MAX_EVAL_BATCH = 4096


@dataclass
class EvalResult:
    """What `ncbot eval --json` prints. win/draw/loss are rates; loss also counts unfinished (truncated) games."""

    games: int
    win: float
    draw: float
    loss: float
    task_success: float
    task_success_ci95: list[float]
    avg_reward: float  # per action, as the paper
    avg_return: float  # per game
    avg_length: float  # actions per game
    search_decisions: int | None = None  # with --search: robot game moves chosen by the search
    search_cpu_s_per_decision: float | None = None  # their process CPU seconds per move

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


def summarise(outcomes: torch.Tensor, returns: torch.Tensor, lengths: torch.Tensor) -> EvalResult:
    """Paper metrics from per-game outcome codes, returns and lengths."""
    games = int(outcomes.numel())
    wins = int((outcomes == OUTCOME_ROBOT_WON).sum())
    draws = int((outcomes == OUTCOME_DRAW).sum())
    total_actions = float(lengths.sum())
    return EvalResult(
        games=games,
        win=wins / games,
        draw=draws / games,
        loss=(games - wins - draws) / games,
        task_success=(wins + draws) / games,
        task_success_ci95=wilson_interval(wins + draws, games),
        avg_reward=float(returns.sum()) / max(total_actions, 1.0),
        avg_return=float(returns.mean()),
        avg_length=total_actions / games,
    )


@torch.no_grad()
def play_games(make_env, policy, games: int, *, logger=None,
               log_kwargs: dict[str, Any] | None = None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Play `games` greedy games on envs from `make_env(batch_size)`, counting each slot's first game.

    Returns per-game (outcome codes, returns, lengths).
    """
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    if games <= 0:
        raise ValueError(f"games must be a positive number of test games, got {games}")
    outcomes, returns, lengths = [], [], []
    remaining = games
    while remaining > 0:
        batch = min(remaining, MAX_EVAL_BATCH)
        env = make_env(batch)
        slot_outcome = torch.zeros(batch, dtype=torch.int64)
        slot_return = torch.zeros(batch)
        slot_length = torch.zeros(batch, dtype=torch.int64)
        counting = torch.ones(batch, dtype=torch.bool)
        td = env.reset()
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            while counting.any():
                if hasattr(policy, "searching"):  # a searching policy spends no search on uncounted games
                    policy.searching = counting
                td = policy(td)
                td, next_root = env.step_and_maybe_reset(td)
                if logger is not None:
                    logger.record_steps(td, env=env, **(log_kwargs or {}))
                reward = td.get(("next", "reward")).reshape(batch)
                done = td.get(("next", "done")).reshape(batch)
                slot_return += torch.where(counting, reward, torch.zeros_like(reward))
                slot_length += counting.long()
                ended = counting & done
                slot_outcome[ended] = td.get(("next", "outcome")).reshape(batch)[ended].long()
                counting &= ~done
                td = next_root
        env.close()
        if hasattr(policy, "searching"):
            policy.searching = None
        outcomes.append(slot_outcome)
        returns.append(slot_return)
        lengths.append(slot_length)
        remaining -= batch
    return torch.cat(outcomes), torch.cat(returns), torch.cat(lengths)


def evaluate_agent(config, policy, *, games: int, seat: str, seed: int, opponent: str | None = None,
                   logger=None, agent_name: str | None = None) -> EvalResult:
    """Greedy games of a built policy from one seat (first | second | alternate) against `opponent`.

    `alternate` plays half of the games from each seat (the first half robot-first).
    """
    from modules.recurrent import memory_env
    from pipelines.run_env import make_run_env, seat_to_first

    seat_to_first(seat)
    if games <= 0:
        raise ValueError(f"games must be a positive number of test games, got {games}")
    split = {"first": [("robot", games)], "second": [("human", games)],
             "alternate": [("robot", (games + 1) // 2), ("human", games // 2)]}[seat]
    per_game = []
    for offset, (first, count) in enumerate(split):
        if count == 0:
            continue

        def make_env(batch_size: int, first: str = first, offset: int = offset):
            env = make_run_env(config.env, batch_size=batch_size, seed=seed + offset, first=first,
                               opponent=opponent or config.eval.opponent)
            return memory_env(env, policy)  # a recurrent policy's hidden state runs through each game

        log_kwargs = {"phase": "eval", "agent": agent_name or config.agent.name, "seed": seed + offset}
        per_game.append(play_games(make_env, policy, count, logger=logger, log_kwargs=log_kwargs))
    return summarise(*(torch.cat(parts) for parts in zip(*per_game)))


def evaluate_checkpoint(checkpoint_path, *, games: int = 3000, opponent: str = "random", seat: str = "alternate",
                        seed: int = 0, mcap_dir=None, search: int | None = None, value: str | None = None) -> EvalResult:
    """`ncbot eval`: load a checkpoint and play greedy test games (optionally logged to MCAP in `mcap_dir`).

    `search` > 0 chooses the robot's game moves by MCTS guided by the Q-network with that many simulations;
    `value`: a value network file that scores the search's leaves (Ultimate).
    """
    if search is not None and search < 1:
        raise ValueError(f"--search must be a positive number of simulations, got {search}")
    from pipelines.agents import load_agent, load_guided_agent

    if search:
        config, policy = load_guided_agent(checkpoint_path, search, seed, value=value)
    else:
        config, policy = load_agent(checkpoint_path, recurrent=True)  # evaluate_agent carries its hidden state
    if mcap_dir is None:
        result = evaluate_agent(config, policy, games=games, seat=seat, seed=seed, opponent=opponent)
    else:
        from logs import EpisodeLogger

        with EpisodeLogger(mcap_dir, run_info={"command": "eval", "checkpoint": str(checkpoint_path)}) as logger:
            result = evaluate_agent(config, policy, games=games, seat=seat, seed=seed, opponent=opponent,
                                    logger=logger)
    if search:
        result.search_decisions = policy.decisions
        result.search_cpu_s_per_decision = policy.cpu_seconds / max(policy.decisions, 1)
    return result
