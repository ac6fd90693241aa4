"""A hash of everything the dialogue env outputs over seeded rollouts: proof that a speed change kept it bit-identical.

Why: training runs depend on the env's random stream, so a faster env must give the same numbers for the same
seed. Each configuration is rolled out with ``env.rand_action`` (or, for the refused-act paths, a policy drawing
from ``dialogue_mask``, the DQN-Original action set, whose repeated moves are refused) through
``env.step_and_maybe_reset`` (partial resets), and every output key of every step is hashed (name, dtype,
shape and bytes). `bench/env_fingerprint.py` prints the per-configuration and total hashes recorded in
docs/env.md; compare them before and after a change.
"""
from __future__ import annotations

import hashlib

import torch
from tensordict import TensorDictBase

# (name, make_env keyword arguments, policy): "mask" = env.rand_action, "dialogue" = uniform over dialogue_mask
CONFIGS: tuple[tuple[str, dict, str], ...] = (
    ("standard/robot", dict(game="standard", first="robot"), "mask"),
    ("standard/alternate", dict(game="standard", first="alternate"), "mask"),
    ("standard/alternate/no-temporal", dict(game="standard", first="alternate", temporal=False), "mask"),
    ("standard/random-seat/dialogue-mask", dict(game="standard", first="random"), "dialogue"),
    ("standard/human/rule-opponent", dict(game="standard", first="human", opponent="rule"), "mask"),
    ("ultimate/robot", dict(game="ultimate", first="robot"), "mask"),
    ("ultimate/alternate", dict(game="ultimate", first="alternate"), "mask"),
    ("ultimate/alternate/open_subgrids", dict(game="ultimate", first="alternate", free_move="open_subgrids", temporal=False), "mask"),
    ("ultimate/robot/dialogue-mask", dict(game="ultimate", first="robot"), "dialogue"),
)


def hash_tensordict(digest: "hashlib._Hash", td: TensorDictBase) -> None:
    """Feed every leaf (sorted by key) into ``digest``: key, dtype, shape and raw bytes."""
    for key in sorted(td.keys(include_nested=True, leaves_only=True), key=str):
        value = td.get(key)
        digest.update(f"{key}|{value.dtype}|{tuple(value.shape)}".encode())
        digest.update(value.contiguous().view(torch.uint8).numpy().tobytes() if value.dtype != torch.bool else value.numpy().tobytes())


def fingerprint(kwargs: dict, policy: str, steps: int, batch: int, seed: int = 0) -> str:
    """The hash of a seeded rollout of ``steps`` calls of ``step_and_maybe_reset`` at ``batch`` games."""
    from ncbot.envs import make_env
    from ncbot.envs.dialogue_env import uniform_choice

    env = make_env(batch_size=(batch,), seed=seed, **kwargs)
    policy_rng = torch.Generator().manual_seed(seed + 7)
    digest = hashlib.sha256()
    td = env.reset()
    hash_tensordict(digest, td)
    for _ in range(steps):
        if policy == "mask":
            td = env.rand_action(td)
        else:
            td.set("action", uniform_choice(td.get("dialogue_mask"), policy_rng))
        stepped, td = env.step_and_maybe_reset(td)
        hash_tensordict(digest, stepped)
        hash_tensordict(digest, td)
    return digest.hexdigest()[:16]
