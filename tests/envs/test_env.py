"""The dialogue env: specs, masks, the paper's rewards on hand-made positions, features, seats, truncation,
reproducibility and clear errors."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs

from ncbot.envs import make_env
from ncbot.envs.dialogue import ROBOT_COMMANDS
from tests.envs.helpers import QueuedMoves
from ncbot.envs.rules import LINES_3X3

torch.set_num_threads(1)


def act(env, name_or_cell, user_cell: int | None = None) -> TensorDict:
    """Step a batch-1 env with one action (name or cell); queue the user's reply move if given."""
    action = name_or_cell if isinstance(name_or_cell, int) else env.action_names.index(name_or_cell)
    if user_cell is not None:
        env.opponent.queue([user_cell])
    return env.step(TensorDict({"action": torch.tensor([action])}, batch_size=[1]))["next"]


def start_game(env) -> TensorDict:
    """Play the pre-game dialogue (greeting, name, play request until the user agrees)."""
    td = env.reset()
    for _ in range(30):
        allowed = td["action_mask"][0].nonzero().flatten().tolist()
        if any(a < env.cells for a in allowed) or env.action_names.index("Request(userGameMove)") in allowed:
            return td
        td = act(env, allowed[0])
    raise AssertionError("the user never agreed to play")


def scripted(starts: str = "robot", **kw):
    return make_env("standard", batch_size=(1,), first=starts, opponent=QueuedMoves(), **kw)


# ---------------------------------------------------------------- specs and sizes
@pytest.mark.parametrize("game", ["standard", "ultimate"])
@pytest.mark.parametrize("batch", [1, 64])
def test_check_env_specs(game: str, batch: int) -> None:
    check_env_specs(make_env(game, batch_size=(batch,)))


@pytest.mark.parametrize("game,temporal,features,actions", [
    ("standard", True, 73, 18), ("standard", False, 64, 18), ("ultimate", True, 289, 90), ("ultimate", False, 208, 90)])
def test_sizes_and_names(game: str, temporal: bool, features: int, actions: int) -> None:
    env = make_env(game, temporal=temporal)
    assert env.n_features == len(env.feature_names) == features
    assert env.n_actions == len(env.action_names) == len(env.templates) == len(env.robot_commands) == actions
    assert len(env.words) == 39 and len(set(env.feature_names)) == features
    assert env.reset()["observation"].shape == (1, features)
    assert set(env.robot_commands) == set(ROBOT_COMMANDS) | {"draw"}
    assert env.action_names[:2] == ["GameMove(gridloc=0)", "GameMove(gridloc=1)"]
    assert env.user_utterance(-1) == ""


# ---------------------------------------------------------------- masks over random rollouts
@pytest.mark.parametrize("game,free_move", [("standard", "anywhere"), ("ultimate", "anywhere"), ("ultimate", "open_subgrids")])
def test_random_rollouts_respect_masks_and_invariants(game: str, free_move: str) -> None:
    env = make_env(game, batch_size=(32,), free_move=free_move, first="random", seed=4)
    data = env.rollout(300 if game == "ultimate" else 60, break_when_any_done=False)
    mask, action = data["action_mask"], data["action"]
    assert mask.gather(-1, action.unsqueeze(-1)).all(), "a random rollout took a masked action"
    for td in (data, data["next"]):
        assert td["action_mask"].any(-1).all(), "an all-False mask row"
        assert (td["lookahead_reward"][~td["action_mask"]] == -5).all()
        assert (td["winning_actions"] <= td["action_mask"]).all()
        assert (td["action_mask"] <= td["dialogue_mask"]).all()
    # the step reward is the look-ahead reward of the action taken: the look-ahead is exact
    assert torch.equal(data["next", "reward"].squeeze(-1), data["lookahead_reward"].gather(-1, action.unsqueeze(-1)).squeeze(-1))
    board = data["next", "board"]
    robot, human = (board == 1).sum(-1), (board == 2).sum(-1)
    first = data["next", "robot_first"].squeeze(-1)
    assert ((robot - human) == torch.where(first, (robot + human) % 2, -((robot + human) % 2))).all()
    assert data["next", "terminated"].any(), "some dialogues close"
    closed = data["next", "terminated"].squeeze(-1)
    assert (data["next", "outcome"].squeeze(-1)[closed] > 0).all(), "random masked dialogues close only after the game"


# ---------------------------------------------------------------- rewards on hand-made 3x3 positions
def play_script(env, robot_cells: list[int], user_cells: list[int]) -> list[float]:
    """Robot moves ``robot_cells``; the user answers each with the next of ``user_cells`` (if any)."""
    rewards = []
    users = list(user_cells)
    if env.first == "human":
        act(env, "Request(userGameMove)", users.pop(0))
    for cell in robot_cells:
        td = act(env, cell, users.pop(0) if users else None)
        rewards.append(float(td["reward"]))
    return rewards


def started(starts: str):
    env = scripted(starts)
    start_game(env)
    return env


@pytest.fixture
def robot_first_env():
    return started("robot")


@pytest.fixture
def human_first_env():
    return started("human")


def test_win_reward(robot_first_env) -> None:
    # R0 H3 R1 H4 R2: the third robot mark completes the top row
    assert play_script(robot_first_env, [0, 1, 2], [3, 4]) == [0.0, 5.0, 5.0]


def test_about_to_win_needs_an_open_line_and_no_opponent_threat(robot_first_env) -> None:
    # R0 H4: R1 threatens 2 and the user has no immediate win -> +5 (about to win)
    assert play_script(robot_first_env, [0, 1], [4, 2]) == [0.0, 5.0]


def test_about_to_lose_beats_about_to_win(robot_first_env) -> None:
    # R0 H4 R8 H3: the user threatens 5; R1 creates a threat of its own but leaves 5 open -> -5
    assert play_script(robot_first_env, [0, 8, 1], [4, 3, 5]) == [0.0, 0.0, -5.0]
    assert int(act(robot_first_env, "Provide(feedback=loose)")["outcome"]) == 2


def test_blocking_move_is_not_punished(robot_first_env) -> None:
    # same position, R5 blocks the user and makes the robot's own 2-5-8 threat -> +5
    assert play_script(robot_first_env, [0, 8, 5], [4, 3, 6]) == [0.0, 0.0, 5.0]


def test_draw_reward(robot_first_env) -> None:
    # R0 H1 R2 H4 R3 H5 R7 H6 R8: the robot's fifth mark fills the board without a line -> +1
    rewards = play_script(robot_first_env, [0, 2, 3, 7, 8], [1, 4, 5, 6])
    assert rewards[-1] == 1.0
    assert int(robot_first_env._output()["outcome"]) == 3


def test_about_to_draw(human_first_env) -> None:
    # H5 R3 H0 R2 H7 R8 H4 R1: after R1 no line is open for anyone (it was before) -> +1; H6 then draws
    env = human_first_env
    rewards = play_script(env, [3, 2, 8, 1], [5, 0, 7, 4, 6])
    after_r1 = [2, 1, 1, 1, 2, 2, 0, 2, 1]
    assert all({after_r1[c] for c in line} >= {1, 2} for line in LINES_3X3)
    assert rewards == [0.0, 0.0, 0.0, 1.0]
    assert int(env._output()["outcome"]) == 3


def test_repeated_move_and_refused_act_cost_five_and_change_nothing(robot_first_env) -> None:
    env = robot_first_env
    act(env, 4, 0)
    before = env._output()
    td = act(env, 4)  # square taken: a repeated move
    assert float(td["reward"]) == -5.0 and torch.equal(td["board"], before["board"])
    assert torch.equal(td["observation"], before["observation"]) and int(td["turn"]) == int(before["turn"]) + 1
    td = act(env, "Salutation(greeting)")  # outside the act filter mid-game
    assert float(td["reward"]) == -5.0 and int(td["user_act"]) == -1


def test_lookahead_does_not_change_state(robot_first_env) -> None:
    env = robot_first_env
    td = env._output()
    again = env._output()
    assert torch.equal(td["lookahead_reward"], again["lookahead_reward"]) and torch.equal(td["board"], again["board"])
    assert td["winning_actions"].sum() == 0  # empty board: no move wins or threatens yet


# ---------------------------------------------------------------- features
def test_features_words_commands_and_temporal() -> None:
    env = make_env("standard", batch_size=(1,), asr_confidence=(0.25, 0.5), opponent=QueuedMoves())
    td = env.reset()
    assert td["observation"].abs().sum() == 0
    td = act(env, "Salutation(greeting)")
    names, obs = env.feature_names, td["observation"][0]
    value = dict(zip(names, obs.tolist()))
    assert value["command[hello]"] == 1.0 and sum(value[f"command[{c}]"] for c in ROBOT_COMMANDS) == 1.0
    for word in ("hello", "nice", "meet"):
        assert value[f"word[{word}]"] == 1.0  # said by the robot
    heard = env.user_utterance(int(td["user_utterance"]))
    for word in heard.split():
        if word not in ("hello", "nice", "to", "meet", "you"):
            assert 0.25 <= value[f"word[{word}]"] < 0.5  # the user's words carry an ASR confidence
    start = start_game(env)
    assert start is not None
    td = act(env, 4, 0)
    td = act(env, 8, 2)
    value = dict(zip(env.feature_names, td["observation"][0].tolist()))
    # four marks: 4 (1st), 0 (2nd), 8 (3rd), 2 (4th) -> order / number of marks
    assert [value[f"time[{c}]"] for c in (4, 0, 8, 2, 1)] == [0.25, 0.5, 0.75, 1.0, 0.0]
    assert value["robot_move[4]"] == value["robot_move[8]"] == value["human_move[0]"] == 1.0
    assert value["command[hello]"] == 0.0  # a move issues the draw command, not one of the 7


# ---------------------------------------------------------------- seats, truncation, reproducibility
def test_human_first_starts_with_your_turn() -> None:
    env = make_env("standard", batch_size=(1,), first="human")
    td = start_game(env)
    allowed = [env.action_names[a] for a in td["action_mask"][0].nonzero().flatten().tolist()]
    assert allowed == ["Request(userGameMove)"]
    td = act(env, "Request(userGameMove)")
    assert int(td["user_move"]) >= 0 and int((td["board"] == 2).sum()) == 1


@pytest.mark.parametrize("starts,expected", [("robot", {True}), ("human", {False}), ("alternate", {True, False}), ("random", {True, False})])
def test_seat_options(starts: str, expected: set[bool]) -> None:
    env = make_env("standard", batch_size=(16,), first=starts, seed=1)
    seats = set(env.reset()["robot_first"].flatten().tolist()) | set(env.reset()["robot_first"].flatten().tolist())
    assert seats == expected
    if starts == "alternate":
        first = env.reset()["robot_first"]
        assert torch.equal(env.reset()["robot_first"], ~first)


def test_starts_is_no_option() -> None:
    """Who opens has one name, ``first``: the old ``starts=`` is refused like any unknown option."""
    with pytest.raises(ValueError, match="unknown option 'starts'"):
        make_env("standard", batch_size=(8,), seed=3, starts="human")
    assert not hasattr(make_env("standard"), "starts")


def test_truncated_after_100_actions() -> None:
    env = make_env("standard", batch_size=(2,))
    env.reset()
    for step in range(100):
        td = env.step(TensorDict({"action": torch.tensor([0, 0])}, batch_size=[2]))["next"]  # always refused
        assert bool(td["truncated"].all()) == (step == 99)
    assert td["done"].all() and not td["terminated"].any() and (td["reward"] == -5).all()


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_same_seed_same_rollout(game: str) -> None:
    def rollout(seed: int):
        env = make_env(game, batch_size=(8,), seed=seed, first="random")
        return env.rollout(40, break_when_any_done=False)

    a, b, c = rollout(3), rollout(3), rollout(4)
    for key in ("observation", "action", ("next", "reward"), ("next", "board")):
        assert torch.equal(a[key], b[key])
    assert not torch.equal(a["next", "observation"], c["next", "observation"])


def test_partial_reset_only_touches_selected_games() -> None:
    env = make_env("standard", batch_size=(4,), seed=2)
    env.rollout(12, break_when_any_done=False)
    before = env._output()
    reset = torch.tensor([[True], [False], [True], [False]])
    td = env.reset(TensorDict({"_reset": reset}, batch_size=[4]))
    assert (td["turn"][reset.squeeze(1)] == 0).all()
    assert torch.equal(td["board"][~reset.squeeze(1)], before["board"][~reset.squeeze(1)])


# ---------------------------------------------------------------- bad arguments
@pytest.mark.parametrize("kwargs,message", [
    ({"game": "chess"}, "game must be one of standard, ultimate"),
    ({"batch_size": (0,)}, "batch_size must be a 1-tuple with a positive size"),
    ({"batch_size": (2, 3)}, "batch_size must be a 1-tuple"),
    ({"first": "nobody"}, "first must be one of robot, human, alternate, random"),
    ({"free_move": "never"}, "free_move must be one of anywhere, open_subgrids"),
    ({"opponent": "grandmaster"}, "unknown opponent 'grandmaster'"),
    ({"opponent": 3}, "opponent must be a name"),
    ({"asr_confidence": (0.5, 0.2)}, "asr_confidence must satisfy"),
    ({"max_actions": 0}, "max_actions must be a positive int"),
])
def test_bad_arguments(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make_env(**kwargs)


def test_unknown_option_is_rejected() -> None:
    with pytest.raises(ValueError, match="unknown option 'colour'; options: first, opponent"):
        make_env(colour="red")


@pytest.mark.parametrize("bad", [-1, 18, 1000])
def test_out_of_range_action(bad: int) -> None:
    env = make_env("standard")
    env.reset()
    with pytest.raises(ValueError, match=r"out of range: expected 0\.\.17"):
        env.step(TensorDict({"action": torch.tensor([bad])}, batch_size=[1]))


def test_an_opponent_object_with_rows_plays_queued_moves_and_rejects_illegal_ones() -> None:
    env = scripted("robot")
    start_game(env)
    with pytest.raises(ValueError, match="not legal"):
        act(env, 4, 4)



@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_filter_is_as_sharp_as_the_example_dialogues(game: str) -> None:
    """In masked play every dialogue context allows one act type, and feedback always matches the result."""
    env = make_env(game, batch_size=(64,), first="random", seed=9)
    cells, td = env.cells, env.reset()
    feedback = {1: "Provide(feedback=win)", 2: "Provide(feedback=loose)", 3: "Provide(feedback=draw)"}
    for _ in range(120 if game == "ultimate" else 40):
        mask = td["action_mask"]
        kinds = mask[:, :cells].any(1).long() + mask[:, cells:].sum(1)
        assert (kinds == 1).all(), "more than one kind of act allowed in a context of the example dialogues"
        over = td["outcome"].squeeze(1) > 0
        for row in over.nonzero().flatten().tolist():
            allowed = {env.action_names[a] for a in mask[row].nonzero().flatten().tolist()}
            assert allowed <= {feedback[int(td["outcome"][row])], "Salutation(closing)"}
        td = env.rand_action(td)
        _, td = env.step_and_maybe_reset(td)
