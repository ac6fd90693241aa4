"""Write the example dialogues the env learns its dialogue from: two sets, a dozen dialogues per game each.

``example_dialogues.yaml`` (set ``compact``, the default): the user answers each robot move at once with its own.
``example_dialogues_paper.yaml`` (set ``paper``, env option ``dialogues="paper"``): the shape the paper's act table
implies: the opening in full (after the user agrees the robot says "Nice. Let me start."
(Reply(playGame=yes)) when it opens the game), and before each user move the robot says "your turn"
(Request(userGameMove)); the user watches the robot's own moves in silence.

The dialogue skeletons (who starts, how the user is asked to play, what the user says) are written out
below by hand; only the game moves inside them are sampled (seeded) by playing legal games with the exact
rules (robot: take a winning square if there is one, else random; user: random), keeping games whose result
matches the skeleton's feedback. Run ``python -m ncbot.envs.data.make_example_dialogues`` to regenerate both files
(same seeds -> same files; each set has its own random stream, so adding one never changed the other).

``example_dialogues_paper_extra.yaml`` (ours, authored): dialogues 13-24 per game in the paper's shape, so the
data-budget curve can be measured at k = 24; env.dialogues=paper alone never reads it (docs/reproduction.md).
"""
from __future__ import annotations

import random
from pathlib import Path

from ncbot.envs.rules import Standard, Ultimate

OUT = Path(__file__).with_name("example_dialogues.yaml")
OUT_PAPER = Path(__file__).with_name("example_dialogues_paper.yaml")
OUT_PAPER_EXTRA = Path(__file__).with_name("example_dialogues_paper_extra.yaml")

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
# The paper-style set: who opens and how the user is asked (a user who opens is asked, never asks: the robot's
# "Nice. Let me start." answers a user's request); what the user says when it has drawn its move.
PAPER_SKELETONS = [
    (True, "asked", "win"), (True, "asked", "win"), (True, "user_asks", "win"), (True, "declines_first", "draw"),
    (True, "asked", "lose"), (True, "user_asks", "draw"), (True, "asked", "win"), (True, "declines_first", "win"),
    (False, "asked", "win"), (False, "declines_first", "lose"), (False, "asked", "draw"), (False, "asked", "win"),
]
# Own word lists, chosen so the set's vocabulary (its templates' words and its users' words) has the paper's 39 words.
PAPER_GREETINGS = ["hello", "hello pepper", "hello nice to meet you", "hello pepper nice to meet you"]
PAPER_USER_ASKS = ["lets play a game", "lets play"]
PAPER_MOVE_WORDS = ["done", "this one", "my move is done", "done pepper"]


# The authored second dozen of the paper set (ours, dialogues 13-24 per game, file example_dialogues_paper_extra.yaml):
# the same acts, robot lines and 39 words, new sequences; used only when a data-budget subset asks for k > 12.
# (robot_first, opening, result, user's first move, after the feedback) per dialogue.
EXTRA_SKELETONS = [
    (True, "declines_twice", "win", "at_once", "replies"), (True, "silent_greeting", "draw", "slow", "replies"),
    (False, "name_twice", "win", "slow", "replies"), (True, "asks_first", "win", "at_once", "silent"),
    (False, "misheard_play", "draw", "at_once", "replies"), (True, "misheard_name", "lose", "at_once", "replies"),
    (False, "declines_twice", "lose", "slow", "silent"), (True, "no_name", "win", "at_once", "replies"),
    (False, "silent_greeting", "win", "at_once", "replies"), (True, "name_twice", "draw", "slow", "replies"),
    (False, "no_name", "draw", "at_once", "silent"), (True, "misheard_play", "win", "at_once", "replies"),
]
EXTRA_GREETINGS = ["hello", "nice to meet you pepper", "hello pepper", "hello nice to meet you"]
EXTRA_NAMES = ["sam", "my name is sam", "name is sam"]
EXTRA_YES = ["yes lets play", "sure", "yes please", "sure lets play a game", "yes"]
EXTRA_NO = ["no", "no thank you", "no no"]
EXTRA_MOVE_WORDS = ["done", "your turn pepper", "this one", "my move is done", "done your turn"]
EXTRA_USER_WON = ["i won", "good game pepper"]
EXTRA_FEEDBACK_REPLIES = ["good game", "thank you pepper", "well done", "it is a draw"]
EXTRA_CLOSINGS = ["goodbye", "thank you goodbye", "goodbye pepper nice to meet you"]


def play_game(game, robot_first: bool, want: str, rng: random.Random) -> list[tuple[str, int]]:
    """A legal game (list of (who, cell)) whose result for the robot is ``want``."""
    while True:
        moves, result = play_once(game, robot_first, rng)
        if result == want:
            return moves


def play_once(game, robot_first: bool, rng: random.Random) -> tuple[list[tuple[str, int]], str]:
    """One legal game (robot: a winning square if it has one, else random; user: random) and its result for the
    robot ("win", "lose" or "draw")."""
    robot_mark = 1 if robot_first else 2
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
    return moves, {"draw": "draw"}.get(game.outcome(s), "win" if game.outcome(s) == "xo"[robot_mark - 1] else "lose")


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


def paper_dialogue_lines(game, name: str, index: int, robot_first: bool, opening: str, result: str,
                         rng: random.Random) -> list[str]:
    """One dialogue in the paper's shape: "your turn" before each user move, the user silent during the robot's."""
    pick = lambda options, k=0: options[(index + k) % len(options)]  # noqa: E731
    lines = [f"  - id: {name}-paper-{index + 1:02d}", f"    game: {name}", f"    robot_first: {str(robot_first).lower()}",
             "    turns:"]
    lines.append(turn("Salutation(greeting)", "Salutation(greeting)", pick(PAPER_GREETINGS)))
    if opening == "user_asks":
        lines.append(turn("Provide(name)", "Request(playGame)", pick(PAPER_USER_ASKS)))
        lines.append(turn('"Reply(playGame=yes)"', None, None))  # "Nice. Let me start."
    else:
        lines.append(turn("Provide(name)", "Provide(name)", pick(NAMES)))
        if opening == "declines_first":
            lines.append(turn("Request(playGame)", '"Reply(playGame=no)"', pick(NO)))
        lines.append(turn("Request(playGame)", '"Reply(playGame=yes)"', pick(YES)))
        if robot_first:
            lines.append(turn('"Reply(playGame=yes)"', None, None))
    lines += paper_move_turns(game, robot_first, result, rng, pick, PAPER_MOVE_WORDS)
    feedback = {"win": "win", "lose": "loose", "draw": "draw"}[result]
    lines.append(turn(f'"Provide(feedback={feedback})"', "Provide(feedback)", pick(FEEDBACK_REPLIES)))
    lines.append(turn("Salutation(closing)", "Salutation(closing)", pick(CLOSINGS)))
    return lines


def paper_move_turns(game, robot_first: bool, result: str, rng: random.Random, pick, move_words: list[str],
                     slow: bool = False) -> list[str]:
    """The game part of a paper-shaped dialogue: "your turn" before every user move, the user silent while the robot
    draws and speaking on the robot's last move; ``slow``: the first "your turn" gets no move and is asked again."""
    lines = []
    moves = play_game(game, robot_first, result, rng)
    for k, (who, cell) in enumerate(moves):
        last = k == len(moves) - 1
        if who == "robot":
            ending = AFTER_ROBOT_WINS if result == "win" else AFTER_DRAW_MOVE
            user, says = ("Provide(feedback)", pick(ending, k)) if last else (None, None)
            lines.append(turn(f'"GameMove(gridloc={cell})"', user, says))
        else:
            if slow:
                lines.append(turn("Request(userGameMove)", None, None))
                slow = False
            lines.append(turn("Request(userGameMove)", f'"GameMove(gridloc={cell})"', pick(move_words, k)))
    return lines


def extra_dialogue_lines(game, name: str, index: int, robot_first: bool, opening: str, result: str, first_move: str,
                         after: str, rng: random.Random) -> list[str]:
    """One authored dialogue of the paper's shape (number 13 + index) with one of the openings and turns the first
    dozen never shows: refusals, silence, the name asked twice, misheard questions, no name, the user asking first."""
    pick = lambda options, k=0: options[(index + k) % len(options)]  # noqa: E731
    lines = [f"  - id: {name}-paper-{index + 13:02d}", f"    game: {name}", f"    robot_first: {str(robot_first).lower()}",
             "    turns:"]
    if opening == "silent_greeting":  # the user does not answer the first greeting
        lines.append(turn("Salutation(greeting)", None, None))
    lines.append(turn("Salutation(greeting)", "Salutation(greeting)", pick(EXTRA_GREETINGS)))
    if opening == "asks_first":  # the user asks to play before the robot gives its name; the robot opens
        lines.append(turn("Provide(name)", "Request(playGame)", "lets play a game"))
        lines.append(turn('"Reply(playGame=yes)"', None, None))
    else:
        if opening == "name_twice":  # no answer to the name question: asked again
            lines.append(turn("Provide(name)", None, None))
        if opening == "misheard_name":  # the user hears a greeting, not the question, and greets back
            lines.append(turn("Provide(name)", "Salutation(greeting)", "hello pepper"))
        if opening != "no_name":
            lines.append(turn("Provide(name)", "Provide(name)", pick(EXTRA_NAMES)))
        if opening == "declines_twice":
            lines.append(turn("Request(playGame)", '"Reply(playGame=no)"', pick(EXTRA_NO)))
            lines.append(turn("Request(playGame)", '"Reply(playGame=no)"', pick(EXTRA_NO, 1)))
        if opening == "misheard_play":  # the user answers the play question with its name again
            lines.append(turn("Request(playGame)", "Provide(name)", pick(EXTRA_NAMES, 1)))
        lines.append(turn("Request(playGame)", '"Reply(playGame=yes)"', pick(EXTRA_YES)))
        if robot_first:
            lines.append(turn('"Reply(playGame=yes)"', None, None))
    # slow: the user has not drawn yet at the first "your turn": asked again
    lines += paper_move_turns(game, robot_first, result, rng, pick, EXTRA_MOVE_WORDS, slow=first_move == "slow")
    feedback = {"win": "win", "lose": "loose", "draw": "draw"}[result]
    if after == "silent":
        lines.append(turn(f'"Provide(feedback={feedback})"', None, None))
    else:
        replies = EXTRA_USER_WON if result == "lose" else EXTRA_FEEDBACK_REPLIES
        says = "it is a draw" if result == "draw" else pick([r for r in replies if r != "it is a draw"])
        lines.append(turn(f'"Provide(feedback={feedback})"', "Provide(feedback)", says))
    lines.append(turn("Salutation(closing)", "Salutation(closing)", pick(EXTRA_CLOSINGS)))
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


PAPER_HEADER = HEADER.replace(
    "# Example dialogues of the robot (system) and the user, a dozen per game.\n",
    "# Example dialogues in the paper's shape (env option dialogues=paper), a dozen per game: the robot says\n"
    "# \"your turn\" (Request(userGameMove)) before each user move and \"Nice. Let me start.\" (Reply(playGame=yes))\n"
    "# when the user agrees and the robot opens; the user is silent (null) while the robot draws.\n",
)


EXTRA_HEADER = PAPER_HEADER.replace(
    "# Example dialogues in the paper's shape (env option dialogues=paper), a dozen per game: the robot says\n",
    "# OURS (authored, not the paper's): dialogues 13-24 per game of the paper-shaped set, read only when a data-budget\n"
    "# subset asks for more than a dozen (env.dialogue_subset.k > 12); env.dialogues=paper alone uses the first\n"
    "# dozen (example_dialogues_paper.yaml). Same acts, robot lines and 39 words; new sequences: refusals, silence,\n"
    "# the name asked twice, misheard questions, no name, the user asking first, a slow first move.\n"
    "# Example dialogues in the paper's shape (env option dialogues=paper): the robot says\n",
)


def write_set(out: Path, header: str, skeletons: list, make_lines, seed: int) -> None:
    """One dialogue file: both games, the given skeletons, game moves from its own seeded stream."""
    rng = random.Random(seed)
    lines = [header.rstrip("\n")]
    for name, game in (("standard", Standard()), ("ultimate", Ultimate("anywhere"))):
        for index, skeleton in enumerate(skeletons):
            lines += make_lines(game, name, index, *skeleton, rng)
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")


# The sets by the file the built-in games read them from: header, skeletons, dialogue writer, seed.
SETS = {
    OUT.name: (HEADER, SKELETONS, dialogue_lines, 2019),
    OUT_PAPER.name: (PAPER_HEADER, PAPER_SKELETONS, paper_dialogue_lines, 2020),
    OUT_PAPER_EXTRA.name: (EXTRA_HEADER, EXTRA_SKELETONS, extra_dialogue_lines, 2021),
}
RESULT_SAMPLE, RESULT_SHARE = 100, 0.05  # games per seat, and the share of them a result needs to be written


def reachable_results(game, rng: random.Random) -> set[str]:
    """The results ("win", "lose", "draw") that at least RESULT_SHARE of ``play_once``'s games reach on ``game``
    (RESULT_SAMPLE per seat). Why: a rarer result would make ``play_game`` search for long (random Connect Four
    games almost never draw, a 9x9 board with k 3 never does); such a result is left out of the examples."""
    results = [play_once(game, robot_first, rng)[1] for _ in range(RESULT_SAMPLE) for robot_first in (True, False)]
    return {r for r in set(results) if results.count(r) >= RESULT_SHARE * len(results)}


def declared_dialogue_text(game, file_name: str) -> str:
    """The example dialogues of a declared game (``ncbot.envs.rules.Declared``) for the set read from ``file_name``:
    the same skeletons, utterances and writers as the built-in games', moves sampled with the declared rules, as
    the YAML text a dialogue file holds. A skeleton whose result the game does not reach gets the first reachable of
    win, lose, draw. Same declaration and set -> same text."""
    header, skeletons, make_lines, seed = SETS[file_name]
    rng = random.Random(seed)
    reachable = reachable_results(game, rng)
    lines = [header.rstrip("\n")]
    for index, (robot_first, opening, result, *rest) in enumerate(skeletons):
        result = result if result in reachable else next(r for r in ("win", "lose", "draw") if r in reachable)
        lines += make_lines(game, game.name, index, robot_first, opening, result, *rest, rng)
    return "\n".join(lines) + "\n"


def main() -> None:
    write_set(OUT, HEADER, SKELETONS, dialogue_lines, 2019)
    write_set(OUT_PAPER, PAPER_HEADER, PAPER_SKELETONS, paper_dialogue_lines, 2020)
    write_set(OUT_PAPER_EXTRA, EXTRA_HEADER, EXTRA_SKELETONS, extra_dialogue_lines, 2021)


if __name__ == "__main__":
    main()
