"""How often the Q-guided search's pick agrees with the greedy move on the robot's own moves (search-target labels).

Why: `search_targets` trains Q towards the search's picks with a margin; where the two disagree on near-tied moves
the margin teaches tie-breaks (docs/ultimate.md). Plays `--frames` greedy frames of an agent
against the random user, labels up to `--moves` robot moves with a choice (robot-second games unless `--seat both`)
with each teacher, prints the share that agrees with the greedy move and the CPU per label.

    python bench/studies/search_label_agreement.py /tmp/ult/runs/base_s0/checkpoint.pt --value /tmp/s7/value_small/value.pt
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--value", default=None, help="value network for the second teacher (200 simulations)")
    parser.add_argument("--frames", type=int, default=2560)
    parser.add_argument("--moves", type=int, default=400)
    parser.add_argument("--seat", choices=("both", "second"), default="second")
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args()

    import torch

    from ncbot.modules.policies.policy import make_policies
    from ncbot.modules.search.search_targets import EXPERT_ACTION_KEY, LABEL_MASK_KEY, SearchTeacher
    from ncbot.pipelines.agents import guided_search, load_agent
    from ncbot.pipelines.run_env import make_run_env
    from ncbot.pipelines.train.build import make_collector

    torch.set_num_threads(1)
    config, greedy = load_agent(args.checkpoint)
    env = make_run_env(config.env, batch_size=64, seed=args.seed)
    agent = make_policies(greedy[0], env.action_spec_unbatched, config.lookahead, eps_init=0.0, eps_end=0.0,
                          annealing_frames=1)
    collector = make_collector(env, agent.explore, args.frames, args.frames)
    batch = next(iter(collector)).clone()
    collector.shutdown()
    teachers = [("Q priors + playouts, 32 simulations", 32, None)]
    if args.value:
        teachers.append(("value network, 200 simulations", 200, args.value))
    for name, simulations, value in teachers:
        search = guided_search(config, greedy, simulations, value=value)
        teacher = SearchTeacher(greedy, search, rows_per_batch=args.moves, seat=args.seat, gap=None, seed=1)
        teacher.label(batch)
        labels = teacher.labels[:]
        q = greedy(labels.select("observation").clone().update({
            "action_mask": labels[LABEL_MASK_KEY], "lookahead_reward": torch.zeros(len(labels), env.n_actions),
            "winning_actions": torch.zeros(len(labels), env.n_actions, dtype=torch.bool)}))["action_value"]
        greedy_move = q.masked_fill(~labels[LABEL_MASK_KEY], float("-inf")).argmax(-1)
        agree = float((greedy_move == labels[EXPERT_ACTION_KEY]).float().mean())
        print(f"{name}: {len(labels)} moves, agrees with greedy on {agree:.3f}, "
              f"{1000 * teacher.cpu_seconds / len(labels):.2f} ms CPU per label")
    env.close()


if __name__ == "__main__":
    main()
