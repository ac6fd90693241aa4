"""loss.bootstrap: ("next", "bootstrap_mask"), where the loss maximises, holds the next state's greedy mask (the agent's
own rule) under `greedy` and its available actions under `available`; the env's masks keep their meaning."""
from __future__ import annotations

import pytest
import torch

from ncbot.envs import make_env
from ncbot.modules.replay.bootstrap import BOOTSTRAP_MASK_KEY, NEXT_LOOKAHEAD_KEYS, bootstrap_keys, set_bootstrap_mask
from ncbot.modules.policies.masks import GREEDY_MASK_KEY, LookaheadMasks

torch.set_num_threads(1)
KEYS = ("observation", "action_mask", "action", ("next", "observation"), ("next", "action_mask"), ("next", "reward"))


def rollout_transitions(steps: int = 12, batch: int = 64):
    """Real transitions of random masked play (robot from both seats), flattened like the training loop's."""
    env = make_env("standard", batch_size=(batch,), seed=4, first="alternate")
    td = env.reset()
    collected = []
    for _ in range(steps):
        td = env.rand_action(td)
        td, root = env.step_and_maybe_reset(td)
        collected.append(td.select(*KEYS, *NEXT_LOOKAHEAD_KEYS).clone())
        td = root
    return torch.cat(collected)


@pytest.mark.parametrize("lookahead", ["one_step", "variant", "none"])
def test_greedy_bootstrap_mask_is_the_policy_greedy_mask_of_the_next_state(lookahead: str) -> None:
    transitions = rollout_transitions()
    next_state = transitions.get("next").clone()
    expected = LookaheadMasks(lookahead)(next_state).get(GREEDY_MASK_KEY)
    result = set_bootstrap_mask(transitions.clone(), "greedy", lookahead)
    assert torch.equal(result.get(BOOTSTRAP_MASK_KEY), expected)
    assert not any(key in result.keys(include_nested=True) for key in NEXT_LOOKAHEAD_KEYS)  # buffer stays small
    for key in ("action_mask", ("next", "action_mask")):  # the env's masks are untouched
        assert torch.equal(result.get(key), transitions.get(key))
    if lookahead == "one_step":  # on 3x3 the greedy set really is smaller than the available moves in many states
        assert bool((result.get(BOOTSTRAP_MASK_KEY) != transitions.get(("next", "action_mask"))).any())


def test_available_is_unchanged_and_bad_input_is_named() -> None:
    transitions = rollout_transitions(steps=3, batch=8)
    assert bootstrap_keys("available") == () and bootstrap_keys("greedy") == NEXT_LOOKAHEAD_KEYS
    same = set_bootstrap_mask(transitions.clone(), "available", "one_step")
    assert torch.equal(same.get(BOOTSTRAP_MASK_KEY), transitions.get(("next", "action_mask")))
    with pytest.raises(ValueError, match="unknown loss.bootstrap 'best'; expected one of available, greedy"):
        bootstrap_keys("best")
    with pytest.raises(ValueError, match="needs the transitions'"):
        set_bootstrap_mask(transitions.exclude(*NEXT_LOOKAHEAD_KEYS), "greedy", "one_step")
    with pytest.raises(ValueError, match="one-step mask rules"):
        set_bootstrap_mask(transitions.clone(), "greedy", "k2")


def test_training_applies_the_option(tmp_path) -> None:
    """Same seed, the two bootstraps: the trained weights differ, so train.py really routes loss.bootstrap."""
    from ncbot.pipelines.checkpoint import load_checkpoint
    from ncbot.pipelines.config import load_config
    from ncbot.pipelines.train.run import train
    from tests.learning_helpers import write_tiny_config

    weights = {}
    for choice in ("available", "greedy"):
        config = load_config(write_tiny_config(tmp_path), [f"loss.bootstrap={choice}", "collector.total_frames=256"])
        train(config, tmp_path / choice)
        weights[choice] = load_checkpoint(tmp_path / choice / "checkpoint.pt")["qnet"]
    assert weights["available"].keys() == weights["greedy"].keys()
    assert any(not torch.equal(weights["available"][key], weights["greedy"][key]) for key in weights["greedy"])
