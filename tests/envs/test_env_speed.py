"""Correctness of the env's speed paths: each fast path must give exactly what the plain path gives."""
from __future__ import annotations

import pytest
import torch
from torchrl.envs import EnvBase
from torchrl.envs.utils import step_mdp

from ncbot.envs import make_env
from ncbot.envs.dialogue_env import uniform_choice
from tests.envs.helpers import engine_of as make_engine
from ncbot.envs.engine.tables import uniform_choice_by_rows


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
    env = make_env(game, batch_size=(32,), seed=2, temporal=True, first="alternate")
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


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_step_output_needs_no_torchrl_completion(game: str) -> None:
    """The env skips TorchRL's ``_step_proc_data``: the generic pass must leave every step output unchanged."""
    env = make_env(game, batch_size=(8,), seed=4)
    td = env.reset()
    for _ in range(30):
        td = env.rand_action(td)
        out = env._step(td)
        generic = EnvBase._step_proc_data(env, out.clone())
        assert set(generic.keys()) == set(out.keys())
        for key in generic.keys():
            assert torch.equal(generic[key], out[key]) and generic[key].shape == out[key].shape, key
        td = step_mdp(td.set("next", out))
        if bool(td["done"].any()):
            td = env.reset(td.set("_reset", td["done"].clone()))


def test_standard_random_legal_by_table_equals_uniform_choice() -> None:
    """The 3x3 user's pick read from tables == uniform_choice over the legal squares, for every board code."""
    engine = make_engine("standard")
    state = engine.new(3**9)
    state.codes[:, 0] = torch.arange(3**9)
    legal = engine.legal(state)
    has_move = legal.any(1)
    for seed in range(4):
        by_table = engine.random_legal(state, torch.Generator().manual_seed(seed))
        plain = uniform_choice(legal, torch.Generator().manual_seed(seed))
        assert torch.equal(by_table[has_move], plain[has_move])
    assert int(has_move.sum()) > 5000


@pytest.mark.parametrize("width", [9, 18, 81, 90])
def test_uniform_choice_by_rows_equals_uniform_choice(width: int) -> None:
    """The 9-column-block pick (Ultimate's user and ``rand_action``) == uniform_choice, same generator, every row
    (all-False rows included), from sparse to full masks."""
    generator = torch.Generator().manual_seed(11)
    for density in (0.0, 0.03, 0.5, 1.0):
        mask = torch.rand(3000, width, generator=generator) < density
        for seed in range(3):
            plain = uniform_choice(mask, torch.Generator().manual_seed(seed))
            by_rows = uniform_choice_by_rows(mask, torch.Generator().manual_seed(seed))
            assert torch.equal(plain, by_rows)


@pytest.mark.parametrize("free_move", ["anywhere", "open_subgrids"])
def test_ultimate_random_legal_and_legal_rows(free_move: str) -> None:
    """Ultimate's user pick == uniform_choice over the legal squares, and ``legal(active=...)`` == legal AND active,
    over random games played to the end (forced, free and finished games in one batch)."""
    engine = make_engine("ultimate", free_move)
    generator = torch.Generator().manual_seed(4)
    state = engine.new(256)
    for ply in range(81):
        legal = engine.legal(state)
        active = torch.rand(256, generator=generator) < 0.6
        assert torch.equal(engine.legal(state, active), legal & active.unsqueeze(1))
        seed = ply * 7 + 1
        pick = engine.random_legal(state, torch.Generator().manual_seed(seed))
        assert torch.equal(pick, uniform_choice(legal, torch.Generator().manual_seed(seed)))
        can_move = legal.any(1)
        if not bool(can_move.any()):
            break
        engine.play(state, pick, 1 + ply % 2, can_move)
    assert ply > 40


def test_stage_table_equals_phase_rules() -> None:
    """Every stage (board status + dialogue flags) maps to the phase ``dialogue.phase_of`` gives."""
    from ncbot.envs import dialogue as dlg
    from ncbot.envs.dialogue_env import AGREED, CLOSED, ROBOT_FIRST

    env = make_env("standard", batch_size=(1,))
    for outcome in range(4):
        for marks in range(2):
            for robot_first in (False, True):
                for agreed in (False, True):
                    for closed in (False, True):
                        stage = outcome * 2 + marks + ROBOT_FIRST * robot_first + AGREED * agreed + CLOSED * closed
                        expected = dlg.phase_of(agreed, closed, outcome, (marks == 0) == robot_first)
                        assert int(env.tables.stage_phase[stage]) == expected


def test_standard_mask_and_lookahead_by_code_equal_engine_path() -> None:
    """3x3 mask / look-ahead / winning actions read as board-code rows == the engine's legal squares and
    move rewards combined with the act filter, over random rollouts (both seats)."""
    env = make_env("standard", batch_size=(64,), seed=6, first="alternate")
    td = env.reset()
    cells, checked = env.cells, 0
    for _ in range(200):
        td = env.rand_action(td)
        _, td = env.step_and_maybe_reset(td)
        dialogue_mask = td["dialogue_mask"]
        legal = env.engine.legal(env.boards) & dialogue_mask[:, :cells]
        mask = torch.cat([legal, dialogue_mask[:, cells:]], dim=1)
        rewards = torch.nn.functional.pad(env.engine.move_rewards(env.boards, 1), (0, env.n_actions - cells))
        lookahead = torch.where(mask, rewards, -5.0)
        assert torch.equal(td["action_mask"], mask)
        assert torch.equal(td["lookahead_reward"], lookahead)
        assert torch.equal(td["winning_actions"], mask & (lookahead == 5.0))
        checked += int(legal.any(1).sum())
    assert checked > 1000


def test_reply_tables_equal_model_tables_and_follow_edits() -> None:
    """The user's reply tables == reading ``reply_options`` with min(pick, K - 1) and silence where a context has
    no reply (or a move reply where the user does not move); a swapped-in model or an in-place edit of its
    tables (what ``ncbot play`` does) is picked up."""
    import dataclasses

    from ncbot.envs import dialogue as dlg

    env = make_env("standard", batch_size=(4,))
    env.model = dataclasses.replace(env.model, reply_options=env.model.reply_options.clone(),
                                    reply_counts=env.model.reply_counts.clone())
    options, model_counts = env.model.reply_options, env.model.reply_counts
    width = options.shape[-1]
    for _ in range(2):
        counts, replies = env.user.reply_tables()
        flat, flat_counts = options.reshape(-1, width), model_counts.reshape(-1)
        assert torch.equal(counts, flat_counts)
        for context in range(len(flat_counts)):
            if int(flat_counts[context]) == 0:  # pick = floor(u * 0) = 0 only
                assert int(replies[context * (width + 1)]) == env.tables.silence
                continue
            for pick in range(width + 1):
                expected = int(flat[context, min(pick, width - 1)])
                if int(env.model.utterance_acts[expected]) == dlg.USER_MOVE and not bool(env.tables.user_turn[context]):
                    expected = env.tables.silence  # a move utterance where the user does not move
                assert int(replies[context * (width + 1) + pick]) == expected
        model_counts[1] = 0  # edit in place: the next read must see it
        options[2, :, 0] = int(torch.nonzero(env.model.utterance_acts == dlg.USER_MOVE)[0])  # a move reply everywhere
    assert int(env.user.reply_tables()[0].reshape(model_counts.shape)[1].sum()) == 0
