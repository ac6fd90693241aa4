"""The robot asks where the person drew, after its camera missed a move, and hears the answer (real speech).

What happens (docs/speech.md, "Where did you draw?"): the robot asks; the person says the cell's phrase
(speech.cell_answers) in the game's voice over the game's noise; the robot decodes it with the answers'
recogniser. A phrase naming a cell that is free on the robot's board is confirmed ("Did you say top left?"):
the person answers "yes, that is right" when it is the cell they drew in, "no, that is wrong" otherwise, and a
heard yes settles the move.
Anything else (nothing heard, no phrase, a taken cell, a confirmation not heard as "yes") makes the robot ask
again, at most `MAX_ASKS` questions in all; then the robot gives up asking (the caller looks again).

A cell settled by a "yes" the person did not say (their no heard as yes) is a misheard cell: the robot's
board then holds the person's mark in the wrong cell.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ncbot.speech.cell_answers import CONFIRM_NO, CONFIRM_YES, AnswerEars, cell_phrase

ASK_WHERE = "I could not see your move, where did you draw?"  # also text mode's question (the answer: the dialogue)
ASK_AGAIN = "Sorry, I did not get that. Where did you draw?"
CONFIRM = "Did you say {}?"
LOOK_AGAIN = "Let me look again."
#: Questions "where did you draw?" per unseen move (the first and two more), each with at most one confirmation.
MAX_ASKS = 3


def ask_where(true_cell: int, legal: np.ndarray, ears: AnswerEars, say: Callable[[str], None],
              heard: Callable[[object, str], None], max_asks: int = MAX_ASKS) -> int | None:
    """The cell the robot settles on from the person's spoken answers, or None if the questions settled nothing.

    `legal` marks the cells free on the robot's board; `say(text)` speaks a robot question; `heard(utterance,
    question)` logs each of the person's answers (a `ncbot.speech.hearing.HeardUtterance`)."""
    grid = ears.grid
    for ask in range(max_asks):
        question = ASK_WHERE if ask == 0 else ASK_AGAIN
        say(question)
        answer = ears.hear_cell(cell_phrase(true_cell, grid))
        heard(answer, question)
        cell = answer.understood
        if cell < 0 or not legal[cell]:
            continue
        question = CONFIRM.format(cell_phrase(cell, grid))
        say(question)
        reply = ears.hear_confirm(CONFIRM_YES if cell == true_cell else CONFIRM_NO)
        heard(reply, question)
        if reply.understood == 1:
            return cell
    return None
