"""Cost per decision of the k-step look-ahead rules, on positions of real dialogues.

Plays random dialogues in the real env (batch of games), keeps every TensorDict in which some robot may move,
then times each look-ahead rule's masks on those TensorDicts. Prints, per game / rule variant and rule: mean
wall and CPU milliseconds per robot decision, the worst batch, and how often the rule removed a move the
one-step rule kept. The machine is shared: CPU time (time.process_time) is what an idle core would see.

    python bench/studies/lookahead_cost.py                    # standard + both ultimate variants, k1 k3 k5
    python bench/studies/lookahead_cost.py --games ultimate --rules k3 --steps 200 --png lookahead_cost.png
"""
from __future__ import annotations

import argparse
import time

import torch


def collect_positions(game: str, free_move: str, batch: int, steps: int, seed: int) -> list:
    """TensorDicts (copies) of the states in which at least one robot may take a square."""
    from ncbot.envs import make_env

    env = make_env(game, batch_size=(batch,), temporal=True, free_move=free_move, seed=seed, first="alternate")
    td = env.reset()
    kept = []
    for _ in range(steps):
        if bool(td["action_mask"][:, :env.cells].any()):
            kept.append(td.clone())
        td = env.step(env.rand_action(td))["next"]
        if bool(td["done"].any()):
            td = env.reset(td.set("_reset", td["done"]))
    env.close()
    return kept


def time_rule(rule_name: str, positions: list, cells: int) -> dict:
    from ncbot.modules.policies.deep_lookahead import KStepLookahead
    from ncbot.modules.policies.masks import lookahead_rule

    rule = lookahead_rule(rule_name)
    one_step = lookahead_rule("one_step")
    decisions = removed = 0
    wall = cpu = worst = 0.0
    for td in positions:
        rows = td["action_mask"][:, :cells].any(-1)
        decisions += int(rows.sum())
        w0, c0 = time.perf_counter(), time.process_time()
        if isinstance(rule, KStepLookahead):
            _, greedy = rule.masks_from_tensordict(td)
        else:
            _, greedy = rule(td["action_mask"], td["lookahead_reward"], td["winning_actions"])
        w1, c1 = time.perf_counter(), time.process_time()
        wall, cpu, worst = wall + w1 - w0, cpu + c1 - c0, max(worst, w1 - w0)
        _, base = one_step(td["action_mask"], td["lookahead_reward"], td["winning_actions"])
        removed += int(((base & ~greedy)[:, :cells].any(-1) & rows).sum())
    return {"decisions": decisions, "wall_ms": 1e3 * wall / max(decisions, 1), "cpu_ms": 1e3 * cpu / max(decisions, 1),
            "worst_batch_ms": 1e3 * worst, "changed": removed / max(decisions, 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", nargs="+", default=["standard", "ultimate:anywhere", "ultimate:open_subgrids"])
    parser.add_argument("--rules", nargs="+", default=["one_step", "k1", "k3", "k5"])
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--steps", type=int, default=150, help="env steps of random dialogues per game")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--png", default=None, help="also draw CPU ms per decision as a bar chart")
    args = parser.parse_args()
    torch.set_num_threads(1)
    from ncbot.pipelines.progress import progress_bar

    results = []
    jobs = [(g, r) for g in args.games for r in args.rules]
    bar = progress_bar(jobs, desc="look-ahead cost", unit="rule")
    cache: dict = {}
    for spec, rule in bar:
        game, _, free_move = spec.partition(":")
        free_move = free_move or "anywhere"
        name = rule + ("_open" if free_move == "open_subgrids" and rule.startswith("k") else "")
        if spec not in cache:
            cache[spec] = collect_positions(game, free_move, args.batch, args.steps, args.seed)
        cells = 9 if game == "standard" else 81
        bar.set_postfix_str(f"{spec} {name}")
        results.append({"game": spec, "rule": name, **time_rule(name, cache[spec], cells)})
    print(f"\nbatch {args.batch}, {args.steps} env steps of random dialogues per game, seed {args.seed}\n")
    print("| game | rule | robot decisions | wall ms / decision | CPU ms / decision | worst batch (wall ms) | decisions where it removed a move one_step kept |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r['game']} | {r['rule']} | {r['decisions']} | {r['wall_ms']:.3f} | {r['cpu_ms']:.3f} | "
              f"{r['worst_batch_ms']:.1f} | {100 * r['changed']:.1f}% |")
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(8, 3.5))
        labels = [f"{r['game']}\n{r['rule']}" for r in results]
        ax.bar(range(len(results)), [r["cpu_ms"] for r in results], color="#457b9d")
        ax.set_xticks(range(len(results)), labels, fontsize=7, rotation=45, ha="right")
        ax.set_yscale("log")
        ax.set_ylabel("CPU ms per robot decision (log)")
        ax.set_title("k-step look-ahead: cost per decision")
        fig.tight_layout()
        fig.savefig(args.png, dpi=120)
        print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
