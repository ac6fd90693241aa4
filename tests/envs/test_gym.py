"""The Gymnasium wrapper passes Gymnasium's own checker and carries the mask."""
from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ncbot.envs as envs
from ncbot.envs.gym_wrapper import NoughtsCrossesGymEnv

GAMES = ["standard", "ultimate"]


@pytest.mark.parametrize("game", GAMES)
def test_registered_env_passes_check_env(game: str) -> None:
    env = gymnasium.make(envs.GYM_ID, game=game)
    with warnings.catch_warnings():
        warnings.simplefilter("error", category=UserWarning)  # checker warnings would hide real problems
        check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("game,temporal,features", [("standard", True, 73), ("ultimate", False, 208)])
def test_masked_random_episode_ends_and_mask_matches_info(game: str, temporal: bool, features: int) -> None:
    env = gymnasium.make(envs.GYM_ID, game=game, temporal=temporal, render_mode="ansi")
    obs, info = env.reset(seed=5)
    assert obs.shape == (features,) and obs.dtype == np.float32
    rng = np.random.default_rng(0)
    for _ in range(100):
        mask = env.unwrapped.action_masks()
        assert np.array_equal(mask, info["action_mask"]) and mask.any()
        action = rng.choice(np.flatnonzero(mask))
        obs, reward, terminated, truncated, info = env.step(action)
        assert env.observation_space.contains(obs)
        assert reward in (-5.0, 0.0, 1.0, 5.0)
        if terminated or truncated:
            break
    assert terminated, "a masked random dialogue closes within 100 actions"
    assert info["outcome"] in (1, 2, 3)
    assert "robot:" in env.unwrapped.render()


def test_same_seed_same_episode() -> None:
    def run(seed: int) -> list[float]:
        env = gymnasium.make(envs.GYM_ID, game="standard", first="random")
        obs, info = env.reset(seed=seed)
        trace = [float(obs.sum())]
        for _ in range(12):
            action = int(np.flatnonzero(info["action_mask"])[-1])
            obs, reward, terminated, truncated, info = env.step(action)
            trace += [float(obs.sum()), reward]
        return trace

    assert run(11) == run(11)


def test_bad_kwargs_are_clear() -> None:
    with pytest.raises(ValueError, match="game must be one of standard, ultimate"):
        gymnasium.make(envs.GYM_ID, game="go")
    with pytest.raises(ValueError, match="render_mode"):
        NoughtsCrossesGymEnv(render_mode="human")
