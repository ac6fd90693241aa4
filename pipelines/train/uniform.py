"""The agent that learns nothing: a uniform choice inside an agent's greedy look-ahead mask (`agent.name: uniform`).

Why it is a row of every table: the masks alone (Algorithm 2's A and A_hat) win or draw most games against a random
user, so a learnt agent's task success means something only beside this baseline's. It is evaluated exactly like
a trained agent (same seeds, games and seats) and writes the same eval.json, with 0 frames and no checkpoint.
"""
from __future__ import annotations

import json
import time
from typing import Any

from ncbot.fileio import atomic_write_text
from ncbot.pipelines.config import RunConfig, dump_config
from ncbot.pipelines.machine import machine_record
from ncbot.pipelines.train.loop import EVAL_SEED_OFFSET


def evaluate_uniform(config: RunConfig, run: Any) -> dict[str, Any]:
    """eval.json of the uniform-inside-the-masks agent of ``config.lookahead`` (`train.seed` seeds its choices)."""
    from ncbot.modules.masks import LookaheadOnlyPolicy
    from ncbot.pipelines.evaluate.games import evaluate_agent
    from ncbot.pipelines.run_env import robot_seat

    started = time.monotonic()
    atomic_write_text(dump_config(config), run.path / "config.yaml")  # every run folder keeps what it ran
    seed = config.train.seed
    policy = LookaheadOnlyPolicy(seed=seed, lookahead=config.lookahead, all_negative=config.agent.all_negative)
    report: dict[str, Any] = {"frames": 0, "updates": 0, "episodes": 0, "seed": seed, "run_id": run.run_id,
                              "time_to_0995_s": None,
                              "lookahead": config.lookahead}
    for first in ("robot", "human"):
        result = evaluate_agent(config, policy, games=config.eval.games, first=first, seed=seed + 2 * EVAL_SEED_OFFSET,
                                agent_name="uniform")
        report[robot_seat(first)] = result.to_dict()
    report["train_wall_time_s"] = 0.0  # nothing is trained
    report["train_cpu_time_s"] = 0.0
    report["eval_wall_time_s"] = round(time.monotonic() - started, 2)
    report["history"] = []
    report["machine"] = machine_record()  # which CPU, kernels, threads and versions made these numbers
    atomic_write_text(json.dumps(report, indent=2) + "\n", run.path / "eval.json")
    return report
