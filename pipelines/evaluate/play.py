"""`ncbot play`: a person at the terminal plays the robot through the real dialogue env.

Why through the env: the person should meet exactly what the agent was trained and evaluated on (the same
acts, templates, action filter, look-ahead masks and rewards), and the game is logged like any other episode.
Two hooks make the env listen to the person instead of its simulated user:

- the user's game move: the env asks its opponent for the user's square; ``TerminalHuman`` is that opponent
  and asks the person (board drawn with coordinates, legal squares marked, bad input explained and asked again);
- the user's spoken reply: the env samples it from the replies in its example dialogues; ``HeardReplies``
  gives the env a private copy of that reply table in which the only option is what the person typed (matched
  to the closest known utterance by shared words), so the env's own code turns it into words and a user act.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import torch

from ncbot.envs import dialogue as dlg
from ncbot.envs.games import make_game

QUIT_WORDS = {"quit", "exit", "q"}
HELP_WORDS = {"help", "?"}


class QuitGame(Exception):
    """The person asked to stop (``quit``, end of input)."""


class Console:
    """Reads and writes lines; one place so that ``quit`` and end-of-input are handled the same everywhere."""

    def __init__(self, read: Callable[[str], str] = input, write: Callable[[str], None] = print) -> None:
        self._read, self._write = read, write

    def say(self, text: str = "") -> None:
        self._write(text)

    def ask(self, prompt: str) -> str:
        try:
            text = self._read(prompt)
        except EOFError:
            raise QuitGame from None
        if text.strip().lower() in QUIT_WORDS:
            raise QuitGame
        return text.strip()


class TerminalHuman:
    """The env's opponent for the user's squares: shows the board and asks the person for a legal cell."""

    name = "human"

    def __init__(self, console: Console, game: str, free_move: str, symbols: dict[int, str]) -> None:
        self.console = console
        self.rules = make_game(game, free_move)
        self.symbols = symbols

    def select(self, boards: torch.Tensor, last_move: torch.Tensor, legal: torch.Tensor, player: int,
               generator=None) -> torch.Tensor:
        legal_cells = torch.nonzero(legal[0]).flatten().tolist()
        self.console.say(self.rules.render_board(boards[0].tolist(), self.symbols, legal_cells=legal_cells))
        self.console.say(f"(· marks the squares you may take; you are {self.symbols[player]})")
        example = self.rules.cell_name(legal_cells[len(legal_cells) // 2])
        while True:
            text = self.console.ask(f"Your move (e.g. {example}): ")
            if text.lower() in HELP_WORDS:
                self.console.say(f"Type a column letter and a row number, e.g. {example}; 'quit' ends the game.")
                continue
            try:
                cell = self.rules.parse_cell(text)
            except ValueError as error:
                self.console.say(f"Sorry: {error}.")
                continue
            if cell not in legal_cells:
                taken = boards[0, cell].item() != 0
                why = "is already taken" if taken else "is not allowed now (you must play in the highlighted squares)"
                self.console.say(f"Sorry: {text} {why}. Legal: {' '.join(self.rules.cell_name(c) for c in legal_cells)}")
                continue
            return torch.tensor([cell], dtype=torch.long)


class HeardReplies:
    """Makes the env's simulated user say what the person typed (see the module docstring)."""

    def __init__(self, env) -> None:
        model = env.model
        self._options, self._counts = model.reply_options.clone(), model.reply_counts.clone()
        self._original_options, self._original_counts = model.reply_options, model.reply_counts
        env.model = dataclasses.replace(model, reply_options=self._options, reply_counts=self._counts)
        self.model = env.model
        self.words = [set(dlg.tokenize(text)) for text in model.utterance_texts]

    def set_reply(self, act_type: int, utterance: int | None) -> None:
        """The reply of the user to the next act of type ``act_type``: an utterance id, or None for silence."""
        self._options.copy_(self._original_options)
        self._counts.copy_(self._original_counts)
        self._counts[act_type] = 0 if utterance is None else 1
        if utterance is not None:
            self._options[act_type, :, 0] = utterance

    def match(self, text: str, act_type: int) -> int | None:
        """The known utterance sharing most words with ``text`` (ties: the shorter one); None if none shares any."""
        said = set(dlg.tokenize(text))
        if not said:
            return None
        best, best_key = None, (0.0, 0)
        for utterance, words in enumerate(self.words):
            shared = len(said & words)
            key = (shared / len(said | words), -len(words))
            if shared and key > best_key:
                best, best_key = utterance, key
        if best is None and act_type == dlg.NAME:  # a bare name ("Alice") answers "what is your name?"
            return self._shortest_of_act("Provide(name)")
        return best

    def examples(self, act_type: int) -> list[str]:
        """Distinct replies the example dialogues show after acts of this type (for the "did not understand" hint)."""
        texts = []
        for phase in range(self._original_counts.shape[1]):
            for utterance in self._original_options[act_type, phase, : int(self._original_counts[act_type, phase])].tolist():
                text = self.model.utterance_texts[utterance]
                if text not in texts:
                    texts.append(text)
        return texts

    def game_move_utterance(self) -> int:
        """What the person "says" when they answer with a move (the env silences it when no move follows)."""
        return self._shortest_of_act("GameMove")

    def _shortest_of_act(self, act_name: str) -> int:
        act = dlg.USER_ACTS.index(act_name)
        ids = [u for u, a in enumerate(self.model.utterance_acts.tolist()) if a == act]
        return min(ids, key=lambda u: len(self.model.utterance_texts[u]))


def _build(game: str | None, checkpoint: str | None, free_move: str | None, first: str, seed: int, human_factory):
    """(env, policy, agent name) from a checkpoint (its own game and features) or the look-ahead policy."""
    from ncbot.envs import make_env
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy

    if checkpoint is None:
        game = game or "standard"
        free_move = free_move or "anywhere"
        human = human_factory(game, free_move)
        env = make_env(game, batch_size=(1,), temporal=True, free_move=free_move, seed=seed, first=first,
                       opponent=human, asr_confidence=(1.0, 1.0))
        return env, LookaheadOnlyPolicy(seed), "lookahead"
    from ncbot.pipelines.agents import load_agent
    from ncbot.pipelines.run_env import make_run_env

    if not Path(checkpoint).exists():
        raise FileNotFoundError(f"checkpoint {checkpoint!r} not found (expected a checkpoint.pt written by ncbot train)")
    config, policy = load_agent(checkpoint)
    if game is not None and game != config.env.game:
        raise ValueError(f"--game {game} does not match the checkpoint, which plays {config.env.game}; drop --game")
    if free_move is not None and free_move != config.env.free_move:
        raise ValueError(f"--free-move {free_move} does not match the checkpoint's {config.env.free_move}")
    config.env.options = {**config.env.options, "asr_confidence": (1.0, 1.0)}
    config.env.asr = "uniform"  # the person types: the ASR channel model is for simulated speech, not for text
    human = human_factory(config.env.game, config.env.free_move)
    env = make_run_env(config.env, batch_size=1, seed=seed, first=first, opponent=human)
    return env, policy, config.agent.name


def play_dialogue(*, game: str | None = None, checkpoint: str | None = None, first: str = "robot",
                  free_move: str | None = None, seed: int = 0, log_dir: str | None = "runs/play",
                  console: Console | None = None) -> dict:
    """One dialogue (greeting ... game ... goodbye) between the person and the robot; returns a summary.

    ``first`` is who opens the game: robot | human (the person draws the first mark). Raises ``QuitGame``
    when the person types ``quit`` or input ends; KeyboardInterrupt passes through (the CLI ends cleanly).
    """
    from torchrl.envs.utils import ExplorationType, set_exploration_type, step_mdp

    from ncbot.modules.networks.recurrent import memory_env
    from ncbot.pipelines.run_env import check_first

    check_first(first, ("robot", "human"))
    console = console or Console()
    symbols = {1: "o", 2: "x"} if first == "human" else {1: "x", 2: "o"}
    human = None

    def human_factory(game_name: str, rule: str) -> TerminalHuman:
        nonlocal human
        human = TerminalHuman(console, game_name, rule, symbols)
        return human

    torch.set_num_threads(1)
    env, policy, agent = _build(game, checkpoint, free_move, first, seed, human_factory)
    replies = HeardReplies(env)  # edits the dialogue env itself, so it takes the env, not the wrapper below
    stepper = memory_env(env, policy)  # agent.memory: the hidden state runs through the dialogue, zero at its start
    rules = human.rules
    logger = None
    if log_dir is not None:
        from ncbot.logs import EpisodeLogger, PHASES

        phase = "play" if "play" in PHASES else "robot"
        logger = EpisodeLogger(log_dir, run_info={"command": "play", "game": env.game, "agent": agent,
                                                  "checkpoint": checkpoint, "first": first, "seed": seed})
    console.say(f"ncbot play: {env.game} noughts & crosses against Pepper ({agent} policy). "
                f"You are {symbols[2]}, Pepper is {symbols[1]}. Type 'quit' to stop.")
    summary = {"outcome": "unfinished", "actions": 0, "game": env.game, "agent": agent, "log_dir": log_dir}
    try:
        td = stepper.reset()
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            while True:
                td = policy(td)
                action = int(td.get("action").reshape(-1)[0])
                act_type = dlg.MOVE if action < env.cells else action - env.cells + 1
                console.say(f"Pepper: {env.describe_action(action)}")
                if act_type in (dlg.MOVE, dlg.REQUEST_USER_MOVE):
                    replies.set_reply(act_type, replies.game_move_utterance())
                else:
                    replies.set_reply(act_type, _ask_reply(console, replies, act_type, rules))
                td = stepper.step(td)
                if logger is not None:
                    logger.record_steps(td, env=env, phase=phase, agent=agent, seed=seed, extra={"player": "human"})
                after = td.get("next")
                summary["actions"] += 1
                outcome = int(after.get("outcome").reshape(-1)[0])
                if outcome and summary["outcome"] == "unfinished":
                    summary["outcome"] = {1: "robot won", 2: "you won", 3: "draw"}[outcome]
                    console.say(rules.render_board(after.get("board")[0].tolist(), symbols))
                    console.say(f"Game over: {summary['outcome']}.")
                if bool(after.get("done").reshape(-1)[0]):
                    if bool(after.get("truncated").reshape(-1)[0]):
                        console.say(f"(the dialogue reached its limit of {env.max_actions} robot actions)")
                    break
                td = step_mdp(td)
    finally:
        if logger is not None:
            logger.close()
        stepper.close()
    return summary


def _is_cell(rules, text: str) -> bool:
    try:
        rules.parse_cell(text)
    except ValueError:
        return False
    return True


def _ask_reply(console: Console, replies: HeardReplies, act_type: int, rules) -> int | None:
    """The person's answer to a non-move act, matched to a known utterance; empty input means silence."""
    while True:
        text = console.ask("You: ")
        if not text:
            return None
        if _is_cell(rules, text):
            console.say(f"Pepper is not waiting for your move now: answer in words, e.g. "
                        f"{' / '.join(replies.examples(act_type)[:3]) or 'hello'}.")
            continue
        if text.lower() in HELP_WORDS:
            console.say("Answer Pepper in a few words, e.g.: " + " / ".join(replies.examples(act_type)[:5])
                        + ". Press Enter to stay silent, 'quit' to stop.")
            continue
        utterance = replies.match(text, act_type)
        if utterance is not None:
            return utterance
        hints = " / ".join(replies.examples(act_type)[:5]) or "hello / yes / goodbye"
        console.say(f"Sorry, I did not understand {text!r}. You could say: {hints}.")
