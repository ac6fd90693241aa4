"""One place that turns the `env` section of a run config into `ncbot.envs.make_env(...)` calls.

Training, periodic evaluation and `ncbot eval` all build their envs here, so who opens (`first`) or an opponent
means the same thing everywhere.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any

from ncbot.envs.core import FIRST_CHOICES

# who opens test games (`--first`, `eval.first`): the env's choices but a random draw, so each seat is reported
TEST_FIRST_CHOICES = tuple(choice for choice in FIRST_CHOICES if choice != "random")


def make_run_env(env_config: Any, *, batch_size: int, seed: int, first: str | None = None,
                 opponent: str | None = None, hearing: Any = None):
    """Batched dialogue env for this run; `first` is who starts (robot | human | alternate | random); `hearing`
    (e.g. a `ncbot.speech.hearing.RecogniserHearing`) replaces the ears `env.asr` would give it."""
    from ncbot.envs import make_env
    from ncbot.envs.readings import FIELDS

    given = set(FIELDS) | ({"hearing"} if hearing is not None or env_config.asr == "channel" else set())
    repeated = sorted(given & set(env_config.options))
    if repeated:
        raise ValueError(f"env.options.{repeated[0]} repeats the config key env.{repeated[0]}: set env.{repeated[0]} only")
    if hearing is None and env_config.asr == "channel":
        hearing = run_hearing(env_config)
    return make_env(
        game=env_config.game,
        batch_size=(int(batch_size),),
        temporal=env_config.temporal,
        free_move=env_config.free_move,
        seed=int(seed),
        first=first or env_config.first,
        opponent=opponent or env_config.opponent,
        max_actions=env_config.max_steps,
        readings=readings_of(env_config),
        **({"hearing": hearing} if hearing is not None else {}),
        **env_config.options,
    )


def readings_of(env_config: Any):
    """The paper's readings of a run's `env` section, as the one object every part of the env reads
    (`ncbot.envs.readings.Readings`): built here, once per env, from the config keys `env.taken_squares`, ..."""
    from ncbot.envs.readings import Readings

    return Readings(taken_squares=env_config.taken_squares, misread_rate=env_config.misread_rate,
                    win_set=env_config.win_set, about_to=env_config.about_to, dialogues=env_config.dialogues,
                    dialogue_subset=env_config.subset)


def run_hearing(env_config: Any):
    """The env's ears for ``env.asr: channel``: the fitted ASR channel model over this game's utterances."""
    return _channel_hearing(env_config.game, env_config.dialogues, env_config.asr_channel,
                            tuple(float(v) for v in env_config.asr_snr_db), env_config.asr_noise, env_config.subset)


@lru_cache(maxsize=8)
def _channel_hearing(game: str, dialogues: str, path: str | None, snr_db: tuple[float, float], noise: str,
                     subset: tuple[int, int] | None = None):
    """Cached: evaluation builds envs every few thousand frames; the hearing holds no state (the env's generator
    draws its noise), so games and seeds can share one."""
    from ncbot.envs.dialogue import build_dialogue_model
    from ncbot.speech.channel import DEFAULT_CHANNEL, ChannelModel
    from ncbot.speech.hearing import ChannelHearing

    dialogue = build_dialogue_model(game, dialogues, subset)
    model = ChannelModel.load(DEFAULT_CHANNEL if path is None else path)
    return ChannelHearing(model, dialogue.utterance_texts, dialogue.words, snr_db, noise)


def check_first(first: str, allowed: tuple[str, ...] = TEST_FIRST_CHOICES, name: str = "first") -> str:
    """`first` (who opens: robot | human | ...) checked against the values a command takes."""
    if first not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(allowed)}, got {first!r}")
    return first


def robot_seat(first: str) -> str:
    """Who opens (`first`: robot | human) -> the robot's seat as results files name it: "first" | "second".

    The one translation between the two spellings. Everything a user types or a config holds says who opens with
    `first` (`--first robot|human`, `env.first`, `eval.first`); only results keep keys by the robot's seat, "first"
    and "second": eval.json, the `ncbot train` table, ladder rows and `ncbot eval --exhaustive` results. Those keys
    stay as they are because results files already written (and the tools that read them) depend on them.
    """
    seats = {"robot": "first", "human": "second"}
    if first not in seats:
        raise ValueError(f"first must be robot or human, got {first!r}")
    return seats[first]
