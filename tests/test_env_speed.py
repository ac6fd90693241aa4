"""Correctness of the env's speed paths: each fast path must give exactly what the plain path gives."""
from __future__ import annotations

import pytest
import torch
from torchrl.envs import EnvBase
from torchrl.envs.utils import step_mdp

from envs import make_env
from envs.dialogue_env import uniform_choice
from envs.engine import make_engine


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_reset_merge_equals_torchrl_generic_merge(game: str) -> None:
    """The env's one-update reset merge == TorchRL's per-key where, also for a key the env does not emit."""
    torch.manual_seed(0)
    batch = 16
    env = make_env(game, batch_size=(batch,), seed=1)
    td = env.reset()
    merged = 0
    for _ in range(120 if game == "standard" else 200):
        td = step_mdp(env.step(env.rand_action(td)))
        td["policy_output"] = torch.arange(1.0, batch + 1).unsqueeze(1)  # e.g. a Q-value the policy wrote
        done = td["done"]
        if not bool(done.any()):
            continue
        request = td.clone()
        request["_reset"] = done.clone()
        reset_out = env._reset(request.select("_reset"))
        fast = env._reset_proc_data(request.clone(), reset_out.clone())
        generic = EnvBase._reset_proc_data(env, request.clone(), reset_out.clone())
        assert set(fast.keys(True, True)) == set(generic.keys(True, True))
        for key in generic.keys(True, True):
            assert torch.equal(fast[key], generic[key]), key
        # the padded key: 0 on reset rows, kept elsewhere
        assert torch.equal(fast["policy_output"][done], torch.zeros(int(done.sum())))
        merged += int(not bool(done.all()))
        td = fast
    assert merged > 0, "no partial reset happened: the test did not exercise the merge"


def test_uniform_choice_is_uniform_over_allowed_columns() -> None:
    generator = torch.Generator().manual_seed(0)
    mask = torch.zeros(60_000, 90, dtype=torch.bool)
    allowed = [0, 7, 8, 44, 89]
    mask[:, allowed] = True
    mask[:10, :] = False
    mask[:10, 3] = True  # a row with one allowed column must pick it
    picks = uniform_choice(mask, generator)
    assert bool(mask.gather(1, picks.unsqueeze(1)).all()), "picked a masked column"
    assert bool((picks[:10] == 3).all())
    counts = torch.bincount(picks[10:], minlength=90)[allowed].float()
    expected = (60_000 - 10) / len(allowed)
    assert float(((counts - expected).abs() / expected).max()) < 0.05, counts
    again = uniform_choice(mask, torch.Generator().manual_seed(0))
    assert torch.equal(picks, again), "same seed, different picks"


def test_uniform_choice_full_and_narrow_rows() -> None:
    generator = torch.Generator().manual_seed(3)
    for width in (1, 2, 9, 81):
        mask = torch.rand(5000, width, generator=generator) < 0.5
        mask[:, -1] = True
        picks = uniform_choice(mask, generator)
        assert bool(mask.gather(1, picks.unsqueeze(1)).all())
        assert int(picks.max()) == width - 1 or width == 1


@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_ultimate_lookahead_on_active_rows_only_matches_all_rows(free_move: str) -> None:
    """``move_rewards(active=...)`` skips games, and must not change the rows it evaluates."""
    engine = make_engine("ultimate", free_move)
    generator = torch.Generator().manual_seed(5)
    state = engine.new(256)
    checked = 0
    for move in range(60):
        legal = engine.legal(state)
        can_move = legal.any(1)
        if not bool(can_move.any()):
            break
        active = can_move & (torch.rand(256, generator=generator) < 0.6)
        full = engine.move_rewards(state, 1 + move % 2)
        partial = engine.move_rewards(state, 1 + move % 2, active)
        rows = active.unsqueeze(1) & legal
        assert torch.equal(full[rows], partial[rows])
        checked += int(rows.sum())
        engine.play(state, uniform_choice(legal, generator), 1 + move % 2, can_move)
    assert checked > 10_000


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_partial_reset_output_equals_full_recompute(game: str) -> None:
    """A partial reset pastes the fresh observation / winning rows into the last ones: == computing them anew."""
    env = make_env(game, batch_size=(32,), seed=2, temporal=True, starts="alternate")
    td = env.reset()
    partial = 0
    for _ in range(60 if game == "standard" else 150):
        td = step_mdp(env.step(env.rand_action(td)))
        done = td["done"].reshape(-1)
        if not bool(done.any()) or bool(done.all()):
            continue
        fast = env._reset(td.select().set("_reset", td["done"].clone()))
        full = env._output()  # the plain path on the same (already reset) state
        for key in full.keys():
            assert torch.equal(fast[key], full[key]), key
        assert not bool(fast["done"].any())
        partial += 1
        td = fast
    assert partial > 0, "no partial reset happened: the test did not exercise the fast path"
