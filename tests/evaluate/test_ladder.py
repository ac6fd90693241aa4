"""`ncbot ladder`: a real checkpoint plays real env games against the opponents; table, JSON and PNG read back."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest
import torch

from ncbot.pipelines.evaluate.ladder import check_goals, run_ladder


def _checkpoint(tmp_path, game: str = "standard"):
    """A checkpoint in the format ncbot train writes (an untrained Q-network: the look-ahead masks still apply)."""
    from ncbot.envs import make_env
    from ncbot.modules.networks.qnet import make_qnet
    from ncbot.pipelines.checkpoint import FORMAT, atomic_save
    from ncbot.pipelines.config import RunConfig

    config = RunConfig()
    config.env.game = game
    env = make_env(game, batch_size=(1,))
    torch.manual_seed(0)
    qnet = make_qnet(env.n_features, env.n_actions, config.agent.hidden)
    path = tmp_path / "run" / "checkpoint.pt"
    atomic_save({"format": FORMAT, "config": config.to_dict(), "n_features": env.n_features,
                 "n_actions": env.n_actions, "qnet": qnet.state_dict()}, path)
    return path


def test_ladder_writes_table_json_and_png(tmp_path) -> None:
    checkpoint = _checkpoint(tmp_path)
    result = run_ladder(str(checkpoint), games=12, opponents=["random", "minimax"], seed=1, progress=False)
    rows = result["rows"]
    assert [(r["opponent"], r["seat"]) for r in rows] == [("random", "first"), ("random", "second"),
                                                          ("minimax", "first"), ("minimax", "second")]
    for r in rows:
        assert r["games"] == 12 and abs(r["win"] + r["draw"] + r["loss"] - 1.0) < 1e-9
        assert r["score"] == pytest.approx(r["win"] + 0.5 * r["draw"])
    # nobody beats perfect play (an untrained agent may still lose to it by a fork)
    assert all(r["win"] == 0 for r in rows if r["opponent"] == "minimax")
    files = result["files"]
    markdown = open(files["markdown"]).read()
    assert "| minimax | second | 12 |" in markdown and "Goals (a score goal is decided" in markdown
    saved = json.loads(open(files["json"]).read())
    assert saved["rows"] == json.loads(json.dumps(rows)) and saved["game"] == "standard"
    import matplotlib.image

    image = matplotlib.image.imread(files["png"])
    assert image.shape[0] > 100 and image.shape[1] > 100
    assert files["png"].startswith(str(checkpoint.parent))  # default: beside the checkpoint


def test_same_seed_same_ladder(tmp_path) -> None:
    checkpoint = _checkpoint(tmp_path)
    first = run_ladder(str(checkpoint), games=8, opponents=["rule"], seed=4, out_dir=str(tmp_path / "a"), progress=False)
    again = run_ladder(str(checkpoint), games=8, opponents=["rule"], seed=4, out_dir=str(tmp_path / "b"), progress=False)
    assert first["rows"] == again["rows"]


def test_workers_play_the_same_rows(tmp_path) -> None:
    """`--workers 2` plays the matches in two processes and gets the rows of one process, search and baseline
    included (each match re-seeds the robot's own chance), in the same order; a match does not depend on which
    matches ran before it: the same match seeds alone (rule's matches are the third and fourth, seeds 3 + 2000
    and 3 + 3000) give the same rows."""
    checkpoint = _checkpoint(tmp_path)
    kwargs = dict(games=4, opponents=["random", "rule"], seed=3, search=4, baseline=True, progress=False)
    one = run_ladder(str(checkpoint), out_dir=str(tmp_path / "one"), **kwargs)
    two = run_ladder(str(checkpoint), out_dir=str(tmp_path / "two"), workers=2, **kwargs)
    strip = lambda rows: [{k: v for k, v in r.items() if k != "search_cpu_s_per_decision"} for r in rows]  # noqa: E731
    assert strip(one["rows"]) == strip(two["rows"]) and len(one["rows"]) == 8
    assert {r["policy"] for r in one["rows"]} == {"agent", "look-ahead only"}
    alone = run_ladder(str(checkpoint), out_dir=str(tmp_path / "alone"), **{**kwargs, "opponents": ["rule"], "seed": 2003})
    assert strip(alone["rows"]) == strip(one["rows"][4:])


def test_ultimate_ladder_against_mcts(tmp_path) -> None:
    checkpoint = _checkpoint(tmp_path, "ultimate")
    result = run_ladder(str(checkpoint), games=2, opponents=["mcts:5"], seed=0, out_dir=str(tmp_path / "u"),
                        progress=False)
    assert [r["seat"] for r in result["rows"]] == ["first", "second"]
    with pytest.raises(ValueError, match="minimax.*solve exactly"):
        run_ladder(str(checkpoint), games=2, opponents=["minimax"], progress=False, out_dir=str(tmp_path / "x"))


def test_goals_follow_the_targets() -> None:
    rows = [{"opponent": "minimax", "seat": s, "games": 10, "win": 0.0, "draw": d, "loss": 1 - d, "score": d / 2}
            for s, d in (("first", 1.0), ("second", 0.9))]
    (goal,) = [g for g in check_goals("standard", rows) if "minimax" in g["goal"]]
    assert not goal["met"] and goal["value"] == "1 losses"
    rows = [{"opponent": "mcts:100", "seat": s, "games": 10, "win": w, "draw": 0.0, "loss": 1 - w, "score": w}
            for s, w in (("first", 0.7), ("second", 0.4))]
    (goal,) = check_goals("ultimate", rows)
    assert goal["goal"] == "score >= 0.5 against mcts:100" and goal["met"]
    assert goal["value"] == "0.550 [0.342, 0.742] over 20 games" and goal["verdict"] == "undecided"  # 20 games do not decide it
    rows = [{"opponent": "mcts:1000", "seat": s, "games": 100, "win": w, "draw": 0.1, "loss": 0.9 - w, "score": w + 0.05,
             "search_cpu_s_per_decision": t} for s, w, t in (("first", 0.9, 0.12), ("second", 0.8, 0.25))]
    score, budget = check_goals("ultimate", rows)
    assert score["verdict"] == "met" and score["value"].startswith("0.900 [0.851, 0.934]")  # the lower bound clears 0.75
    assert budget["verdict"] == "missed" and budget["value"] == "0.250 s in the slowest match"
    rows[1]["score"] = 0.6
    assert check_goals("ultimate", rows)[0]["verdict"] == "undecided"
    for row in rows:
        row["score"] = 0.6
    assert check_goals("ultimate", rows)[0]["verdict"] == "missed"


def test_a_stopped_ladder_stops_its_workers(tmp_path) -> None:
    """SIGTERM while `--workers 2` play: exit 143 with the one line, and both worker processes are gone at once
    (they do not finish their matches first)."""
    import os
    import signal
    import time

    checkpoint = _checkpoint(tmp_path)
    ladder = subprocess.Popen([sys.executable, "-m", "ncbot", "ladder", str(checkpoint), "--opponents",
                               "random", "--games", "100000", "--workers", "2", "--out", str(tmp_path / "l")],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def children() -> list[int]:
        found = []
        for entry in os.listdir("/proc"):
            try:
                fields = open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()
            except (OSError, IndexError):
                continue
            if entry.isdigit() and int(fields[1]) == ladder.pid and fields[0] != "Z":
                found.append(int(entry))
        return found

    deadline = time.monotonic() + 120
    while len(children()) < 2 and time.monotonic() < deadline:  # the pool's workers (and its resource tracker)
        time.sleep(0.5)
    workers = children()
    assert len(workers) >= 2, "the ladder did not start its workers"
    time.sleep(5)  # let the workers load the robot and start playing
    ladder.send_signal(signal.SIGTERM)
    _, stderr = ladder.communicate(timeout=60)
    assert ladder.returncode == 143, stderr
    assert "terminated (SIGTERM)" in stderr and "Traceback" not in stderr
    def alive(pid: int) -> bool:
        try:
            return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    deadline = time.monotonic() + 10  # the pool's resource tracker leaves when it reads its pipe's end
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [pid for pid in workers if alive(pid)]


def test_cli_errors_are_one_line(tmp_path) -> None:
    checkpoint = _checkpoint(tmp_path)
    for args, message in (([str(tmp_path / "missing.pt")], "not found"),
                          ([str(checkpoint), "--opponents", "chess"], "unknown opponent 'chess'"),
                          ([str(checkpoint), "--games", "0"], "--games must be a positive"),
                          ([str(checkpoint), "--workers", "0"], "--workers must be a positive")):
        done = subprocess.run([sys.executable, "-m", "ncbot", "ladder", *args], capture_output=True, text=True)
        assert done.returncode == 2, done.stderr
        assert message in done.stderr and "Traceback" not in done.stderr


def test_agent_checkpoint_as_an_opponent(tmp_path) -> None:
    """``agent:CHECKPOINT``: legal cells, the look-ahead takes wins and blocks, and the env accepts it by name."""
    from ncbot.envs import make_env
    from ncbot.envs.opponents import make_opponent
    from ncbot.pipelines.agents import register_agent_opponent

    checkpoint = _checkpoint(tmp_path)
    register_agent_opponent()
    agent = make_opponent(f"agent:{checkpoint}", game="standard", seed=0)
    boards = torch.tensor([[1, 1, 0, 2, 2, 0, 0, 0, 0],    # player 2 to move... wins at c2 (cell 5)
                           [1, 1, 0, 2, 0, 0, 2, 0, 0]],   # player 2 must block a1 b1 at c1 (cell 2)
                          dtype=torch.int8)
    legal = boards == 0
    cells = agent.select(boards, torch.tensor([1, 1]), legal, 2, torch.Generator().manual_seed(0))
    assert cells.tolist() == [5, 2]
    env = make_env("standard", batch_size=(4,), opponent=f"agent:{checkpoint}", first="human", seed=0)
    td = env.reset()
    for _ in range(12):
        td = env.step(env.rand_action(td))["next"]
    with pytest.raises(ValueError, match="needs a checkpoint path"):
        make_opponent("agent", game="standard")
    with pytest.raises(ValueError, match="plays standard, not ultimate"):
        make_opponent(f"agent:{checkpoint}", game="ultimate")
    result = run_ladder(str(checkpoint), games=4, opponents=[f"agent:{checkpoint}"], out_dir=str(tmp_path / "self"),
                        progress=False)
    assert len(result["rows"]) == 2


def test_baseline_rows_play_the_masks_alone(tmp_path) -> None:
    checkpoint = _checkpoint(tmp_path)
    result = run_ladder(str(checkpoint), games=10, opponents=["minimax"], seed=2, out_dir=str(tmp_path / "base"),
                        progress=False, baseline=True)
    assert [(r["policy"], r["seat"]) for r in result["rows"]] == [
        ("agent", "first"), ("look-ahead only", "first"), ("agent", "second"), ("look-ahead only", "second")]
    assert "| look-ahead only | minimax | second | 10 |" in result["markdown"]
    assert len(result["goals"]) == 1  # goals judge the agent's rows only


def test_match_command_plays_two_opponents() -> None:
    done = subprocess.run([sys.executable, "-m", "ncbot", "match", "random", "minimax", "--games", "30",
                           "--seed", "2"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    row = [line for line in done.stdout.splitlines() if line.startswith("| random | minimax |")][0]
    cells = [c.strip() for c in row.strip("|").split("|")]
    first_wins, draws, second_wins = int(cells[3]), int(cells[4]), int(cells[5])
    assert first_wins == 0 and draws + second_wins == 30  # nobody beats minimax


def test_lookahead_option_replaces_the_masks(tmp_path) -> None:
    """`--lookahead k5`: the same (untrained) Q-network behind deeper masks loses less to minimax, and the table
    says which masks played; a name for the other Ultimate variant is mapped, a bad name is one line."""
    from ncbot.pipelines.agents import resolve_lookahead

    checkpoint = _checkpoint(tmp_path)
    losses = {}
    for rule in ("none", "k5"):
        result = run_ladder(str(checkpoint), games=20, opponents=["minimax"], seed=3, lookahead=rule,
                            out_dir=str(tmp_path / rule), progress=False)
        assert f"Robot decides by: greedy Q, masks {rule}." in result["markdown"]
        assert json.loads(open(result["files"]["json"]).read())["lookahead"] == rule
        losses[rule] = sum(r["loss"] for r in result["rows"])
    assert losses["k5"] < losses["none"]
    assert resolve_lookahead("k3", "open_subgrids") == "k3_open" and resolve_lookahead("k3", "anywhere") == "k3"
    with pytest.raises(ValueError, match="--lookahead must be one of"):
        resolve_lookahead("k9", "anywhere")
    done = subprocess.run([sys.executable, "-m", "ncbot", "ladder", str(checkpoint), "--lookahead", "deep"],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "--lookahead must be one of" in done.stderr and "Traceback" not in done.stderr


def test_search_option_prunes_forced_losses_at_the_root(tmp_path) -> None:
    """`--search N --lookahead k5`: the Q-guided search never plays a move the k-step rule proves lost while
    another move survives (a 3-simulation search alone would, often), in real dialogues of the env."""
    from ncbot.envs import make_env
    from ncbot.pipelines.agents import load_robot

    checkpoint = _checkpoint(tmp_path)
    config, policy, robot = load_robot(str(checkpoint), search=3, lookahead="k5", seed=0)
    assert robot == "Q-guided MCTS 3 sims, masks k5" and policy.prune is not None
    env = make_env("standard", batch_size=(16,), seed=0, first="alternate")
    td, pruned = env.reset(), 0
    for _ in range(60):
        td = policy(td)
        moves = td.get("action_mask")[:, :9]
        survivors = moves & ~policy.prune.forced_losses(td, td.get("action_mask"))[:, :9]
        action = td.get("action")
        for row in (survivors.any(-1) & (survivors != moves).any(-1)).nonzero().flatten().tolist():
            pruned += 1
            assert int(action[row]) >= 9 or bool(survivors[row, int(action[row])])
        _, td = env.step_and_maybe_reset(td)
    assert pruned >= 10  # the check above really met positions with moves lost by force
    result = run_ladder(str(checkpoint), games=4, opponents=["rule"], seed=0, search=3, out_dir=str(tmp_path / "s"),
                        progress=False)
    assert "Robot decides by: Q-guided MCTS 3 sims, masks one_step." in result["markdown"]
    summary = json.loads(open(result["files"]["json"]).read())
    assert summary["search"] == 3
    for row in summary["rows"]:  # each match's own searched moves (not a running total) and their CPU per move
        assert 4 <= row["search_decisions"] <= 4 * 5 and 0 < row["search_cpu_s_per_decision"] < 1
    assert summary["goals"][-1]["goal"] == "<= 0.2 CPU s per searched move (one core)"
