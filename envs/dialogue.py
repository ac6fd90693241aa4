"""The dialogue side of the game: the paper's dialogue acts, their templates and robot commands, the vocabulary,
and what the env learns from the example dialogues (the Naive Bayes action filter and the simulated user).

Why a compact "dialogue context" for the filter: the paper trains a Naive Bayes classifier from state features
to the next system act. Ours uses three categorical state features that summarise the key-value memory for
that purpose -- the last system act, the last user act and the game phase -- so the whole classifier is a
table over their 11 x 9 x 7 = 693 combinations, computed once and looked up per step for the whole batch.
"""
from __future__ import annotations

import random
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
import yaml

DATA_FILE = Path(__file__).with_name("data") / "example_dialogues.yaml"
PAPER_DATA_FILE = Path(__file__).with_name("data") / "example_dialogues_paper.yaml"
# ours, authored for the data-budget curve's k = 24 (dialogues 13-24 per game, same acts, templates and words)
PAPER_EXTRA_FILE = Path(__file__).with_name("data") / "example_dialogues_paper_extra.yaml"

# System dialogue-act types. Action ids: GameMove(gridloc=c) is action c (c < cells); type k >= 1 is action
# cells + k - 1, so acts are [moves..., greeting, name, ..., closing].
MOVE = 0
SYSTEM_TYPES = (
    "GameMove",
    "Salutation(greeting)",
    "Provide(name)",
    "Request(playGame)",
    "Reply(playGame=yes)",
    "Request(userGameMove)",
    "Provide(feedback=win)",
    "Provide(feedback=loose)",
    "Provide(feedback=draw)",
    "Salutation(closing)",
)
GREETING, NAME, REQUEST_PLAY, REPLY_YES, REQUEST_USER_MOVE, FEEDBACK_WIN, FEEDBACK_LOSE, FEEDBACK_DRAW, CLOSING = range(1, 10)
TEMPLATES = (
    "I take this one.",
    "Hello, nice to meet you!",
    "My name is Pepper, what is your name?",
    "Would you like to play a game?",
    "Yes, let's play!",
    "Your turn, please draw your move.",
    "I won, good game!",
    "You won, well done!",
    "It is a draw, good game!",
    "Thank you, goodbye!",
)
# The paper's act table gives these two lines; the other acts keep the lines above.
PAPER_TEMPLATES = tuple({REPLY_YES: "Nice. Let me start.", REQUEST_USER_MOVE: "Your turn."}.get(t, line)
                        for t, line in enumerate(TEMPLATES))
# The bracketed command of each act type; "draw" (moves) is represented by the move features instead.
TYPE_COMMANDS = ("draw", "hello", "asr", "please", "happy", "read", "happy", "no", "think", "hello")
ROBOT_COMMANDS = ("hello", "please", "happy", "no", "think", "asr", "read")

USER_ACTS = (
    "Salutation(greeting)",
    "Provide(name)",
    "Request(playGame)",
    "Reply(playGame=yes)",
    "Reply(playGame=no)",
    "GameMove",
    "Provide(feedback)",
    "Salutation(closing)",
)
USER_YES, USER_MOVE = USER_ACTS.index("Reply(playGame=yes)"), USER_ACTS.index("GameMove")

# Game phases (the third context feature).
PHASES = ("pre_game", "robot_to_move", "user_to_move", "robot_won", "user_won", "draw", "closed")
PRE_GAME, ROBOT_TO_MOVE, USER_TO_MOVE, ROBOT_WON, USER_WON, GAME_DRAWN, CLOSED = range(7)



@dataclass(frozen=True)
class DialogueSet:
    """One set of example dialogues (env option ``dialogues``): its file, the robot's lines, and the system acts
    the simulated user answers with its game move (on its turn).

    Why the last is declared, not learnt: it is the dialogue's shape (who prompts a move), which must hold for
    any subset of the examples, also one without a user-first game.
    """

    name: str
    path: Path
    templates: tuple[str, ...]
    user_moves_after: tuple[int, ...]
    extra_path: Path | None = None  # more examples of the same shape, used only by subsets of k > a dozen


DIALOGUE_SETS = {
    # ours: the user answers each robot move at once with its own move; "your turn" only opens a user-first game
    "compact": DialogueSet("compact", DATA_FILE, TEMPLATES, (MOVE, REQUEST_USER_MOVE)),
    # the paper's shape: "your turn" before every user move, the opening in full ("Nice. Let me start.")
    "paper": DialogueSet("paper", PAPER_DATA_FILE, PAPER_TEMPLATES, (REQUEST_USER_MOVE,), PAPER_EXTRA_FILE),
}
DIALOGUE_CHOICES = tuple(DIALOGUE_SETS)


def dialogue_set(name: str) -> DialogueSet:
    """The dialogue set called ``name``; ValueError naming the choices otherwise."""
    try:
        return DIALOGUE_SETS[name]
    except KeyError:
        raise ValueError(f"dialogues must be one of {', '.join(DIALOGUE_CHOICES)}; got {name!r}") from None


FILTER_THRESHOLD = 1e-3  # the paper's Pr(a|s) > 0.001
NB_SMOOTHING = 1e-4  # additive smoothing of the Naive Bayes counts (ours): small, so unseen evidence is strong

_MOVE_PATTERN = re.compile(r"GameMove\(gridloc=(\d+)\)")


def tokenize(text: str) -> list[str]:
    """Lower-case words without punctuation ("let's" -> "lets"): how utterances become word features."""
    return re.findall(r"[a-z]+", text.lower().replace("'", ""))


def action_names(cells: int) -> list[str]:
    """Names of all actions of a game with ``cells`` squares (moves first)."""
    return [f"GameMove(gridloc={c})" for c in range(cells)] + list(SYSTEM_TYPES[1:])


def phase_of(agreed: bool, closed: bool, outcome: int, robot_to_move: bool) -> int:
    """The game phase from the dialogue flags and the board outcome (0 none, 1 robot won, 2 user won, 3 draw)."""
    if closed:
        return CLOSED
    if outcome:
        return (ROBOT_WON, USER_WON, GAME_DRAWN)[outcome - 1]
    if not agreed:
        return PRE_GAME
    return ROBOT_TO_MOVE if robot_to_move else USER_TO_MOVE


@dataclass(frozen=True)
class DialogueModel:
    """Everything learnt from one game's example dialogues, as tensors ready for batched look-ups.

    ``filter_allowed[last_sys, last_user, phase, type]``: the NB filter (Pr > 0.001). Index 0 of last_sys /
    last_user means "none yet"; others are type / user act + 1. ``reply_options[type, phase, k]`` holds
    utterance ids the simulated user may answer with (the first ``reply_counts[type, phase]`` are valid;
    none means silence). ``utterance_acts`` / ``utterance_texts`` / ``utterance_words`` describe each
    utterance; ``words`` is the vocabulary (sorted), ``template_words[1 + type]`` the system words of
    each act type (row 0: nothing said yet).
    """

    words: tuple[str, ...]
    utterance_texts: tuple[str, ...]
    utterance_acts: torch.Tensor  # (U,) int64 user act id
    utterance_words: torch.Tensor  # (U, V) float 0/1
    template_words: torch.Tensor  # (1 + types, V) float 0/1
    template_commands: torch.Tensor  # (1 + types, 7) float 0/1
    filter_probability: torch.Tensor  # (11, 9, 7, types) float
    filter_allowed: torch.Tensor  # (11, 9, 7, types) bool
    reply_options: torch.Tensor  # (types, phases, K) int64
    reply_counts: torch.Tensor  # (types, phases) int64
    n_examples: int
    templates: tuple[str, ...] = TEMPLATES
    user_moves_after: tuple[int, ...] = (MOVE, REQUEST_USER_MOVE)
    example_contexts: tuple[tuple[int, int, int], ...] = ()  # (last sys, last user, phase) of each example turn


def load_dialogues(game: str, path: Path = DATA_FILE) -> list[dict]:
    """The example dialogues of ``game`` from the data file (FileNotFoundError / ValueError if unusable); a declared
    game's are generated from its declaration with the same skeletons and utterances (``declared_dialogues``)."""
    if game not in ("standard", "ultimate"):
        return declared_dialogues(game, path.name)
    if not path.is_file():
        raise FileNotFoundError(f"example dialogue file {path} not found: expected the YAML shipped in envs/data")
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict) or not isinstance(data.get("dialogues"), list):
        raise ValueError(f"{path}: expected a mapping with a 'dialogues' list")
    chosen = [d for d in data["dialogues"] if d.get("game") == game]
    if not chosen:
        raise ValueError(f"{path}: no dialogues for game {game!r}")
    return chosen


@lru_cache(maxsize=16)
def _declared_dialogue_text(game: str, file_name: str) -> str:
    from ncbot.envs.data.make_example_dialogues import declared_dialogue_text
    from ncbot.envs.rules import make_game

    return declared_dialogue_text(make_game(game), file_name)


def declared_dialogues(game: str, file_name: str) -> list[dict]:
    """The example dialogues of the declared ``game`` for the set whose built-in file is ``file_name``: data made
    from the declaration (``ncbot.envs.data.make_example_dialogues.declared_dialogue_text``), never per-game code."""
    return yaml.safe_load(_declared_dialogue_text(game, file_name))["dialogues"]


def _parse_system(act: str, cells: int, where: str) -> tuple[int, int]:
    """(type, cell) of a system act name; ValueError naming the dialogue turn otherwise."""
    found = _MOVE_PATTERN.fullmatch(act)
    if found:
        cell = int(found.group(1))
        if cell >= cells:
            raise ValueError(f"{where}: cell {cell} out of range 0..{cells - 1}")
        return MOVE, cell
    if act in SYSTEM_TYPES[1:]:
        return SYSTEM_TYPES.index(act), -1
    raise ValueError(f"{where}: unknown system act {act!r}; expected GameMove(gridloc=N) or one of {', '.join(SYSTEM_TYPES[1:])}")


def _parse_user(act: str | None, where: str) -> tuple[int, int]:
    """(user act id or -1 for silence, cell or -1)."""
    if act is None:
        return -1, -1
    found = _MOVE_PATTERN.fullmatch(act)
    if found:
        return USER_MOVE, int(found.group(1))
    if act in USER_ACTS and act != "GameMove":
        return USER_ACTS.index(act), -1
    raise ValueError(f"{where}: unknown user act {act!r}; expected GameMove(gridloc=N), null or one of {', '.join(USER_ACTS)}")


@lru_cache(maxsize=32)
def build_dialogue_model(game: str, dialogues: str = "compact", subset: tuple[int, int] | None = None) -> DialogueModel:
    """Replay ``game``'s example dialogues of the set ``dialogues`` with the exact rules and fit the filter and the
    user model; the vocabulary is the set's templates' words and its users' words.

    ``subset`` (k, seed): learn the filter and the user from ``subset_examples`` instead (env option
    ``dialogue_subset``), keeping the whole set's vocabulary. Why a fixed vocabulary: the observation's word
    features are the network's input, so every k gives the same input size (73 / 289 features) and the same
    network; a word no chosen dialogue uses is simply never heard (its feature stays 0). Otherwise the curve
    over k would compare networks of different sizes, not only different data.

    Each dialogue is replayed under its own ``free_move`` rule (default "anywhere", the paper's); what is
    learnt (acts per dialogue context, user replies) does not depend on the variant the env is run with.
    """
    chosen = dialogue_set(dialogues)
    if subset is None:
        return fit_dialogue_model(game, examples_of(game, dialogues), chosen)
    words = build_dialogue_model(game, chosen.name).words
    return fit_dialogue_model(game, examples_of(game, dialogues, subset), chosen, vocabulary=words)


def examples_of(game: str, dialogues: str = "compact", subset: tuple[int, int] | None = None) -> list[dict]:
    """The example dialogues ``build_dialogue_model`` learns from for ``game``, the set ``dialogues`` and the
    optional ``subset`` (k, seed): what a data-budget report counts."""
    chosen = dialogue_set(dialogues)
    if subset is None:
        return load_dialogues(game, chosen.path)
    k, seed = subset
    return subset_examples(game, chosen, k, seed)


def example_pool(game: str, chosen: DialogueSet) -> list[dict]:
    """Every example dialogue a subset may draw from: the set's dozen, then its extra file's (if any)."""
    pool = load_dialogues(game, chosen.path)
    return pool + (load_dialogues(game, chosen.extra_path) if chosen.extra_path is not None else [])


def subset_examples(game: str, chosen: DialogueSet, k: int, seed: int) -> list[dict]:
    """A seeded subset of ``k`` example dialogues, in file order (so k = the whole dozen is the set itself).

    k up to the set's dozen: drawn from the dozen. Larger k: the whole dozen plus k - 12 drawn from the extra
    file (ours, authored), so every larger subset contains the paper-sized one.
    """
    dozen, pool = load_dialogues(game, chosen.path), example_pool(game, chosen)
    if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= len(pool):
        raise ValueError(f"dialogue_subset k must be an integer between 1 and {len(pool)} (the {chosen.name} set's "
                         f"example dialogues for {game}), got {k!r}")
    rng = random.Random(seed)
    if k <= len(dozen):
        return [dozen[i] for i in sorted(rng.sample(range(len(dozen)), k))]
    extra = pool[len(dozen):]
    return dozen + [extra[i] for i in sorted(rng.sample(range(len(extra)), k - len(dozen)))]


def fit_dialogue_model(game: str, dialogues: list[dict], chosen: DialogueSet,
                       vocabulary: tuple[str, ...] | None = None) -> DialogueModel:
    """The model learnt from ``dialogues`` (replayed and checked) under the set ``chosen``'s templates and shape;
    any subset of a set's examples works (the data-budget curve of ``ncbot reproduce budget``). ``vocabulary``:
    use these words (ValueError if a dialogue says another) instead of the ones the dialogues give."""
    from ncbot.envs.rules import make_game

    contexts: list[tuple[int, int, int]] = []
    labels: list[int] = []
    replies: dict[tuple[int, int], list[int]] = {}
    utterances: dict[tuple[int, str], int] = {}
    for dialogue in dialogues:
        robot_mark = 1 if dialogue.get("robot_first", True) else 2
        rules = make_game(game, dialogue.get("free_move", "anywhere"))
        state, agreed, closed, last_sys, last_user = rules.new(), False, False, 0, 0

        def phase() -> int:
            outcome = rules.outcome(state)
            result = {None: 0, "draw": 3}.get(outcome, 1 if outcome == "xo"[robot_mark - 1] else 2)
            return phase_of(agreed, closed, result, rules.mark_to_move(state) == robot_mark)

        for number, turn in enumerate(dialogue.get("turns", [])):
            where = f"dialogue {dialogue.get('id')} turn {number + 1}"
            act_type, cell = _parse_system(turn["robot"], rules.n_cells, where)
            contexts.append((last_sys, last_user, phase()))
            labels.append(act_type)
            if act_type == MOVE:
                if phase() != ROBOT_TO_MOVE:
                    raise ValueError(f"{where}: robot move while the phase is {PHASES[phase()]}")
                state = rules.play(state, cell)
            agreed |= act_type == REPLY_YES
            closed |= act_type == CLOSING
            user_act, user_cell = _parse_user(turn.get("user"), where)
            text = turn.get("says") or ""
            heard = replies.setdefault((act_type, phase()), [])  # a context seen only with silence stays silent
            if user_act >= 0:
                key = (user_act, text)
                heard.append(utterances.setdefault(key, len(utterances)))
            if user_act == USER_MOVE:
                if phase() != USER_TO_MOVE or act_type not in chosen.user_moves_after:
                    raise ValueError(f"{where}: user move while the phase is {PHASES[phase()]}")
                state = rules.play(state, user_cell)
            agreed |= act_type == REQUEST_PLAY and user_act == USER_YES
            last_sys, last_user = act_type + 1, user_act + 1

    texts = [text for (_, text) in utterances]
    system_words = {w for t in chosen.templates for w in tokenize(t)}
    words = tuple(sorted(system_words | {w for t in texts for w in tokenize(t)}))
    if vocabulary is not None:
        unknown = sorted(set(words) - set(vocabulary))
        if unknown:
            raise ValueError(f"example dialogues say {unknown[0]!r}, outside the {chosen.name} set's fixed vocabulary "
                             f"of {len(vocabulary)} words")
        words = tuple(vocabulary)
    index = {w: i for i, w in enumerate(words)}

    def bag(text: str) -> np.ndarray:
        row = np.zeros(len(words), dtype=np.float32)
        row[[index[w] for w in tokenize(text)]] = 1.0
        return row

    template_words = np.stack([np.zeros(len(words), dtype=np.float32)] + [bag(t) for t in chosen.templates])
    commands = np.zeros((1 + len(SYSTEM_TYPES), len(ROBOT_COMMANDS)), dtype=np.float32)
    for act_type, command in enumerate(TYPE_COMMANDS):
        if command in ROBOT_COMMANDS:
            commands[1 + act_type, ROBOT_COMMANDS.index(command)] = 1.0
    probability = _fit_naive_bayes(np.array(contexts), np.array(labels))
    options, counts = _reply_table(replies, [act for (act, _) in utterances])
    return DialogueModel(
        words=words,
        utterance_texts=tuple(texts),
        utterance_acts=torch.tensor([act for (act, _) in utterances], dtype=torch.int64),
        utterance_words=torch.from_numpy(np.stack([bag(t) for t in texts])),
        template_words=torch.from_numpy(template_words),
        template_commands=torch.from_numpy(commands),
        filter_probability=torch.from_numpy(probability),
        filter_allowed=torch.from_numpy(_safe_filter(probability)),
        reply_options=options,
        reply_counts=counts,
        n_examples=len(labels),
        templates=chosen.templates,
        user_moves_after=chosen.user_moves_after,
        example_contexts=tuple(contexts),
    )


def _fit_naive_bayes(contexts: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Categorical Naive Bayes Pr(type | last_sys, last_user, phase) for every context, shape (11, 9, 7, T)."""
    sizes = (1 + len(SYSTEM_TYPES), 1 + len(USER_ACTS), len(PHASES))
    n_types = len(SYSTEM_TYPES)
    class_counts = np.bincount(labels, minlength=n_types).astype(np.float64)
    log_joint = np.log((class_counts + NB_SMOOTHING) / (class_counts.sum() + NB_SMOOTHING * n_types))
    log_joint = np.broadcast_to(log_joint, sizes + (n_types,)).copy()
    for feature, size in enumerate(sizes):
        counts = np.zeros((size, n_types))
        np.add.at(counts, (contexts[:, feature], labels), 1.0)
        log_likelihood = np.log((counts + NB_SMOOTHING) / (class_counts + NB_SMOOTHING * size))  # (size, T)
        shape = [1, 1, 1, n_types]
        shape[feature] = size
        log_joint += log_likelihood.reshape(shape)
    log_joint -= log_joint.max(-1, keepdims=True)
    joint = np.exp(log_joint)
    return (joint / joint.sum(-1, keepdims=True)).astype(np.float32)


def _safe_filter(probability: np.ndarray) -> np.ndarray:
    """The filter (Pr > 0.001) with moves only where the robot is to move, never leaving a context empty.

    Outside ``robot_to_move`` no square is legal for the robot, so the move type is dropped there; if that
    leaves nothing, the most probable other act is kept (so an action mask row is never all False).
    """
    allowed = probability > FILTER_THRESHOLD
    not_robot_turn = np.ones(len(PHASES), dtype=bool)
    not_robot_turn[ROBOT_TO_MOVE] = False
    allowed[:, :, not_robot_turn, MOVE] = False
    best_other = 1 + probability[..., 1:].argmax(-1)
    empty = ~allowed.any(-1)
    for i, j, k in np.argwhere(empty):
        allowed[i, j, k, best_other[i, j, k]] = True
    return allowed


def _reply_table(replies: dict[tuple[int, int], list[int]], utterance_acts: list[int]) -> tuple[torch.Tensor, torch.Tensor]:
    """User replies per (system type, phase); unseen contexts fall back to the type's replies (no moves).

    A context the examples show only with silence (the paper set's user watching the robot draw) keeps no
    reply; one seen with both silence and words keeps the words only (no example dialogue has such a context).
    """
    n_types, n_phases = len(SYSTEM_TYPES), len(PHASES)
    table: dict[tuple[int, int], list[int]] = {}
    for act_type in range(n_types):
        fallback = [u for (t, _), us in replies.items() if t == act_type for u in us if utterance_acts[u] != USER_MOVE]
        for phase in range(n_phases):
            table[act_type, phase] = replies.get((act_type, phase), fallback)
    width = max(1, max(len(v) for v in table.values()))
    options = torch.zeros(n_types, n_phases, width, dtype=torch.int64)
    counts = torch.zeros(n_types, n_phases, dtype=torch.int64)
    for (act_type, phase), us in table.items():
        options[act_type, phase, : len(us)] = torch.tensor(us, dtype=torch.int64)
        counts[act_type, phase] = len(us)
    return options, counts
