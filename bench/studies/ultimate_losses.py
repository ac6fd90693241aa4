"""What the robot's Ultimate losses are: short tactics a k-ply look-ahead would have seen, or strategy.

Reads the lost eval games of an MCAP log (`ncbot eval CKPT --out DIR`), replays each game's moves with the exact
bitboard engine and, at the robot's last decisions, finds every move after which the user can FORCE a win within
k plies (k = 1, 3, 5; ``ncbot.modules.policies.deep_lookahead.losing_moves``). Each loss is classed by the robot's LAST decision
that still had a move escaping a 5-ply forced loss ("the last escape"):
- ``k3``: the chosen move lost by force within 3 plies (a fork) while another move did not;
- ``k5``: the chosen move lost by force within 5 plies while another move did not;
- ``strategic``: the chosen move was not lost within 5 plies; the random user's later replies found the win in a
  position that was bad beyond the horizon (e.g. the user holding two-in-a-row of subgrids more than once);
- ``none``: no robot decision in the game had an escape (lost from the look-ahead's view as early as it looks).
One-step masks rule out chosen moves lost within 1 ply, so that class is only a check.

    python bench/studies/ultimate_losses.py DIR [--last 6]
"""
from __future__ import annotations

import argparse
from collections import Counter

from ncbot.envs.games import make_game
from ncbot.logs.reader import read_episode_records, read_episodes
from ncbot.modules.policies.deep_lookahead import losing_moves

DEPTHS = (1, 3, 5)


def plies_of(record) -> list[tuple[str, int]]:
    """(who, cell) of every game move, in order: the robot's GameMove acts and the user's moves."""
    plies = []
    for turn in sorted(record.dialogue, key=lambda t: (int(t["step"]), t["speaker"] != "robot")):
        if turn["speaker"] == "robot" and int(turn["act"]) < 81:
            plies.append(("robot", int(turn["act"])))
        elif turn["speaker"] == "user" and int(turn.get("move", -1)) >= 0:
            plies.append(("user", int(turn["move"])))
    return plies


def classify(plies: list[tuple[str, int]], last: int, free_move: str = "anywhere") -> tuple[str, int]:
    """(class, plies from the last escape to the end of the game); see the module docstring."""
    engine = make_game("ultimate", free_move).search_engine()
    pos = engine.from_board([0] * 81, 1)
    decisions = []  # (pos before the robot's move, its move)
    for who, cell in plies:
        if who == "robot":
            decisions.append((pos, cell, len(decisions)))
        pos = engine.play(pos, cell)
    robot_plies = [i for i, (who, _) in enumerate(plies) if who == "robot"]
    for pos, chosen, index in reversed(decisions[-last:]):
        moves = engine.moves(pos)
        lost = {k: set(losing_moves(engine, pos, moves, k)) for k in DEPTHS}
        if len(lost[5]) == len(moves):
            continue  # no escape here: look one decision further back
        to_end = len(plies) - robot_plies[index]
        for k in DEPTHS:
            if chosen in lost[k]:
                return f"k{k}", to_end
        return "strategic", to_end
    return "none", -1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", help="MCAP file or folder of `ncbot eval --out`")
    parser.add_argument("--last", type=int, default=6, help="robot decisions looked at, from the end (k5 is slow)")
    args = parser.parse_args()
    lost = [e["episode"] for e in read_episodes(args.log) if e.get("outcome") == "loss" and e.get("phase") == "eval"]
    records = read_episode_records(args.log, lost)
    counts = Counter()
    for episode in lost:
        record = records[episode]
        kind, to_end = classify(plies_of(record), args.last)
        counts[kind] += 1
        print(f"episode {episode} seat {record.summary.get('seat')}: {kind} (last escape {to_end} plies before the end)")
    print("losses:", len(lost), dict(counts))


if __name__ == "__main__":
    main()
