"""The robot asks where the person drew, after its camera missed a move, and settles the cell from the answers
(real speech), or from a touch on the tablet on its chest.

Two ways to settle (docs/speech.md, "Where did you draw?"):
- by confidence (`AnswerThresholds`, the default): the person says the cell's phrase; a free cell heard at least
  `accept` sure is taken; at least `confirm` sure it is confirmed ("top left, is that right?") and a "yes" heard at
  least `yes` sure settles it; anything else (nothing, no phrase, a taken cell, a doubt, a "no", an unsure
  "yes") makes the robot ask again, up to `asks` questions, and then ask the person to touch the cell on its
  tablet, which settles it.
- always confirm (``thresholds=None``): every free cell heard is confirmed, a heard "yes" settles it; anything
  else asks again, at most `MAX_ASKS` questions; then the robot gives up asking (the caller looks again).

A cell settled by a "yes" the person did not say (their no heard as yes), or accepted as heard when it was another
cell, is a misheard cell: the robot's board then holds the person's mark in the wrong cell.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ncbot.speech.answer_policy import AnswerThresholds, phrase_confidence
from ncbot.speech.cell_answers import CONFIRM_NO, CONFIRM_YES, AnswerEars, cell_phrase

ASK_WHERE = "I could not see your move, where did you draw?"  # also text mode's question (the answer: the dialogue)
ASK_AGAIN = "Sorry, I did not get that. Where did you draw?"
CONFIRM = "{}, is that right?"
ASK_TABLET = "Please touch the cell you drew in on my tablet."
LOOK_AGAIN = "Let me look again."
#: Questions "where did you draw?" per unseen move when every cell is confirmed, each with at most one confirmation.
MAX_ASKS = 3
HOW = ("accepted", "confirmed", "tablet")


@dataclass(frozen=True)
class Settled:
    """The cell the robot settled on (None: nothing settled), how (accepted | confirmed | tablet | None), and the
    questions it took: "where did you draw?" asked (`asks`) and confirmations asked."""

    cell: int | None
    how: str | None
    asks: int
    confirmations: int


def ask_where(true_cell: int, legal: np.ndarray, ears: AnswerEars, say: Callable[[str], None],
              heard: Callable[[object, str], None], thresholds: AnswerThresholds | None = None,
              tablet: Callable[[np.ndarray], int] | None = None, max_asks: int = MAX_ASKS) -> Settled:
    """Settle the person's unseen move from their spoken answers (and, by confidence, the tablet).

    `legal` marks the cells free on the robot's board; `say(text)` speaks a robot question; `heard(utterance,
    question)` logs each of the person's answers (a `ncbot.speech.hearing.HeardUtterance`); `tablet(legal)` is the
    cell the person touches (by confidence only; required then)."""
    if thresholds is not None and tablet is None:
        raise ValueError("settling by confidence needs the tablet (the person's touch) as the last resort")
    grid, confirmations = ears.grid, 0
    asks = max_asks if thresholds is None else thresholds.asks
    for ask in range(asks):
        question = ASK_WHERE if ask == 0 else ASK_AGAIN
        say(question)
        answer = ears.hear_cell(cell_phrase(true_cell, grid))
        heard(answer, question)
        cell, sure = answer.understood, phrase_confidence(answer.heard.confidences)
        if cell < 0 or not legal[cell] or (thresholds is not None and sure < thresholds.confirm):
            continue
        if thresholds is not None and sure >= thresholds.accept:
            return Settled(cell, "accepted", ask + 1, confirmations)
        question = CONFIRM.format(cell_phrase(cell, grid))
        say(question)
        confirmations += 1
        reply = ears.hear_confirm(CONFIRM_YES if cell == true_cell else CONFIRM_NO)
        heard(reply, question)
        if reply.understood == 1 and (thresholds is None or phrase_confidence(reply.heard.confidences) >= thresholds.yes):
            return Settled(cell, "confirmed", ask + 1, confirmations)
    if thresholds is None:
        return Settled(None, None, asks, confirmations)
    say(ASK_TABLET)
    return Settled(int(tablet(legal)), "tablet", asks, confirmations)


def count_settled(record, settled: Settled, true_cell: int) -> bool:
    """Add how an unseen move was settled to the game's `GameRecord`; whether a cell was settled."""
    record.where_repeats += max(settled.asks - 1, 0)
    record.confirmations += settled.confirmations
    if settled.how == "tablet":
        record.tablet_fallbacks += 1
    elif settled.cell is not None:
        record.cells_from_answers += 1
        record.cells_accepted += int(settled.how == "accepted")
        record.misheard_cells += int(settled.cell != true_cell)  # the robot's board now holds the mark in the wrong cell
    return settled.cell is not None
