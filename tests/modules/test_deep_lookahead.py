"""k-step look-ahead: exact against a brute-force search over envs.rules, on hand-made and real env positions."""
from __future__ import annotations

import pytest
import torch

from ncbot.envs import make_env
from ncbot.envs.opponents.bitboards import StandardBits, UltimateBits
from ncbot.envs.games import make_game
from ncbot.envs.rules import DRAWN, EMPTY, O, X, State
from ncbot.modules.policies.deep_lookahead import KStepLookahead, losing_moves, owners_from_order
from ncbot.modules.policies.masks import LOOKAHEAD_RULES


def attacker_wins(rules, state: State, plies: int, attacker: int) -> bool:
    """Plain minimax over envs.rules: can `attacker` force a win within `plies` plies from `state`?"""
    if rules.is_over(state):
        return state.result == attacker
    if plies == 0:
        return False
    children = [rules.play(state, cell) for cell in rules.legal(state)]
    if rules.mark_to_move(state) == attacker:
        return any(attacker_wins(rules, child, plies - 1, attacker) for child in children)
    return all(attacker_wins(rules, child, plies - 1, attacker) for child in children)


def brute_losing(rules, state: State, candidates: list[int], plies: int) -> set[int]:
    mover = rules.mark_to_move(state)
    other = X if mover == O else O
    return {c for c in candidates if attacker_wins(rules, rules.play(state, c), plies, other)}


def env_state(env, row: int) -> State:
    """The env's exact game state of one row (its engine keeps owners and the last move) as an envs.rules State."""
    boards = env.boards
    robot_mark = X if bool(env.d.robot_first[row]) else O
    to_xo = {0: EMPTY, 1: robot_mark, 2: X + O - robot_mark, 3: DRAWN}
    board = tuple(to_xo[v] for v in boards.board[row].tolist())
    subgrids = tuple(to_xo[v] for v in boards.owners[row].tolist()) if env.game == "ultimate" else ()
    return State(board=board, last_move=int(boards.last_move[row]), subgrids=subgrids)


def test_rules_are_registered_for_configs():
    for name in ("k1", "k3", "k5", "k3_open"):
        assert name in LOOKAHEAD_RULES
    with pytest.raises(ValueError, match="plies"):
        KStepLookahead(6)
    with pytest.raises(ValueError, match="reads the board"):
        LOOKAHEAD_RULES["k3"](torch.ones(1, 18, dtype=torch.bool), torch.zeros(1, 18), torch.zeros(1, 18, dtype=torch.bool))


def test_hand_made_fork_on_3x3():
    """Human on two opposite corners, robot in the centre: a corner reply lets the human fork (k3), an edge does not."""
    board = [2, 0, 0, 0, 1, 0, 0, 0, 2]
    engine = StandardBits()
    pos = engine.from_board(board, 1)
    free = [c for c in range(9) if board[c] == 0]
    assert losing_moves(engine, pos, free, 1) == []
    assert sorted(losing_moves(engine, pos, free, 3)) == [2, 6]
    rules = make_game("standard")
    state = State(board=tuple({0: EMPTY, 1: O, 2: X}[v] for v in board))
    assert brute_losing(rules, state, free, 3) == {2, 6}


def test_hand_made_ultimate_immediate_and_forced():
    """Ultimate: x (human) owns subgrids 0 and 1 and threatens subgrid 2; o (robot) is sent to the centre."""
    rules = make_game("ultimate", "anywhere")
    board = [EMPTY] * 81
    for cell in (0, 1, 2, 3, 4, 5, 6, 7, 10):
        board[cell] = X
    for cell in (9, 11, 12, 14, 54, 56, 57, 59):
        board[cell] = O
    state = State(board=tuple(board), last_move=10, subgrids=(X, X, 0, 0, 0, 0, 0, 0, 0))
    rules.validate(state)
    legal = rules.legal(state)
    assert legal == [30, 31, 32, 39, 40, 41, 48, 49, 50]
    engine = UltimateBits("anywhere")
    codes = [{EMPTY: 0, O: 1, X: 2}[v] for v in board]  # robot = o, to move
    pos = engine.from_board(codes, 1, state.last_move, [0 if v == 0 else 2 for v in state.subgrids])
    k1 = set(losing_moves(engine, pos, legal, 1))
    assert {30, 31, 32} <= k1  # sent to a decided subgrid (free move) or to subgrid 2: x takes c1 and wins
    for plies in (1, 3):
        assert set(losing_moves(engine, pos, legal, plies)) == brute_losing(rules, state, legal, plies)


def test_owners_from_move_order_take_the_first_line():
    board = [0] * 81
    order = [0] * 81
    # subgrid 0: robot (1) completes its top row at move 5, human (2) its middle row at move 6: robot owns it
    for n, (cell, code) in enumerate([(0, 1), (9, 2), (1, 1), (10, 2), (2, 1), (11, 2)], start=1):
        board[cell], order[cell] = code, n
    assert owners_from_order(board, order)[0] == 1
    order[2], order[11] = 6, 5  # same marks, other order: the human was first
    assert owners_from_order(board, order)[0] == 2


@pytest.mark.parametrize("game,free_move,plies", [
    ("standard", "anywhere", 3), ("ultimate", "anywhere", 3), ("ultimate", "open_subgrids", 3),
])
def test_masks_match_brute_force_on_real_env_positions(game, free_move, plies):
    """Random dialogues in the real env: at every robot move the k-step mask equals the brute-force search."""
    torch.manual_seed(0)
    env = make_env(game, batch_size=(8,), temporal=True, free_move=free_move, seed=3, first="alternate")
    rule = LOOKAHEAD_RULES[f"k{plies}" + ("_open" if free_move == "open_subgrids" else "")]
    rules = make_game(game, free_move)
    td = env.reset()
    checked = deep_found = 0
    for _ in range(80 if game == "ultimate" else 120):
        moves = td["action_mask"][:, :env.cells]
        all_moves = moves.clone()
        found = rule.forced_losses(td, torch.cat([all_moves, torch.zeros_like(td["action_mask"][:, env.cells:])], 1))
        for row in moves.any(-1).nonzero().flatten().tolist():
            state = env_state(env, row)
            legal = all_moves[row].nonzero().flatten().tolist()
            if len(legal) > 9:  # brute force on a free Ultimate root costs minutes; deeper free moves still occur
                continue
            assert sorted(legal) == rules.legal(state)
            expected = brute_losing(rules, state, legal, plies) if len(legal) >= 2 else set()
            assert set(found[row, :env.cells].nonzero().flatten().tolist()) == expected, (row, state)
            checked += 1
            deep_found += bool(expected)
        td = env.step(env.rand_action(td))["next"]
        td = env.reset(td.set("_reset", td["done"])) if bool(td["done"].any()) else td
    assert checked > 40 and deep_found > 0, (checked, deep_found)


def test_a_threat_that_walks_into_a_fork_is_dropped():
    """Human on a1 and b3, robot in the centre: c1/a2/c2/a3 make threats (+5, the env's set A) but c1 lets the
    human block with a fork; k3 keeps the other threats, and leaves A only if every threat loses by force."""
    env = make_env("standard", batch_size=(1,), temporal=True, seed=0)
    td = env.reset()
    board = torch.tensor([[2, 0, 0, 0, 1, 0, 0, 2, 0]], dtype=torch.int8)
    mask = torch.zeros(1, env.n_actions, dtype=torch.bool)
    mask[0, :9] = board[0] == 0
    threats = torch.zeros_like(mask)
    threats[0, [2, 3, 5, 6]] = True
    td.update({"board": board, "action_mask": mask, "winning_actions": threats,
               "lookahead_reward": torch.where(threats, 5.0, torch.where(mask, 0.0, -5.0))})
    explore, greedy = LOOKAHEAD_RULES["k3"].masks_from_tensordict(td)
    assert explore[0].nonzero().flatten().tolist() == [2, 3, 5, 6]
    assert greedy[0].nonzero().flatten().tolist() == [3, 5, 6]
    only_bad = threats.clone()
    only_bad[0, [3, 5, 6]] = False  # pretend c1 were the only threat: the greedy choice leaves A
    td.update({"winning_actions": only_bad, "lookahead_reward": torch.where(only_bad, 5.0, torch.where(mask, 0.0, -5.0))})
    _, greedy = LOOKAHEAD_RULES["k3"].masks_from_tensordict(td)
    assert greedy[0].nonzero().flatten().tolist() == [3, 5, 6, 8]


def test_greedy_mask_drops_forced_losses_and_keeps_one_step():
    env = make_env("standard", batch_size=(1,), temporal=True, seed=0)
    td = env.reset()
    # hand-set the fork position of test_hand_made_fork_on_3x3 into a robot-to-move TensorDict
    board = torch.tensor([[2, 0, 0, 0, 1, 0, 0, 0, 2]], dtype=torch.int8)
    mask = torch.zeros(1, env.n_actions, dtype=torch.bool)
    mask[0, :9] = board[0] == 0
    td.update({"board": board, "action_mask": mask, "winning_actions": torch.zeros_like(mask),
               "lookahead_reward": torch.where(mask, 0.0, -5.0)})
    explore, greedy = LOOKAHEAD_RULES["k3"].masks_from_tensordict(td)
    assert explore[0].nonzero().flatten().tolist() == [1, 2, 3, 5, 6, 7]
    assert greedy[0].nonzero().flatten().tolist() == [1, 3, 5, 7]
    _, greedy1 = LOOKAHEAD_RULES["k1"].masks_from_tensordict(td)
    assert greedy1[0].nonzero().flatten().tolist() == [1, 2, 3, 5, 6, 7]


def test_config_selects_k3_and_a_tiny_run_uses_it(tmp_path):
    """`agent.lookahead: k3` passes config validation, trains through the Collector and reloads for eval."""
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.evaluate.games import evaluate_agent
    from ncbot.pipelines.train.run import train
    from tests.learning_helpers import write_tiny_config

    config = load_config(write_tiny_config(tmp_path), ["agent.lookahead=k3", "collector.total_frames=128"])
    assert config.lookahead == "k3"
    train(config, tmp_path / "run")
    loaded, policy = load_agent(tmp_path / "run" / "checkpoint.pt")
    assert policy[1].lookahead == "k3"
    result = evaluate_agent(loaded, policy, games=20, first="human", seed=0, opponent="minimax")
    assert result.games == 20
    with pytest.raises(ValueError, match="agent.lookahead"):
        load_config(write_tiny_config(tmp_path), ["agent.lookahead=k9"])


def test_lookahead_only_baseline_accepts_k_rules():
    """`ncbot ladder --baseline` / `ncbot play` without a checkpoint: the masks alone, k5 included."""
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy

    env = make_env("standard", batch_size=(16,), seed=0, first="human", opponent="minimax")
    policy = LookaheadOnlyPolicy(0, "k5")
    td = env.reset()
    for _ in range(30):
        td = env.step(policy(td))["next"]
        td = env.reset(td.set("_reset", td["done"])) if bool(td["done"].any()) else td
        assert not bool((td["outcome"] == 2).any())  # 5 plies see every trap of 3x3: never loses to minimax
