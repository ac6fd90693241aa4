"""ncbot envs: the exact rules, the batched engine and the multimodal dialogue game as a TorchRL env.

Imports stay light: torch/torchrl are loaded when ``make_env`` is first called. Importing this package also
registers the Gymnasium id ``ncbot/NoughtsCrosses-v0`` (see ``ncbot.envs.gym_wrapper``).
"""
from __future__ import annotations

from typing import Any

from ncbot.envs.env_options import OPTION_NAMES, READING_NAMES  # light: no torch
from ncbot.envs.readings import Readings

GYM_ID = "ncbot/NoughtsCrosses-v0"


def make_env(
    game: Any = "standard",
    batch_size: Any = (1,),
    temporal: bool = True,
    free_move: str = "anywhere",
    seed: int = 0,
    first: str = "robot",
    **options: Any,
):
    """Build the batched dialogue game env (a TorchRL ``EnvBase`` with batch size ``(B,)``).

    ``first``: robot|human|alternate|random, who makes the first game move (default robot; ``alternate`` flips per
    game slot every episode, ``random`` draws per game). Options: ``opponent`` "random" (uniform among legal squares), another opponent name from ``ncbot.envs.opponents`` or an
    object with ``select(boards, last_move, legal, player, generator)``, ``asr_confidence`` (low, high) of the
    uniform ASR confidence of each user word (default (0, 1)), ``max_actions`` (default 100), ``hearing`` None (the
    words said, at those uniform confidences) or an object with ``hear(utterances, generator)`` that decides what
    the robot hears (``ncbot.speech.hearing.ChannelHearing``; built by ``ncbot.pipelines.run_env`` for ``env.asr: channel``).
    ``game``: a name, a declaration, a game object, or the import path of a game the caller named with
    ``ncbot.envs.games.load_game`` (``make_env(load_game("my_pkg.games:Misere"))``; docs/games.md).

    The paper's readings (docs/env.md "Readings") are one ``readings`` object (``ncbot.envs.readings.Readings``) or
    its fields as keywords (``taken_squares``, ``misread_rate``, ``win_set``, ``about_to``, ``dialogues``,
    ``dialogue_subset``: None (every example dialogue) or (k, seed), the act filter and the simulated user learnt from
    a seeded subset of k example dialogues, the data-budget curve); keywords replace the object's fields.
    """
    for name in options:
        if name not in OPTION_NAMES:
            raise ValueError(f"unknown option {name!r}; options: {', '.join(OPTION_NAMES)}")
    readings = Readings.of(options.pop("readings", None), **{name: options.pop(name) for name in READING_NAMES if name in options})
    from ncbot.envs.dialogue_env import DialogueGameEnv

    return DialogueGameEnv(game, batch_size, readings=readings, temporal=temporal, free_move=free_move, seed=seed,
                           first=first, **options)


def _register_gym() -> None:
    try:
        from gymnasium.envs.registration import register, registry
    except ImportError:  # gymnasium is a dependency; stay importable without it anyway
        return
    if GYM_ID not in registry:
        register(id=GYM_ID, entry_point="ncbot.envs.gym_wrapper:NoughtsCrossesGymEnv")


_register_gym()
