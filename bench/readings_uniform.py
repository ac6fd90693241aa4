"""The paper's readings without learning: the Proposed agent's look-ahead masks with a uniform choice inside them.

Run: python bench/readings_uniform.py [--games 1000] [--game ultimate] [--dialogues paper] [--seed 0]
Why: whether a reading of taken squares (env.taken_squares), of the fallback when every allowed move is negative
(agent.all_negative) and of set A (env.win_set) makes games loop to the 100-act cap can be seen before any
training. Each row plays the first dialogue of ``--games`` env slots, robot first, with
``ncbot.modules.policies.masks.LookaheadOnlyPolicy`` (the greedy mask of the ``one_step`` rule, uniform inside it), to its end
(closing or the cap). Columns: task success (won or drawn), share of games cut at the cap, share of games that
reached a state where every allowed game move had a negative look-ahead reward (``all_moves_negative``), mean
dialogue length in acts, refused game moves per game. misread uses the paper configs' rate (0.10).
``--policy fixed`` replaces the uniform choice by a fixed preference (a seeded random score per game slot and
action, the same in every state: the greedy choice of an untrained Q that happens to prefer some squares), which
shows the loop a greedy agent falls into when a refusal changes nothing.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # measure this tree's code

MISREAD_RATE = 0.10


class FixedPreference:
    """Greedy over the look-ahead's greedy mask with a fixed random score per (game slot, action)."""

    def __init__(self, games: int, n_actions: int, seed: int, all_negative: str) -> None:
        from ncbot.modules.policies.masks import LookaheadMasks

        self.masks = LookaheadMasks("one_step", all_negative)
        self.scores = torch.rand(games, n_actions, generator=torch.Generator().manual_seed(seed))

    def __call__(self, td):
        greedy = self.masks(td).get("greedy_mask")
        td.set("action", torch.where(greedy, self.scores, -1.0).argmax(-1))
        return td


@torch.no_grad()
def rollout(game: str, dialogues: str, taken_squares: str, all_negative: str, win_set: str, games: int,
            seed: int = 0, chooser: str = "uniform") -> dict[str, float]:
    from ncbot.envs import make_env
    from ncbot.modules.policies.mask_rules import all_moves_negative
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy

    env = make_env(game, batch_size=(games,), seed=seed, first="robot", dialogues=dialogues, win_set=win_set,
                   taken_squares=taken_squares, misread_rate=MISREAD_RATE if taken_squares == "misread" else None)
    if chooser == "uniform":
        policy = LookaheadOnlyPolicy(seed=seed + 1, lookahead="one_step", all_negative=all_negative)
    else:
        policy = FixedPreference(games, env.n_actions, seed + 1, all_negative)
    td = env.reset()
    done = torch.zeros(games, dtype=torch.bool)
    length = torch.zeros(games)
    refused = torch.zeros(games)
    negative = torch.zeros(games, dtype=torch.bool)
    outcome = torch.zeros(games, dtype=torch.int64)
    truncated = torch.zeros(games, dtype=torch.bool)
    while not bool(done.all()):
        alive = ~done
        negative |= alive & all_moves_negative(td["action_mask"], td["lookahead_reward"], env.cells)
        td = policy(td)
        action = td["action"]
        refused += alive & (action < env.cells) & ~env.d.legal.gather(1, action.unsqueeze(1)).squeeze(1)
        step = env.step(td)["next"]
        length += alive
        ended = step["done"].squeeze(1)
        outcome = torch.where(alive & ended, step["outcome"].squeeze(1).long(), outcome)
        truncated |= alive & step["truncated"].squeeze(1)
        done |= ended
        td = step
    return {"task_success": float(((outcome == 1) | (outcome == 3)).float().mean()),
            "truncated": float(truncated.float().mean()), "all_negative_games": float(negative.float().mean()),
            "length": float(length.mean()), "refused": float(refused.mean())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--games", type=int, default=1000)
    parser.add_argument("--game", default="ultimate")
    parser.add_argument("--dialogues", default="paper")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--policy", choices=("uniform", "fixed"), default="uniform")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"{args.game}, robot first, dialogues {args.dialogues}, {args.games} games, seed {args.seed}, "
          f"one_step masks + {args.policy} choice")
    print("| taken_squares | all_negative | win_set | task success | truncated (100-act cap) | reached all-moves-negative "
          "| acts / dialogue | refused moves / game |")
    print("|---|---|---|---|---|---|---|---|")
    for taken in ("refused", "never", "misread"):
        for all_negative in ("available", "untaken"):
            for win_set in ("wins_and_threats", "wins"):
                start = time.perf_counter()
                r = rollout(args.game, args.dialogues, taken, all_negative, win_set, args.games, args.seed, args.policy)
                print(f"| {taken} | {all_negative} | {win_set} | {r['task_success']:.3f} | {r['truncated']:.3f} | "
                      f"{r['all_negative_games']:.3f} | {r['length']:.1f} | {r['refused']:.2f} |"
                      f"  <!-- {time.perf_counter() - start:.0f} s -->", flush=True)


if __name__ == "__main__":
    main()
