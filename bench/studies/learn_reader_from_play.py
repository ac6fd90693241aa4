"""The reader that learns from play, measured on the robot's own camera (SAPIEN): games against a person writing in
a handwriting the classifier never saw, the reader learning after each game, against the same games read frozen;
then learning again offline from the frozen games' logs, from other starting classifiers and with a share of
deliberately wrong labels (a person who lies).

    python bench/studies/learn_reader_from_play.py --weights W.pt --styles sketch,hershey --games 20 --seed 0 \
        --out runs/learn_reader [--offline-weights W1.pt,W2.pt] [--wrong-claims 0.1,0.25,0.5] [--label-checks on,off]

Each step is one `ncbot` command (printed before it runs) whose folder is kept: a step whose report is there is not
run again, so the study resumes after a stop. Writes OUT/learn_reader.json and OUT/learn_reader.png.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.pipelines.evaluate.games import wilson_interval  # noqa: E402
from ncbot.pipelines.plots import pyplot, save_figure  # noqa: E402


def ncbot(args: list[str], report: Path) -> dict:
    """Run one step unless its report exists; its JSON report."""
    if not report.is_file():
        print("ncbot " + " ".join(args), file=sys.stderr, flush=True)
        done = subprocess.run([sys.executable, "-m", "ncbot", *args], capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"step failed ({done.returncode}): {done.stderr[-2000:]}")
        if not report.is_file():  # `ncbot learn --json` prints its report
            report.write_text(done.stdout)
    return json.loads(report.read_text())


def play(style: str, weights: Path, games: int, seed: int, out: Path, learn: bool) -> dict:
    conditions = out / f"{style}.yaml"
    conditions.parent.mkdir(parents=True, exist_ok=True)
    conditions.write_text(f"base: lab\nhandwriting: [{style}]\n")
    folder = out / style / ("learning" if learn else "frozen")
    args = ["robot", "play", "--games", str(games), "--seed", str(seed), "--first", "alternate", "--speech", "text",
            "--weights", str(weights), "--conditions", str(conditions), "--out", str(folder), "--no-progress"]
    return ncbot(args + (["--learn", "--person", style] if learn else []), folder / "report.json")


def offline(log: Path, weights: Path, claims: float, check: bool, folder: Path) -> dict:
    return ncbot(["learn", str(log), "--out", str(folder), "--weights", str(weights), "--wrong-claims", str(claims),
                  "--json", "--no-progress"] + ([] if check else ["--no-label-check"]), folder.parent / f"{folder.name}.json")


def per_game(report: dict, key: str) -> list[int]:
    return [entry.get(key) or 0 for entry in report["per_game"]]


def wilson(right: int, total: int) -> dict:
    return {"count": right, "of": total, "rate": round(right / total, 4) if total else None,
            "wilson95": [round(b, 4) for b in wilson_interval(right, total)]}


def summarise(data: dict) -> dict:
    """The headline figures per style, each with its 95 % Wilson interval: moves misread or unseen (all games and
    the second half), held-out cells read right before and after (the person's style and the other held-out
    ones), the same after offline learning with wrong labels, and the CPU seconds of an update."""
    summary = {}
    for style, runs in data["styles"].items():
        row = {}
        for mode in ("frozen", "learning"):
            wrong = np.add(runs[mode]["misrecognised"], runs[mode]["unseen"])
            half = len(wrong) // 2
            row[mode] = {"wrong_moves": wilson(int(wrong.sum()), runs[mode]["human_moves"]),
                         "wrong_moves_second_half": int(wrong[half:].sum()),
                         "losses": runs[mode]["outcomes"].count("loss")}
        cells = data["cells_per_style"]
        row["accuracy"] = {name: {when: wilson(round(value * cells), cells) for when, value in read.items()}
                           for name, read in runs["learning"]["accuracy"].items()}
        row["offline_accuracy"] = {name: {other: wilson(round(read["after"] * cells), cells)
                                          for other, read in step["accuracy"].items()}
                                   for name, step in runs["offline"].items()}
        cpu = runs["learning"]["update_cpu_seconds"]
        row["update_cpu_seconds"] = {"mean": round(float(np.mean(cpu)), 3), "max": round(max(cpu), 3),
                                     "updates": len(cpu), "kept": sum(bool(k) for k in runs["learning"]["kept"])}
        summary[style] = row
    return summary


def draw(data: dict, path: Path) -> Path:
    plt = pyplot()
    styles = list(data["styles"])
    fig, axes = plt.subplots(1, len(styles), figsize=(5 * len(styles), 3.8), squeeze=False)
    for ax, style in zip(axes[0], styles):
        for mode, colour in (("frozen", "tab:gray"), ("learning", "tab:purple")):
            run = data["styles"][style][mode]
            wrong = np.add(run["misrecognised"], run["unseen"])
            ax.plot(np.arange(len(wrong)), np.cumsum(wrong), "o-", color=colour, ms=3,
                    label=f"{mode}: {int(wrong.sum())} of {run['human_moves']} moves")
        accuracy = data["styles"][style]["learning"]["accuracy"][style]
        ax.set_title(f"person writing {style!r} (held out)\nits cells read right {100 * accuracy['before']:.1f}% -> "
                     f"{100 * accuracy['after']:.1f}% after play", fontsize=9)
        ax.set_xlabel("game")
        ax.set_ylabel("moves misread or unseen, so far")
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--weights", type=Path, required=True)
    parser.add_argument("--styles", default="sketch,hershey")
    parser.add_argument("--games", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--offline-weights", default="")
    parser.add_argument("--wrong-claims", default="0.1,0.25,0.5")
    parser.add_argument("--label-checks", default="on,off", help="the ink check in the wrong-label runs: on, off or both")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    data = {"weights": str(args.weights), "games": args.games, "seed": args.seed, "styles": {}}
    for style in args.styles.split(","):
        runs = {}
        for mode in ("frozen", "learning"):
            report = play(style, args.weights, args.games, args.seed, args.out, mode == "learning")
            runs[mode] = {"misrecognised": per_game(report, "misrecognised_moves"), "unseen": per_game(report, "unseen_moves"),
                          "outcomes": [entry["outcome"] for entry in report["per_game"]],
                          "human_moves": sum(per_game(report, "human_moves"))}
            if mode == "learning":
                data["cells_per_style"] = report["learning"]["reader"]["cells_per_style"]
                runs[mode]["accuracy"] = report["learning"]["reader"]["accuracy"]
                runs[mode]["update_cpu_seconds"] = [e["reader"]["cpu_seconds"] for e in report["per_game"]]
                runs[mode]["kept"] = [e["reader"]["kept"] for e in report["per_game"]]
        log = args.out / style / "frozen"
        runs["offline"] = {}
        starts = [args.weights] + [Path(w) for w in args.offline_weights.split(",") if w]
        shares = [float(c) for c in args.wrong_claims.split(",") if c]
        steps = [(index, 0.0, True) for index in range(len(starts))]  # lies: from the study's own start, with
        checks = [{"on": True, "off": False}[c] for c in args.label_checks.split(",")]
        steps += [(0, claims, check) for claims in shares for check in checks]  # with and without the ink check
        for index, claims, check in steps:
            name = f"start{index}-claims{claims}-{'check' if check else 'nocheck'}"
            report = offline(log, starts[index], claims, check, args.out / style / "offline" / name)
            runs["offline"][name] = {"weights": str(starts[index]), "wrong_claims": claims, "label_check": check,
                                     "accuracy": report["learning"]["reader"]["accuracy"],
                                     "kept": sum(bool((e.get("reader") or {}).get("kept")) for e in report["per_game"])}
        data["styles"][style] = runs
    data["summary"] = summarise(data)
    print(json.dumps(data["summary"], indent=1))
    (args.out / "learn_reader.json").write_text(json.dumps(data, indent=1))
    draw(data, args.out / "learn_reader.png")
    print(f"wrote {args.out / 'learn_reader.json'} and {args.out / 'learn_reader.png'}")


if __name__ == "__main__":
    main()
