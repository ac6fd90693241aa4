"""`env.asr: channel`: the training env hears the simulated user through the shipped ASR channel model (fitted
from real TTS -> noise -> pocketsphinx round trips) instead of uniform random confidences."""
from __future__ import annotations

import pytest
import torch

from ncbot.envs import make_env
from ncbot.pipelines.config import EnvConfig
from ncbot.pipelines.run_env import make_run_env, run_hearing


class Recorded:
    """The real hearing, keeping what it was asked to hear and what it returned (to look inside the env)."""

    def __init__(self, hearing) -> None:
        self.hearing, self.said, self.understood, self.confidences = hearing, [], [], []

    def hear(self, utterance: torch.Tensor, generator: torch.Generator | None = None):
        columns, confidence, understood = self.hearing.hear(utterance, generator)
        self.said.append(utterance.clone())
        self.understood.append(understood.clone())
        self.confidences.append(confidence[columns < self.hearing.n_env_words])
        return columns, confidence, understood


def rollout(env, steps: int = 40) -> list[torch.Tensor]:
    """Observations of ``steps`` random (masked) actions; the env's own action generator makes them per seed."""
    td = env.reset()
    observations = []
    for _ in range(steps):
        td = env.rand_action(td)
        out, td = env.step_and_maybe_reset(td)
        observations.append(out["next", "observation"].clone())
    return observations


def channel_env(seed: int = 0, snr: tuple[float, float] = (10.0, 30.0), noise: str = "babble", batch: int = 32):
    return make_run_env(EnvConfig(asr="channel", asr_snr_db=list(snr), asr_noise=noise), batch_size=batch, seed=seed)


def test_channel_env_runs_and_is_reproducible_per_seed():
    first, again, other = (rollout(channel_env(seed)) for seed in (0, 0, 1))
    assert all(torch.equal(a, b) for a, b in zip(first, again))
    assert not all(torch.equal(a, b) for a, b in zip(first, other))
    uniform = rollout(make_run_env(EnvConfig(), batch_size=32, seed=0))
    assert not all(torch.equal(a, b) for a, b in zip(first, uniform))  # the channel changes what the robot hears


def hear_through_env(snr: tuple[float, float], noise: str = "white") -> Recorded:
    config = EnvConfig(asr="channel", asr_snr_db=list(snr), asr_noise=noise)
    recorded = Recorded(run_hearing(config))
    env = make_env(game="standard", batch_size=(64,), seed=3, hearing=recorded)
    rollout(env, 60)
    return recorded


def test_confidences_fall_and_mishearings_rise_at_low_snr():
    loud, quiet = hear_through_env((5.0, 5.0)), hear_through_env((30.0, 30.0))
    low, high = torch.cat(loud.confidences), torch.cat(quiet.confidences)
    assert low.numel() > 100 and high.numel() > 100
    assert float(low.mean()) < float(high.mean()) - 0.05

    def misheard(r: Recorded) -> float:
        said, understood = torch.cat(r.said), torch.cat(r.understood)
        spoken = said < len(r.hearing._table)  # not silence
        return float((understood[spoken] != said[spoken]).float().mean())

    assert misheard(loud) > misheard(quiet)
    assert misheard(loud) > 0.1  # misheard replies happened and the env stepped through them


def test_misheard_reply_drives_the_dialogue_act_not_the_board():
    """A hearing that always understands silence: the robot observes no user act, but the user still moves."""

    class Deaf:
        def __init__(self, hearing) -> None:
            self.hearing = hearing

        def hear(self, utterance, generator=None):
            columns, confidence, understood = self.hearing.hear(utterance, generator)
            return columns, confidence, torch.full_like(understood, -1)

    env = make_env(game="standard", batch_size=(16,), seed=0, first="human",
                   hearing=Deaf(run_hearing(EnvConfig(asr="channel"))))
    td = env.reset()
    moved = False
    for _ in range(30):
        td = env.rand_action(td)
        out, td = env.step_and_maybe_reset(td)
        assert bool((out["next", "user_act"] == -1).all())
        moved = moved or bool((out["next", "user_move"] >= 0).any())
    assert moved


def test_bad_asr_settings_raise_one_clear_error(tmp_path):
    with pytest.raises(ValueError, match="asr_snr_db"):
        EnvConfig(asr="channel", asr_snr_db=[30.0, 10.0])
    with pytest.raises(ValueError, match="asr_channel"):
        EnvConfig(asr="channel", asr_channel=str(tmp_path / "none.json"))
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(ValueError, match="not an ASR channel model"):
        make_run_env(EnvConfig(asr="channel", asr_channel=str(bad)), batch_size=2, seed=0)
    with pytest.raises(ValueError, match="hearing must be"):
        make_env(game="standard", batch_size=(2,), hearing=object())
