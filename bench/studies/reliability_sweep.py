"""Run the bad inputs of the reliability tests against every subcommand and count how each ends (docs/reliability.md).

    python bench/studies/reliability_sweep.py [--list]

Each case runs in-process through `ncbot.pipelines.cli.app.main` in a fresh folder with a 90 s alarm. A case is HANDLED when
it exits 2 with one `ncbot: error:` line and no traceback (or, for inputs that are fine, exits 0), and leaves
no new file when it was refused. Prints one line per kind and the totals; exit 1 if any case is not handled.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import pickle
import signal
import sys
import tempfile
from collections import Counter
from pathlib import Path

import torch
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from ncbot.pipelines.checkpoint import FORMAT, atomic_save  # noqa: E402
from ncbot.pipelines.cli.app import main  # noqa: E402
from tests.learning_helpers import TINY  # noqa: E402
from tests.cli.test_reliability_fuzz import GOOD_GRID, _valid_agent  # noqa: E402


class Hang(BaseException):
    """The alarm fired: the case ran longer than a refusal ever should."""


def _alarm(_signum, _frame):
    raise Hang()


def fixtures(tmp: Path) -> dict[str, str]:
    """Files every case may point at: good ones and bad ones of each kind."""
    (tmp / "tiny.yaml").write_text(yaml.safe_dump(TINY))
    atomic_save(_valid_agent(), tmp / "run" / "checkpoint.pt")
    (tmp / "grid.yaml").write_text(yaml.safe_dump(GOOD_GRID))
    (tmp / "binary.bin").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)))
    (tmp / "latin1.yaml").write_bytes("env:\n  game: caf\xe9\n".encode("latin-1"))
    (tmp / "empty.yaml").write_text("")
    (tmp / "badyaml.yaml").write_text("env: [\n  game: standard\n")
    (tmp / "tag.yaml").write_text("!!python/object/apply:os.system ['touch pwned']\n")
    (tmp / "list.yaml").write_text("- env\n- agent\n")
    (tmp / "text.txt").write_text("hello\n")
    (tmp / "a_folder").mkdir()
    (tmp / "empty_folder").mkdir()
    atomic_save({"format": FORMAT}, tmp / "format_only.pt")
    mismatch = _valid_agent()
    mismatch["config"]["agent"]["hidden"] = [100, 100, 100]
    atomic_save(mismatch, tmp / "mismatch.pt")
    torch.save({"weights": torch.zeros(3)}, tmp / "foreign.pt")
    (tmp / "pickle.pt").write_bytes(pickle.dumps({"format": FORMAT, "x": [1, 2]}))
    good = (tmp / "run" / "checkpoint.pt").read_bytes()
    (tmp / "truncated.pt").write_bytes(good[: len(good) // 2])
    (tmp / "notmcap.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(100))
    runs = tmp / "runs" / "s" / "standard" / "proposed-temporal" / "seed0"
    runs.mkdir(parents=True)
    (runs / "eval.json").write_text("[1, 2]")
    return {name: str(tmp / name) for name in (
        "tiny.yaml", "grid.yaml", "binary.bin", "latin1.yaml", "empty.yaml", "badyaml.yaml", "tag.yaml", "list.yaml",
        "text.txt", "a_folder", "empty_folder", "format_only.pt", "mismatch.pt", "foreign.pt", "pickle.pt",
        "truncated.pt", "notmcap.mcap", "runs")} | {"missing": str(tmp / "missing"), "ckpt": str(tmp / "run" / "checkpoint.pt"),
                                                  "under_file": str(tmp / "text.txt" / "sub"), "tmp": str(tmp)}


BAD_FILES = ["missing", "a_folder", "binary.bin", "latin1.yaml", "empty.yaml", "badyaml.yaml", "tag.yaml", "list.yaml",
             "text.txt"]
BAD_CHECKPOINTS = ["missing", "a_folder", "binary.bin", "text.txt", "format_only.pt", "mismatch.pt", "foreign.pt",
                   "pickle.pt", "truncated.pt", "empty.yaml"]
BAD_NUMBERS = ["-1", "0", "abc", "1.5", "100000000000000000000000000000", ""]


def cases() -> list[tuple[str, list[str]]]:
    """(kind, args) with {names} from `fixtures`."""
    out: list[tuple[str, list[str]]] = []
    add = out.append
    # configs and grids
    for bad in BAD_FILES:
        add(("train: bad config file", ["train", f"{{{bad}}}", "--out", "{tmp}/r"]))
        add(("ablate: bad grid file", ["ablate", f"{{{bad}}}", "--out", "{tmp}/r"]))
    for override in ["optim.lr=.nan", "optim.lr=-1", "env.batch_size=100000000000", "agent.hidden=[1000000000]",
                     "env.max_steps=99999999999999999999", "agent.hidden=[]", "env.game=chess", "nosection.key=1",
                     "optim.momentum=0.9", "optim", "=3", "env.batch_size=big", "buffer.size=0", "loss.gamma=2",
                     "agent.hidden=[1,1,1,1,1,1,1,1,1,1,1,1,1,1,1,1,1,1]", "train.seed=-1", "collector.total_frames=1e400"]:
        add(("train: bad override", ["train", "{tiny.yaml}", override, "--out", "{tmp}/r"]))
    for opt, values in (("--seed", ["-1", "abc", "99999999999999999999"]), ("--episodes", ["0", "-5", "abc"])):
        for value in values:
            add((f"train: bad {opt}", ["train", "{tiny.yaml}", opt, value, "--out", "{tmp}/r"]))
    for out_path in ["{text.txt}", "{under_file}", "/proc/ncbot"]:
        add(("train: bad --out", ["train", "{tiny.yaml}", "--out", out_path]))
    add(("train: --resume bad folder", ["train", "--resume", "{missing}"]))
    add(("train: --resume without run", ["train", "--resume", "{a_folder}"]))
    add(("train: --resume and --overwrite", ["train", "--resume", "{a_folder}", "--overwrite"]))
    add(("train: no config", ["train"]))
    # checkpoints
    for bad in BAD_CHECKPOINTS:
        add(("eval: bad checkpoint", ["eval", f"{{{bad}}}", "--games", "1"]))
        add(("ladder: bad checkpoint", ["ladder", f"{{{bad}}}", "--games", "1", "--out", "{tmp}/l"]))
        add(("eval --exhaustive: bad checkpoint", ["eval", f"{{{bad}}}", "--exhaustive"]))
        add(("robot play: bad checkpoint", ["robot", "play", f"{{{bad}}}"]))
        add(("play: bad checkpoint", ["play", f"{{{bad}}}", "--no-log"]))
        add(("match: bad agent opponent", ["match", f"agent:{{{bad}}}", "random", "--games", "1"]))
    for value in BAD_NUMBERS:
        add(("eval: bad --games", ["eval", "{ckpt}", "--games", value]))
        add(("ladder: bad --games", ["ladder", "{ckpt}", "--games", value]))
        add(("match: bad --games", ["match", "random", "random", "--games", value]))
        add(("eval: bad --search", ["eval", "{ckpt}", "--games", "1", "--search", value]))
        add(("eval: bad --seed", ["eval", "{ckpt}", "--games", "1", "--seed", value]))
    for value in ["chess", "", "mcts:0", "mcts:-3", "agent:", "qmcts:x:y", "minimax:3"]:
        add(("eval: bad --opponent", ["eval", "{ckpt}", "--games", "1", "--opponent", value]))
        add(("match: bad opponent", ["match", value or " ", "random", "--games", "1"]))
    for value in [",", " , ", "chess", "random,,chess"]:
        add(("ladder: bad --opponents", ["ladder", "{ckpt}", "--games", "1", "--opponents", value, "--out", "{tmp}/l"]))
    for value in ["k9", "x", ""]:
        add(("ladder: bad --lookahead", ["ladder", "{ckpt}", "--games", "1", "--lookahead", value]))
    for option, value in (("--first", "nobody"), ("--first", "third"), ("--first", "")):
        add(("eval: bad seat", ["eval", "{ckpt}", "--games", "1", option, value]))
        add(("play: bad seat", ["play", option, value, "--no-log"]))
    for out_path in ["{text.txt}", "{under_file}"]:
        add(("eval: bad --out", ["eval", "{ckpt}", "--games", "1", "--out", out_path]))
        add(("ladder: bad --out", ["ladder", "{ckpt}", "--games", "1", "--out", out_path]))
        add(("play: bad --out", ["play", "--out", out_path]))
        add(("ablate: bad --out", ["ablate", "{grid.yaml}", "--out", out_path]))
    add(("play: bad --game", ["play", "--game", "chess", "--no-log"]))
    add(("play: bad --free-move", ["play", "--free-move", "nowhere", "--no-log"]))
    for option, value in (("--seeds", "0"), ("--workers", "0"), ("--backend", "spark"), ("--seeds", "abc")):
        add(("ablate: bad option", ["ablate", "{grid.yaml}", option, value, "--out", "{tmp}/r"]))
    # table
    for bad in ["missing", "a_folder", "text.txt", "runs"]:
        add(("table: bad runs folder", ["table", f"{{{bad}}}"]))
    for out_path in ["{a_folder}", "{under_file}.md", "{tmp}/x.txt"]:
        add(("table: bad --out", ["table", "{runs}", "--out", out_path]))
    # logs
    for command in (["inspect"], ["episodes"], ["show", "FILE", "0"], ["curve", "FILE", "-o", "{tmp}/c.png"],
                    ["to-rerun", "FILE", "-o", "{tmp}/x.rrd"]):
        for bad in ["missing", "a_folder", "binary.bin", "empty.yaml", "notmcap.mcap", "empty_folder"]:
            add((f"logs {command[0]}: bad log", ["logs", *[f"{{{bad}}}" if a == "FILE" else a for a in command]]
                 + ([f"{{{bad}}}"] if "FILE" not in command else [])))
    for out_path in ["{a_folder}", "{under_file}.png", "{tmp}/c.jpg"]:
        add(("logs curve: bad -o", ["logs", "curve", "{tmp}", "-o", out_path]))
        add(("logs to-rerun: bad -o", ["logs", "to-rerun", "{tmp}", "-o", out_path.replace(".png", ".rrd")]))
    add(("logs episodes: bad filter", ["logs", "episodes", "{tmp}", "--phase", "warmup"]))
    add(("logs to-rerun: bad --episodes", ["logs", "to-rerun", "{tmp}", "-o", "{tmp}/x.rrd", "--episodes", "a-b"]))
    # vision
    for bad in ["missing", "a_folder", "binary.bin", "text.txt", "empty.yaml"]:
        add(("vision read: bad image", ["vision", "read", f"{{{bad}}}"]))
        add(("vision classify: bad image", ["vision", "classify", f"{{{bad}}}"]))
    for bad in BAD_CHECKPOINTS:
        add(("vision: bad --weights", ["vision", "read", "{binary.bin}", "--weights", f"{{{bad}}}"]))
    for value in ["0", "-4", "100000", "abc"]:
        add(("vision read: bad --rho", ["vision", "read", "{binary.bin}", "--rho", value]))
    for value in ["4", "0", "abc"]:
        add(("vision read: bad --grid", ["vision", "read", "{binary.bin}", "--grid", value]))
        add(("vision generate: bad --grid", ["vision", "generate", "frames", "--out", "{tmp}/g", "--grid", value]))
    for args in (["generate", "pictures", "--out", "{tmp}/g"], ["generate", "cells", "--out", "{text.txt}"],
                 ["generate", "cells", "--out", "{under_file}"], ["generate", "cells", "--out", "{tmp}/g", "--n", "0"],
                 ["generate", "cells", "--out", "{tmp}/g", "--n", "100000000"],
                 ["generate", "cells", "--out", "{tmp}/g", "--style", "crayon"],
                 ["train", "--out", "{a_folder}"], ["train", "--out", "{tmp}/w.txt"], ["train", "--cells", "3"],
                 ["train", "--out", "{under_file}.pt"], ["eval", "--what", "magic"], ["eval", "--seed-set", "x"],
                 ["eval", "--out", "{text.txt}"], ["eval", "--frames", "0"]):
        add((f"vision {args[0]}: bad option", ["vision", *args]))
    # robot
    for args in (["render", "-o", "{a_folder}"], ["render", "-o", "{tmp}/x.xyz"], ["render", "-o", "{under_file}.png"],
                 ["render", "-o", "{tmp}/m.png", "--marks", "xb2,ob2"], ["render", "-o", "{tmp}/m.png", "--marks", "z9"],
                 ["render", "-o", "{tmp}/m.png", "--marks", "xj9"], ["render", "-o", "{tmp}/m.png", "--view", "side"],
                 ["render", "-o", "{tmp}/m.png", "--width", "100000"], ["render", "-o", "{tmp}/m.png", "--height", "0"],
                 ["render", "-o", "{tmp}/m.png", "--frames", "0"],
                 ["play", "--width", "100000", "--height", "100000"], ["play", "--games", "0"],
                 ["play", "--first", "nobody"], ["play", "--rrd"], ["play", "--meshes", "{empty_folder}"],
                 ["play", "--meshes", "{missing}"], ["play", "--robot-frame-period", "0"],
                 ["play", "--wait-probability", "2"], ["play", "--out", "{text.txt}"], ["play", "--game", "chess"],
                 ["urdf", "-o", "{a_folder}"], ["urdf", "-o", "{tmp}/p.txt"], ["urdf", "-o", "{under_file}.urdf"],
                 ["urdf", "-o", "{tmp}/p.urdf", "--meshes", "{empty_folder}"]):
        add((f"robot {args[0]}: bad option", ["robot", *args]))
    # env and root
    for args in (["env", "describe", "--game", "chess"], ["env", "nothing"], ["nothing"], ["train", "--bogus"],
                 ["eval"], ["version", "extra"]):
        add(("usage error", args))
    return out


def run_case(args: list[str], names: dict[str, str]) -> tuple[int | str, str]:
    for name, value in names.items():
        args = [arg.replace("{" + name + "}", value) for arg in args]
    out, err = io.StringIO(), io.StringIO()
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(90)
    code: int | str
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            main(args)
        code = 0
    except SystemExit as done:
        code = done.code if isinstance(done.code, int) else 1
    except Hang:
        code = "hang"
    finally:
        signal.alarm(0)
    return code, err.getvalue()


def main_sweep() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true", help="print the cases, run nothing")
    options = parser.parse_args()
    all_cases = cases()
    if options.list:
        for kind, args in all_cases:
            print(kind, "|", " ".join(args))
        print(f"{len(all_cases)} cases")
        return 0
    torch.set_num_threads(1)
    outcome: Counter = Counter()
    per_kind: dict[str, Counter] = {}
    failures = []
    with tempfile.TemporaryDirectory() as root:
        for number, (kind, args) in enumerate(all_cases):
            tmp = Path(root) / f"case{number:03d}"
            tmp.mkdir()
            names = fixtures(tmp)
            before = set(tmp.rglob("*"))
            code, err = run_case(args, names)
            lines = err.strip().splitlines()
            left = set(tmp.rglob("*")) - before
            one_line = code == 2 and len(lines) == 1 and lines[0].startswith("ncbot: error: ") and not left
            ok = one_line or code == 0
            verdict = "handled" if ok else ("hang" if code == "hang" else "traceback" if "Traceback" in err else "unclear")
            outcome[verdict] += 1
            per_kind.setdefault(kind, Counter())[verdict] += 1
            if not ok:
                failures.append((kind, args, code, err.strip()[-300:], sorted(str(p) for p in left)[:3]))
    for kind, counts in per_kind.items():
        print(f"{kind:40s} {sum(counts.values()):3d} cases  " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    for kind, args, code, err, left in failures:
        print(f"NOT HANDLED [{kind}] ncbot {' '.join(args)} -> {code}: {err} {left}")
    print(f"TOTAL {len(all_cases)} cases over {len({a[0] if a[0] not in ('logs', 'vision', 'robot', 'env') else ' '.join(a[:2]) for _, a in all_cases})} "
          f"commands: " + ", ".join(f"{k} {v}" for k, v in sorted(outcome.items())))
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main_sweep())
