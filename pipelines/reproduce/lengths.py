"""Dialogue length, task success and reward per act of the untrained look-ahead agents under each reading.

Run: python -m ncbot.pipelines.reproduce.lengths [--games 400] [--game standard,ultimate]
Why: the faithful options (env.taken_squares, env.dialogues) are meant to bring our dialogues to the paper's
shape (3x3 13.9-15.3 acts, Ultimate 52-71); this measures it without training, with each agent's own look-ahead
masks and a seeded uniform choice inside them (modules.policies.masks.LookaheadOnlyPolicy), robot first (the paper's
set-up). A trained agent plays shorter games than its untrained masks (it wins sooner and, with taken squares
offered, learns to avoid them); docs/reproduction.md gives both.
"""
from __future__ import annotations

import argparse

import torch

RULES = {"DQN-Original": "none", "DQN-Variant": "variant", "Proposed": "one_step"}
MISREAD_RATE = 0.10  # the paper configs' env.misread_rate


@torch.no_grad()
def rollout(game: str, dialogues: str, taken_squares: str, rule: str, games: int, seed: int = 0) -> dict[str, float]:
    """The first dialogue of each of ``games`` env slots, played to its end (closing or the 100-action cap)."""
    from ncbot.envs import make_env
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy

    rate = MISREAD_RATE if taken_squares == "misread" else None
    env = make_env(game, batch_size=(games,), seed=seed, first="robot", taken_squares=taken_squares, misread_rate=rate,
                   dialogues=dialogues)
    policy = LookaheadOnlyPolicy(seed=seed + 1, lookahead=rule)
    td = env.reset()
    done = torch.zeros(games, dtype=torch.bool)
    length, total, outcome = torch.zeros(games), torch.zeros(games), torch.zeros(games, dtype=torch.int64)
    while not bool(done.all()):
        step = env.step(policy(td))["next"]
        alive = ~done
        length += alive
        total += step["reward"].squeeze(1) * alive
        ended = step["done"].squeeze(1)
        outcome = torch.where(alive & ended, step["outcome"].squeeze(1).long(), outcome)
        done |= ended
        td = step
    return {"avg_length": float(length.mean()), "task_success": float(((outcome == 1) | (outcome == 3)).float().mean()),
            "avg_reward": float(total.sum() / length.sum()), "features": env.n_features}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--games", type=int, default=400)
    parser.add_argument("--game", default="standard,ultimate")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print("| game | dialogues | taken squares | agent's masks | dialogue length | task success | avg reward / act |")
    print("|---|---|---|---|---|---|---|")
    for game in args.game.split(","):
        for dialogues in ("compact", "paper"):
            for taken in ("never", "refused", "misread"):
                for agent, rule in RULES.items():
                    r = rollout(game, dialogues, taken, rule, args.games)
                    print(f"| {game} | {dialogues} | {taken} | {agent} | {r['avg_length']:.2f} | "
                          f"{r['task_success']:.3f} | {r['avg_reward']:.4f} |", flush=True)


if __name__ == "__main__":
    main()
