"""Board symmetries of replay transitions: a moved transition is exactly what the env gives for the moved game."""
from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from envs import make_env
from envs.external_opponent import ExternalOpponent
from modules.symmetry import BoardSymmetries, square_symmetries

torch.set_num_threads(1)


def test_the_eight_symmetries_form_the_square_group() -> None:
    images = square_symmetries()
    assert images.shape == (8, 9) and images[0].tolist() == list(range(9))
    assert len({tuple(row) for row in images.tolist()}) == 8
    table = {tuple(row) for row in images.tolist()}
    for a in images:
        for b in images:
            assert tuple(a[b].tolist()) in table  # closed under composition
    assert all(int(row[4]) == 4 for row in images)  # the centre stays


def play(robot_moves: list[int], user_moves: list[int], seed: int) -> list[TensorDict]:
    """A robot-second dialogue with scripted moves; every step's (root, next) TensorDict."""
    user = ExternalOpponent()
    env = make_env("standard", batch_size=(1,), seed=seed, starts="human", opponent=user)
    td = env.reset()
    steps = []
    robot_queue, user_queue = list(robot_moves), list(user_moves)
    for _ in range(30):
        mask = td["action_mask"][0]
        if bool(mask[:9].any()):
            action = robot_queue.pop(0)
        else:
            action = int(torch.nonzero(mask).reshape(-1)[0])
            if action == 13 and not user_queue:  # Request(userGameMove) needs a queued user move
                break
        if user_queue and (action < 9 or action == 13):
            user.queue([user_queue.pop(0)])
        td["action"] = torch.tensor([action])
        td = env.step(td)
        steps.append(td.clone())
        td = td["next"].clone()
        if bool(td["done"].all()) or not robot_queue and not user_queue:
            break
    return steps


@pytest.mark.parametrize("g", range(1, 8))
def test_moved_transitions_equal_the_env_playing_the_moved_game(g: int) -> None:
    user_moves, robot_moves = [1, 6, 2], [4, 0, 8]  # the robot wins on the diagonal
    image = square_symmetries()[g]
    original = play(robot_moves, user_moves, seed=5)
    moved = play([int(image[c]) for c in robot_moves], [int(image[c]) for c in user_moves], seed=5)
    assert len(original) == len(moved) >= 5
    env = make_env("standard", batch_size=(1,))
    symmetries = BoardSymmetries(env.feature_names, env.n_actions)
    keys = ["observation", "action_mask", "action", ("next", "observation"), ("next", "action_mask")]
    for step_a, step_b in zip(original, moved):
        transformed = symmetries.apply(step_a.select(*keys).clone(), torch.tensor([g]))
        for key in keys:
            assert torch.equal(transformed.get(key), step_b.get(key)), (g, key)
    assert not torch.equal(original[-1]["next", "observation"], moved[-1]["next", "observation"])  # boards differ


def test_randomise_is_seeded_and_refuses_ultimate() -> None:
    env = make_env("standard", batch_size=(64,), seed=1)
    td = env.rand_action(env.reset())
    td = env.step(td)
    symmetries = BoardSymmetries(env.feature_names, env.n_actions)
    keys = ["observation", "action_mask", "action", ("next", "observation"), ("next", "action_mask")]
    a = symmetries.randomise(td.select(*keys).clone(), torch.Generator().manual_seed(0))
    b = symmetries.randomise(td.select(*keys).clone(), torch.Generator().manual_seed(0))
    assert all(torch.equal(a.get(k), b.get(k)) for k in keys)
    assert bool(a["action_mask"].gather(1, a["action"].unsqueeze(1)).all())  # a legal act stays legal
    ultimate = make_env("ultimate", batch_size=(1,))
    with pytest.raises(ValueError, match="3x3 game only"):
        BoardSymmetries(ultimate.feature_names, ultimate.n_actions)
