"""The person's answers to the robot (buttons and typed words), put through the env as the user's dialogue act.

Why through the env: in `ncbot robot play` the env's simulated user answers each robot act with an utterance
learnt from the example dialogues, and that utterance (its words and act) is what the robot's state, the act
filter and the policy see next. A person in the browser takes that user's place: `ncbot.pipelines.evaluate.play.HeardReplies`
(the same hook `ncbot play` uses for typed text) makes the env's reply table hold the person's utterance, so
the env's own step turns it into words, a user act and its effect (a "no" to "shall we play?" never agrees to
play; silence is silence). Typed text is understood with `ncbot.speech.understand.closest_utterance` (each typed word
heard at confidence 1); text it cannot place is silence, a legal result ("I did not understand").
"""
from __future__ import annotations

from typing import Any

import ncbot.envs.dialogue as dlg

#: The answer buttons (`data-act`) and the user act each stands for; "silence" says nothing.
BUTTONS: dict[str, str | None] = {
    "hello": "Salutation(greeting)", "name": "Provide(name)", "play": "Request(playGame)",
    "yes": "Reply(playGame=yes)", "no": "Reply(playGame=no)", "feedback": "Provide(feedback)",
    "bye": "Salutation(closing)", "silence": None,
}
MAX_TYPED = 200  # characters of one typed answer
#: A cooperative person's answer: the first of these the robot's utterance enables (scripted people, tests).
PREFERRED_ACTS = ("yes", "hello", "name", "feedback", "bye", "play", "no", "silence")


def act_type_of(env: Any, action: int) -> int:
    """The system act type of an env action (moves are type 0)."""
    return dlg.MOVE if action < env.cells else action - env.cells + 1


def needs_answer(act_type: int) -> bool:
    """Whether the person answers this robot act in words: not moves and "your turn" (the click answers them),
    not the closing (the dialogue ends with it)."""
    return act_type not in (dlg.MOVE, dlg.REQUEST_USER_MOVE, dlg.CLOSING)


class EnvAnswers:
    """One env's reply hook: which buttons fit a robot act, what a button or typed text means, and setting it."""

    def __init__(self, env: Any) -> None:
        from ncbot.pipelines.evaluate.play import HeardReplies
        from ncbot.speech.understand import utterance_table

        model = env.model  # the env's own tables, before HeardReplies swaps in its private copy
        self._options, self._counts = model.reply_options, model.reply_counts
        self.replies = HeardReplies(env)
        self.texts: tuple[str, ...] = model.utterance_texts
        self.acts: list[int] = model.utterance_acts.tolist()
        self.words = {w: i for i, w in enumerate(model.words)}
        self.table = utterance_table(self.texts, model.words)

    def buttons_for(self, act_type: int) -> list[str]:
        """The buttons that make sense after a robot act of `act_type`: the user acts the example dialogues show
        in reply to it (the env's simulated user says nothing else there), and silence."""
        seen: set[str] = set()
        for phase in range(self._counts.shape[1]):
            for utterance in self._options[act_type, phase, : int(self._counts[act_type, phase])].tolist():
                seen.add(dlg.USER_ACTS[self.acts[utterance]])
        return [name for name, act in BUTTONS.items() if act is None or act in seen]

    def button_utterance(self, name: str) -> int | None:
        """The utterance a button says: its own word if an example says it, else the shortest example utterance
        of its act (None: silence)."""
        act = BUTTONS[name]
        if act is None:
            return None
        ids = [u for u, a in enumerate(self.acts) if dlg.USER_ACTS[a] == act]
        return min(ids, key=lambda u: (self.texts[u] != name, len(self.texts[u])))  # "hello" says hello

    def understand(self, text: str, act_type: int) -> int | None:
        """The example utterance closest to the typed words (confidence 1 each); None when nothing fits."""
        import torch

        from ncbot.speech.understand import closest_utterance

        words = dlg.tokenize(text)
        known = [self.words[w] for w in words if w in self.words]
        if known:
            heard = torch.tensor([known])
            found = int(closest_utterance(heard, torch.ones(heard.shape), self.table)[0])
            if found >= 0:
                return found
        if words and act_type == dlg.NAME:  # a bare name ("Alice") answers "what is your name?" (as `ncbot play`)
            return self.button_utterance("name")
        return None

    def describe(self, utterance: int | None) -> dict[str, Any]:
        """The log's / page's view of an utterance: its text, act id and act name (silence: act -1)."""
        if utterance is None:
            return {"understood": "", "act": -1, "act_name": "silence"}
        act = self.acts[utterance]
        return {"understood": self.texts[utterance], "act": act, "act_name": dlg.USER_ACTS[act]}

    def set(self, act_type: int, utterance: int | None) -> None:
        """Make the env's user answer the next act of `act_type` with `utterance` (None: silence)."""
        self.replies.set_reply(act_type, utterance)

    def set_without_asking(self, act_type: int) -> None:
        """An act the person does not answer in words: a move or "your turn" is answered by the click (the env
        silences it when no move follows), the closing by silence (the dialogue ends)."""
        self.replies.set_reply(act_type, None if act_type == dlg.CLOSING else self.replies.game_move_utterance())


def answer_turn(model: EnvAnswers, answer: dict[str, Any], record: Any) -> tuple[dict[str, Any], str]:
    """The `/dialogue` turn logged for the person's answer, and the line the page shows ("what the robot heard")."""
    utterance, text, kind = answer["utterance"], answer["text"], answer["input"]
    meaning = model.describe(utterance)
    heard = {"typed": f"You: {text!r}.", "timeout": "You said nothing.", "button": f"You: [{text}]."}[kind]
    if utterance is not None:
        heard += f" The robot understood: {meaning['understood']!r}."
    elif kind == "typed" and text:
        heard += " The robot did not understand (it hears silence)."
    turn = {"episode": record.index if record else -1, "step": record.actions if record else -1, "speaker": "user",
            "act": meaning["act"], "act_name": meaning["act_name"], "text": text, "understood": meaning["understood"],
            "input": kind, "move": -1, "source": "browser" if kind != "timeout" else "serve-timeout"}
    return turn, heard
