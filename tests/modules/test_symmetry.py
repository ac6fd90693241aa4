"""`buffer.augment: d4` (modules/replay/symmetry.py): the 8 board symmetries are symmetries of the real game engines and of
the env's observation layout, and a real training run with them is reproducible and resumable."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from tests.envs.helpers import engine_of as make_engine
from ncbot.modules.replay.symmetry import BoardSymmetries, make_symmetries, square_symmetries
from ncbot.pipelines.config import load_config
from ncbot.pipelines.run_env import make_run_env
from ncbot.pipelines.train.run import train
from tests.learning_helpers import write_tiny_config

torch.set_num_threads(1)
CONFIGS = Path(__file__).resolve().parents[2] / "pipelines" / "configs"


@pytest.mark.parametrize("side", [3, 9])
def test_the_eight_maps_are_distinct_permutations_closed_under_composition(side: int) -> None:
    images = square_symmetries(side)
    cells = side * side
    assert torch.equal(images[0], torch.arange(cells))
    assert all(torch.equal(image.sort().values, torch.arange(cells)) for image in images)
    distinct = {tuple(image.tolist()) for image in images}
    assert len(distinct) == 8
    assert {tuple(a[b].tolist()) for a in images for b in images} == distinct  # a group: composing stays inside


def _random_games(game: str, rows: int, moves: int, seed: int) -> list[torch.Tensor]:
    """Move lists (one (rows,) tensor per ply) of random legal games; finished rows repeat a dummy move."""
    engine, generator = make_engine(game), torch.Generator().manual_seed(seed)
    state, plies = engine.new(rows), []
    for ply in range(moves):
        legal = engine.legal(state)
        active = legal.any(dim=1)
        cells = torch.multinomial(legal.float() + (~active).float().unsqueeze(1), 1, generator=generator).squeeze(1)
        engine.play(state, cells, 1 + ply % 2, active=active)
        plies.append(torch.where(active, cells, -1))
    return plies


@pytest.mark.parametrize("game, moves", [("standard", 4), ("standard", 6), ("ultimate", 25), ("ultimate", 45)])
def test_turned_games_have_turned_legal_moves_and_look_ahead_rewards(game: str, moves: int) -> None:
    """Replaying a game turned by g gives, at the end, the turned legal mask and turned one-step rewards of BOTH
    players: the rules (lines, subgrids, where a move sends the next player) commute with the symmetry."""
    side = 3 if game == "standard" else 9
    plies = _random_games(game, rows=128, moves=moves, seed=moves)
    engine = make_engine(game)
    images = square_symmetries(side)
    results = []
    for image in images:
        state = engine.new(128)
        for ply, cells in enumerate(plies):
            active = cells >= 0
            engine.play(state, image[cells.clamp(min=0)], 1 + ply % 2, active=active)
        results.append((engine.legal(state), engine.move_rewards(state, 1), engine.move_rewards(state, 2)))
    base = results[0]
    assert bool(base[0].any())  # games still on: the comparison is not between empty masks
    for image, turned in zip(images, results):
        preimage = torch.argsort(image)
        for original, image_of_it in zip(base, turned):
            assert torch.equal(original[:, preimage], image_of_it)


@pytest.mark.parametrize("config_name", ["default.yaml", "ultimate.yaml"])
def test_observations_turn_with_the_board_and_dialogue_features_stay(config_name: str) -> None:
    config = load_config(CONFIGS / config_name, [])
    env = make_run_env(config.env, batch_size=32, seed=5)
    symmetries = BoardSymmetries.from_env(env, seed=0)
    cells = env.cells
    td = env.reset()
    for _ in range(12):  # into the game: marks on the board
        td = env.step(td.set("action", env.rand_action(td)["action"]))["next"]
    observation, board = td["observation"], td["board"].long()
    assert bool((board > 0).any())
    robot_mark = observation[:, :cells].bool()
    for which in range(8):
        rows = torch.full((32,), which)
        image = symmetries.observations(observation, rows)
        preimage = torch.argsort(square_symmetries(round(cells ** 0.5))[which])
        assert torch.equal(image[:, :cells].bool(), robot_mark[:, preimage])
        assert torch.equal(image[:, 2 * cells:2 * cells + 46], observation[:, 2 * cells:2 * cells + 46])  # words
        assert torch.equal(image[:, -cells:], observation[:, -cells:][:, preimage])  # temporal
        action = torch.arange(env.n_actions)
        mapped = symmetries.actions(action, torch.full_like(action, which))
        assert torch.equal(mapped[cells:], action[cells:])  # dialogue acts do not move
        mask = td["action_mask"]
        assert torch.equal(symmetries.masks(mask, rows)[:, mapped], mask)  # the image of a legal move is legal


def test_bad_augment_value_names_the_key() -> None:
    with pytest.raises(ValueError, match="buffer.augment"):
        make_symmetries("d8", None, 0)
    with pytest.raises(ValueError, match="buffer.augment"):
        load_config(CONFIGS / "default.yaml", ["buffer.augment=d8"])


def test_augmented_run_is_reproducible_and_differs_from_plain(tmp_path: Path) -> None:
    config_path = write_tiny_config(tmp_path)
    runs = {}
    for name, augment in (("a", "d4"), ("b", "d4"), ("plain", "none")):
        train(load_config(config_path, [f"buffer.augment={augment}"]), tmp_path / name)
        runs[name] = torch.load(tmp_path / name / "checkpoint.pt", weights_only=True)["qnet"]
    assert all(torch.equal(runs["a"][key], runs["b"][key]) for key in runs["a"])
    assert not all(torch.equal(runs["a"][key], runs["plain"][key]) for key in runs["a"])


def test_the_symmetry_stream_resumes_where_it_stopped() -> None:
    """The learner's checkpoint holds the draw generator, so a resumed run draws the same symmetries."""
    symmetries = BoardSymmetries([f"robot_move[{c}]" for c in range(9)], cells=9, n_actions=18, seed=4)
    symmetries.draw(100)
    saved = symmetries.state_dict()
    expected = symmetries.draw(50)
    restored = BoardSymmetries([f"robot_move[{c}]" for c in range(9)], cells=9, n_actions=18, seed=0)
    restored.load_state_dict(saved)
    assert torch.equal(restored.draw(50), expected)
