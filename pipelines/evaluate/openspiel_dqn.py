"""OpenSpiel's PyTorch DQN as a peer learner: its training (one DQN per seat, snapshots on its own clock) and its
snapshots scored by our referee, sampled (`evaluate_dqn`) or exactly on 3x3 (`exact_dqn`).

`bench/time_to_quality.py` trains it beside our agent and compares the times to task success (`first_time`).
Settings: those of OpenSpiel's ``examples/tic_tac_toe_dqn_vs_tabular.py`` (`DQN_EXAMPLE_SETTINGS`).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

DQN_EXAMPLE_SETTINGS = {"hidden_layers_sizes": [32, 32], "replay_buffer_capacity": int(1e4)}  # tic_tac_toe example


def dqn_worker(game: str, cap: float, clock_name: str, every: float, opponent: str, hidden: list[int], out: Path,
               seed: int) -> None:
    """Train OpenSpiel's PyTorch DQN (one per seat) for ``cap`` seconds of ``clock_name``; snapshots of both nets."""
    import numpy as np
    import torch
    from open_spiel.python import rl_environment
    from open_spiel.python.algorithms import random_agent
    from open_spiel.python.pytorch import dqn

    from ncbot.envs.opponents.openspiel import openspiel_name

    torch.set_num_threads(1)
    np.random.seed(seed)
    env = rl_environment.Environment(openspiel_name(game))
    size, actions = env.observation_spec()["info_state"][0], env.action_spec()["num_actions"]
    settings = {**DQN_EXAMPLE_SETTINGS, "hidden_layers_sizes": hidden}
    learners = [dqn.DQN(player_id=p, state_representation_size=size, num_actions=actions, seed=seed + p, **settings)
                for p in range(2)]
    randoms = [random_agent.RandomAgent(player_id=p, num_actions=actions) for p in range(2)]
    snapshots: list[dict[str, Any]] = []

    def save(snapshots: list[dict[str, Any]]) -> None:
        _save_dqn_snapshots(out, snapshots, size, actions, settings, opponent)

    clock, cpu_clock, episodes, steps = 0.0, 0.0, 0, 0
    next_snapshot = every
    def reading() -> float:
        return clock if clock_name == "wall_time" else cpu_clock

    while reading() < cap:
        began, cpu_began = time.monotonic(), time.process_time()
        if opponent == "dqn":
            agents = learners
        else:  # each seat's DQN against the uniform random player, seats alternating by episode
            agents = [learners[0], randoms[1]] if episodes % 2 == 0 else [randoms[0], learners[1]]
        time_step = env.reset()
        while not time_step.last():
            output = agents[time_step.observations["current_player"]].step(time_step)
            time_step = env.step([output.action])
            steps += 1
        for agent in agents:
            agent.step(time_step)
        episodes += 1
        clock += time.monotonic() - began
        cpu_clock += time.process_time() - cpu_began
        if reading() >= next_snapshot or reading() >= cap:
            snapshots.append({"wall_time": round(clock, 3), "cpu_time": round(cpu_clock, 3), "episodes": episodes,
                              "steps": steps,
                              "q": [{k: v.clone() for k, v in agent._q_network.state_dict().items()} for agent in learners]})
            next_snapshot = reading() + every
            save(snapshots)  # after every snapshot (off the clock): a run stopped early keeps what it learnt
    save(snapshots)


def _save_dqn_snapshots(out: Path, snapshots: list[dict[str, Any]], size: int, actions: int, settings: dict,
                        opponent: str) -> None:
    """Write the DQN's snapshots so far, atomically (a reader never sees half a file)."""
    import torch

    from ncbot.fileio import atomic_path

    with atomic_path(out) as temp:
        torch.save({"snapshots": snapshots, "state_size": size, "num_actions": actions, "settings": settings,
                    "opponent": opponent}, temp)


def dqn_network(q_state: dict, meta: dict[str, Any]):
    """One seat's Q-network of a DQN snapshot, as OpenSpiel's DQN builds it (``meta``: the snapshots file's sizes)."""
    from open_spiel.python.pytorch.dqn import MLP

    network = MLP(meta["state_size"], meta["settings"]["hidden_layers_sizes"], meta["num_actions"])
    network.load_state_dict(q_state)
    return network.eval()


def dqn_greedy_move(network, state) -> int:
    """The DQN's move in an OpenSpiel state: greedy Q over the legal actions, as DQN.step(is_evaluation=True)."""
    import torch

    legal = state.legal_actions()
    with torch.no_grad():
        q = network(torch.tensor(state.observation_tensor(state.current_player())).unsqueeze(0))[0]
    return legal[int(torch.argmax(q[legal]))]


class DQNPlayer:
    """A DQN snapshot's seat as a batched opponent (``dqn_greedy_move`` in every game)."""

    @staticmethod
    def build(q_state: dict, meta: dict[str, Any], game: str, free_move: str, seed: int):
        from ncbot.envs.opponents.openspiel import OpenSpielOpponent

        network = dqn_network(q_state, meta)

        class _Player(OpenSpielOpponent):
            name = "openspiel-dqn"

            def decide(self, state, seed):
                return dqn_greedy_move(network, state)

        return _Player(game, free_move, seed)


def evaluate_dqn(snapshot: dict[str, Any], meta: dict[str, Any], game: str, games: int, seed: int) -> dict[str, float]:
    from ncbot.envs.opponents import make_opponent
    from ncbot.envs.opponents.arena import play_match

    from ncbot.envs.opponents.openspiel import OPENSPIEL_FREE_MOVE

    free_move = OPENSPIEL_FREE_MOVE  # OpenSpiel's rule (Ultimate's variant; the other games have one rule)
    players = [DQNPlayer.build(snapshot["q"][p], meta, game, free_move, seed) for p in range(2)]
    rand = make_opponent("random", game=game, free_move=free_move, seed=seed)
    first = play_match(players[0], rand, games, seed=seed, free_move=free_move)
    second = play_match(rand, players[1], games, seed=seed + 1, free_move=free_move)
    return {"first": 1 - first.second_wins / games, "second": 1 - second.first_wins / games}


def exact_dqn(snapshot: dict[str, Any], meta: dict[str, Any]) -> dict[str, float]:
    """Exact task success of a 3x3 DQN snapshot from each seat: the game tree of OpenSpiel's tic_tac_toe with the
    DQN's greedy move at its turns and every move of the uniform random player at the other's (probabilities
    averaged), positions memoised (the greedy move depends on the board only)."""
    from ncbot.envs.opponents.openspiel import import_pyspiel

    pyspiel = import_pyspiel()
    success = {}
    for player, seat in enumerate(("first", "second")):
        network = dqn_network(snapshot["q"][player], meta)
        memo: dict[str, float] = {}

        def loss(state) -> float:
            if state.is_terminal():
                return 1.0 if state.returns()[player] < 0 else 0.0
            key = str(state)
            if key not in memo:
                mine = state.current_player() == player
                moves = [dqn_greedy_move(network, state)] if mine else state.legal_actions()
                memo[key] = sum(loss(state.child(move)) for move in moves) / len(moves)
            return memo[key]

        success[seat] = 1.0 - loss(pyspiel.load_game("tic_tac_toe").new_initial_state())
    return success


def first_time(points: list[dict[str, Any]], threshold: float, clock: str = "wall_time") -> float | None:
    """The ``clock`` reading of the first point with task success >= ``threshold`` in both seats (None: never)."""
    for point in points:
        if min(point["first"], point["second"]) >= threshold:
            return point[clock]
    return None
