"""MCTS guided by a trained Q-network: legal, reproducible by seed, at least as strong as plain mcts:N, usable as
the robot's eval-time policy in the real dialogue env."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from ncbot.envs.opponents import make_opponent
from ncbot.envs.opponents.arena import play_match
from ncbot.modules.search.guided_mcts import parse_qmcts
from ncbot.pipelines.config import load_config
from ncbot.pipelines.evaluate.games import evaluate_agent
from ncbot.modules.search.guided_mcts import GuidedMCTSPolicy
from ncbot.pipelines.agents import guided_search, load_agent, load_guided_agent, register_agent_opponent
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def ultimate_checkpoint(tmp_path_factory) -> str:
    """A real (tiny) Ultimate training run: the Q-network the search reads."""
    folder = tmp_path_factory.mktemp("qmcts")
    config = load_config(write_tiny_config(folder, env={"game": "ultimate"}, eval={"games": 8, "periodic_games": 8}))
    train(config, folder / "run")
    register_agent_opponent()  # also registers qmcts:N:CHECKPOINT
    return str(folder / "run" / "checkpoint.pt")


def test_bad_names_are_one_line_errors(ultimate_checkpoint):
    for arg in (None, "0:x.pt", "ten:x.pt", "10", "10:"):
        with pytest.raises(ValueError, match="qmcts"):
            parse_qmcts(arg)
    with pytest.raises(ValueError, match="plays ultimate, not standard"):
        make_opponent(f"qmcts:10:{ultimate_checkpoint}", game="standard")
    with pytest.raises(FileNotFoundError):
        make_opponent("qmcts:10:/nonexistent/checkpoint.pt", game="ultimate")


@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_legal_and_reproducible_by_seed(ultimate_checkpoint, free_move):
    """The arena referees every move with envs.rules (an illegal one raises); same seeds, same games."""
    def match(seed: int):
        guided = make_opponent(f"qmcts:8:{ultimate_checkpoint}", game="ultimate", free_move=free_move, seed=seed)
        return play_match(guided, make_opponent("random", game="ultimate", free_move=free_move), 6, seed=seed)

    first, again = match(1), match(1)
    assert (first.first_wins, first.draws, first.marks) == (again.first_wins, again.draws, again.marks)
    assert first.first_wins >= 5  # a search with look-ahead beats random

    # the seed drives the search: on 32 opening positions two generator seeds choose differently somewhere
    guided = make_opponent(f"qmcts:4:{ultimate_checkpoint}", game="ultimate", free_move=free_move)
    boards = torch.zeros(32, 81, dtype=torch.int8)
    boards[torch.arange(32), torch.arange(32)] = 2
    legal = boards == 0
    last = torch.arange(32)
    legal &= torch.stack([torch.isin(torch.arange(81), torch.tensor(_cells_of_target(int(c)))) for c in last])
    picks = [guided.select(boards, last, legal, 1, torch.Generator().manual_seed(s)) for s in (1, 1, 2)]
    assert torch.equal(picks[0], picks[1]) and not torch.equal(picks[0], picks[2])
    assert bool(legal.gather(1, picks[2].unsqueeze(1)).all())


def _cells_of_target(last_move: int) -> list[int]:
    from ncbot.envs.rules import SUBGRID_CELLS, TARGET_OF_CELL

    return list(SUBGRID_CELLS[TARGET_OF_CELL[last_move]])


def test_at_least_as_strong_as_plain_mcts_at_the_same_budget(ultimate_checkpoint):
    """Quick check, both seats: qmcts:20 (Q priors + values + root masks) against mcts:20 (UCT, random playouts)."""
    games = 12
    guided = make_opponent(f"qmcts:20:{ultimate_checkpoint}", game="ultimate", seed=1)
    plain = make_opponent("mcts:20", game="ultimate", seed=2)
    as_first = play_match(guided, plain, games, seed=5)
    as_second = play_match(plain, guided, games, seed=6)
    score = (as_first.first_score + as_second.second_score) / 2
    assert score >= 0.5, (as_first, as_second)


def test_guided_policy_plays_real_dialogues(ultimate_checkpoint):
    """The robot's policy at eval time: full dialogues in the real env, from both seats, reproducible."""
    def run(seed: int):
        config, policy = load_guided_agent(ultimate_checkpoint, simulations=8, seed=seed)
        return evaluate_agent(config, policy, games=4, first="alternate", seed=seed, opponent="random")

    result = run(0)
    assert result.games == 4 and result.loss < 1.0
    assert result.avg_length < 100  # every game finished inside the action budget
    assert run(0).to_dict() == result.to_dict()


class _CheckedPolicy(GuidedMCTSPolicy):
    """The guided policy, checking after each step that its game moves keep the agent's own masks."""

    def forward(self, tensordict):
        searching = self.searching
        tensordict = super().forward(tensordict)
        legal = tensordict.get("action_mask")[:, :81]
        rows = legal.any(-1) if searching is None else legal.any(-1) & searching
        greedy_mask = tensordict.get("greedy_mask")
        chosen = tensordict.get("action")
        assert bool(greedy_mask[rows].gather(1, chosen[rows].view(-1, 1)).all()), "a searched move left the masks"
        return tensordict


@pytest.mark.parametrize("first", ["robot", "human"])
def test_guided_policy_keeps_the_agents_masks_and_counts_only_scored_games(ultimate_checkpoint, first):
    """Every searched robot move lies in the agent's greedy mask (its look-ahead masks), from both seats, and the
    search runs only while a slot's first game is being scored (its cost per move is what eval reports)."""
    config, greedy = load_agent(ultimate_checkpoint)
    policy = _CheckedPolicy(greedy, guided_search(config, greedy, 6), seed=3)
    result = evaluate_agent(config, policy, games=6, first=first, seed=4, opponent="random")
    assert result.games == 6 and policy.searching is None
    # a robot game move per robot turn at most: the 6 scored games' robot actions bound the searched moves
    assert 0 < policy.decisions <= round(result.avg_length * result.games)
    assert policy.cpu_seconds > 0
    unscored = _CheckedPolicy(greedy, guided_search(config, greedy, 6), seed=3)
    unscored.searching = torch.zeros(4, dtype=torch.bool)
    from ncbot.pipelines.run_env import make_run_env

    env = make_run_env(config.env, batch_size=4, seed=0, first="robot")
    td = env.reset()
    for _ in range(20):  # the dialogue's opening acts, until the robot has a game move to make
        if bool(td["action_mask"][:, :81].any()):
            break
        td = env.step_and_maybe_reset(greedy(td))[1]
    assert bool(td["action_mask"][:, :81].any())
    td = unscored(td)
    assert unscored.decisions == 0 and torch.equal(td["action"], greedy(td.clone())["action"])
    unscored.searching = None
    unscored(td)
    assert unscored.decisions > 0


def test_ncbot_eval_search_option(ultimate_checkpoint):
    """`ncbot eval CKPT --search N` plays the robot's moves with the guided search; bad budgets exit 2."""
    import json

    from tests.learning_helpers import ncbot

    done = ncbot("eval", ultimate_checkpoint, "--search", "4", "--games", "2", "--first", "robot", "--json")
    assert done.returncode == 0, done.stderr
    metrics = json.loads(done.stdout.strip().splitlines()[-1])
    assert metrics["games"] == 2 and metrics["search_decisions"] > 0 and metrics["search_cpu_s_per_decision"] > 0
    plain = ncbot("eval", ultimate_checkpoint, "--games", "2", "--first", "robot", "--json")
    assert "search_decisions" not in json.loads(plain.stdout.strip().splitlines()[-1])
    bad = ncbot("eval", ultimate_checkpoint, "--search", "0", "--games", "2")
    assert bad.returncode == 2 and "--search must be a positive" in bad.stderr


def test_search_reads_the_same_q_values_as_the_network(ultimate_checkpoint):
    """The search's numpy reads (``MLPReader``) give the network's numbers to float32 rounding, on a played position."""
    import random

    config, greedy = load_agent(ultimate_checkpoint)
    search = guided_search(config, greedy, 4)
    assert search._reader is not None
    engine, rand = search.engine, random.Random(0)
    pos, last = engine.from_board([0] * 81, 1), -1
    for _ in range(12):
        last = rand.choice(engine.moves(pos))
        pos = engine.play(pos, last)
    moves = engine.moves(pos)
    fast = search._q(pos, last, moves)
    search._reader = None
    assert torch.allclose(torch.tensor(search._q(pos, last, moves)), torch.tensor(fast), atol=1e-5)


def test_the_search_plays_a_game_given_only_by_its_rules():
    """Q-guided search on any game's search positions: misère Noughts & Crosses (docs/examples/misere.py, positions
    from its table), a fresh network; every move it chooses is legal, the game ends."""
    import random

    from ncbot.envs.games import load_game
    from ncbot.envs.opponents.bitboards import ONGOING
    from ncbot.modules.search.guided_mcts import GuidedMCTS, TurnFeatures
    from ncbot.modules.networks.qnet import make_qnet

    game = load_game(f"{Path(__file__).resolve().parents[2] / 'docs' / 'examples' / 'misere.py'}:Misere")
    features = TurnFeatures(game.id, temporal=True)
    search = GuidedMCTS(make_qnet(features.n_features, game.n_cells + 9, [16]), features, game.id, simulations=32)
    engine, rng = game.search_engine(), random.Random(0)
    pos, moves_played = engine.from_board([0] * 9, 1), 0
    while engine.result(pos) == ONGOING:
        moves = engine.moves(pos)
        move, visits = search.search(pos, moves, rng)
        assert move in moves and (len(moves) == 1 or sum(visits.values()) > 0)
        pos, moves_played = engine.play(pos, move), moves_played + 1
    assert 5 <= moves_played <= 9
