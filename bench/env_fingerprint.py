"""A hash of everything the dialogue env outputs over seeded rollouts: proof that a speed change kept it bit-identical.

Run: python bench/env_fingerprint.py [--steps 2000] [--batch 64]
The configurations and the hash are `ncbot.envs.fingerprint` (the tests use the same code); the printed
per-configuration and total hashes are recorded in docs/env.md; compare them before and after a change.
"""
from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree's envs, not an installed copy

from ncbot.envs.fingerprint import CONFIGS, fingerprint  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=2000, help="step_and_maybe_reset calls per configuration")
    parser.add_argument("--batch", type=int, default=64)
    args = parser.parse_args()
    torch.set_num_threads(1)
    total = hashlib.sha256()
    for name, kwargs, policy in CONFIGS:
        start = time.process_time()
        value = fingerprint(kwargs, policy, args.steps, args.batch)
        total.update(value.encode())
        print(f"{name:<40} {value}  ({time.process_time() - start:.1f} CPU s)", flush=True)
    print(f"{'TOTAL':<40} {total.hexdigest()[:16]}")


if __name__ == "__main__":
    main()
