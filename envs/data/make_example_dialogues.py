"""Write ``example_dialogues.yaml``: the dozen example dialogues per game the env learns its dialogue from.

The dialogue skeletons (who starts, how the user is asked to play, what the user says) are written out
below by hand; only the game moves inside them are sampled (seeded) by playing legal games with the exact
rules (robot: take a winning square if there is one, else random; user: random), keeping games whose result
matches the skeleton's feedback. Run ``python -m envs.data.make_example_dialogues`` to regenerate the file
(same seed -> same file).
"""
from __future__ import annotations

import random
from pathlib import Path

from envs.rules import Standard, Ultimate

OUT = Path(__file__).with_name("example_dialogues.yaml")

# (robot_first, pre-game opening, result) per dialogue; the same twelve skeletons for both games.
SKELETONS = [
    (True, "asked", "win"), (True, "asked", "win"), (True, "user_asks", "win"), (True, "declines_first", "draw"),
    (True, "asked", "lose"), (True, "user_asks", "draw"), (True, "asked", "win"), (True, "declines_first", "win"),
    (False, "asked", "win"), (False, "user_asks", "lose"), (False, "asked", "draw"), (False, "declines_first", "win"),
]
GREETINGS = ["hello", "hi", "hi pepper", "hello pepper nice to meet you"]
NAMES = ["my name is sam", "sam"]
USER_ASKS = ["can we play a game", "can we play"]
YES = ["yes", "yes please", "sure", "sure lets play"]
NO = ["no", "no thank you"]
MOVE_WORDS = ["your turn", "your turn pepper", "done", "this one"]
AFTER_ROBOT_WINS = ["well done", "well done pepper"]
AFTER_DRAW_MOVE = ["good game", "thank you"]
FEEDBACK_REPLIES = ["thank you", "good game", "well done pepper", "good game pepper"]
CLOSINGS = ["goodbye", "goodbye pepper", "thank you goodbye"]


def play_game(game, robot_first: bool, want: str, rng: random.Random) -> list[tuple[str, int]]:
    """A legal game (list of (who, cell)) whose result for the robot is ``want``."""
    robot_mark = 1 if robot_first else 2
    while True:
        s, moves = game.new(), []
        while game.outcome(s) is None:
            legal = game.legal(s)
            robot_turn = game.mark_to_move(s) == robot_mark
            if robot_turn:
                winning = [c for c in legal if game.outcome(game.play(s, c)) not in (None, "draw")]
                cell = rng.choice(winning or legal)
            else:
                cell = rng.choice(legal)
            moves.append(("robot" if robot_turn else "user", cell))
            s = game.play(s, cell)
        result = {None: None, "draw": "draw"}.get(game.outcome(s), "win" if game.outcome(s) == "xo"[robot_mark - 1] else "lose")
        if result == want:
            return moves


def turn(robot: str, user: str | None, says: str | None) -> str:
    user_text = "null" if user is None else user
    says_text = "null" if says is None else f'"{says}"'
    return f"      - {{robot: {robot}, user: {user_text}, says: {says_text}}}"


def dialogue_lines(game, name: str, index: int, robot_first: bool, opening: str, result: str, rng: random.Random) -> list[str]:
    pick = lambda options, k=0: options[(index + k) % len(options)]  # noqa: E731
    lines = [f"  - id: {name}-{index + 1:02d}", f"    game: {name}", f"    robot_first: {str(robot_first).lower()}", "    turns:"]
    lines.append(turn("Salutation(greeting)", "Salutation(greeting)", pick(GREETINGS)))
    if opening == "user_asks":
        lines.append(turn("Provide(name)", "Request(playGame)", pick(USER_ASKS)))
        lines.append(turn('"Reply(playGame=yes)"', '"Reply(playGame=yes)"', pick(YES, 1)))
    else:
        lines.append(turn("Provide(name)", "Provide(name)", pick(NAMES)))
        if opening == "declines_first":
            lines.append(turn("Request(playGame)", '"Reply(playGame=no)"', pick(NO)))
        lines.append(turn("Request(playGame)", '"Reply(playGame=yes)"', pick(YES)))
    moves = play_game(game, robot_first, result, rng)
    if not robot_first:
        who, cell = moves.pop(0)
        lines.append(turn("Request(userGameMove)", f'"GameMove(gridloc={cell})"', pick(MOVE_WORDS)))
    k = 0
    while moves:
        _, cell = moves.pop(0)
        if moves:
            _, reply = moves.pop(0)
            lines.append(turn(f'"GameMove(gridloc={cell})"', f'"GameMove(gridloc={reply})"', pick(MOVE_WORDS, k)))
        else:
            ending = AFTER_ROBOT_WINS if result == "win" else AFTER_DRAW_MOVE
            lines.append(turn(f'"GameMove(gridloc={cell})"', "Provide(feedback)", pick(ending, k)))
        k += 1
    feedback = {"win": "win", "lose": "loose", "draw": "draw"}[result]
    lines.append(turn(f'"Provide(feedback={feedback})"', "Provide(feedback)", pick(FEEDBACK_REPLIES)))
    lines.append(turn("Salutation(closing)", "Salutation(closing)", pick(CLOSINGS)))
    return lines


HEADER = """\
# Example dialogues of the robot (system) and the user, a dozen per game.
# Written by envs/data/make_example_dialogues.py (skeletons and utterances by hand, game moves sampled).
#
# Format: `dialogues` is a list; each dialogue has `id`, `game` (standard | ultimate), `robot_first`
# (who makes the first game move) and `turns`. A turn is one system act and the user's reply:
#   robot: the system dialogue act (one of the env's action names; GameMove(gridloc=CELL) with CELL the
#          row-major cell on the full grid)
#   user:  the user's dialogue act, or null for silence; GameMove(gridloc=CELL) when the user draws a move
#   says:  what the user says (lower case words; the env's vocabulary is derived from these and the
#          system templates), or null
# The env replays every dialogue with the exact rules (envs/rules.py) to check it and to train the
# Naive Bayes action filter and the simulated user.
dialogues:
"""


def main() -> None:
    rng = random.Random(2019)
    lines = [HEADER.rstrip("\n")]
    for name, game in (("standard", Standard()), ("ultimate", Ultimate("anywhere"))):
        for index, (robot_first, opening, result) in enumerate(SKELETONS):
            lines += dialogue_lines(game, name, index, robot_first, opening, result, rng)
    OUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
