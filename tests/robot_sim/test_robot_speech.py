"""The robot game's speech parts with the real engines: the robot's voice, each game's ears (held-out voices and
noise, seeded), the conditions' background noise, and the logger's audio channels (no SAPIEN needed)."""
from __future__ import annotations

import numpy as np
import pytest
import torch


@pytest.fixture(scope="module")
def atrium_speech():
    from ncbot.robot_sim.conditions import load_conditions
    from ncbot.robot_sim.speech import GameSpeech

    return GameSpeech("standard", load_conditions("atrium"))


def test_presets_carry_background_noise_and_yaml_can_set_it(tmp_path):
    from ncbot.robot_sim.conditions import PRESETS, load_conditions

    assert PRESETS["lab"].speech_snr_db is None  # the lab is quiet: clean speech
    assert PRESETS["atrium"].speech_snr_db[1] <= PRESETS["office"].speech_snr_db[0]  # the atrium is the noisier
    assert set(PRESETS["random"].speech_noise) == {"white", "babble"}
    path = tmp_path / "hall.yaml"
    path.write_text("base: office\nspeech_noise: [white]\nspeech_snr_db: [5, 12]\n")
    ranges = load_conditions(path)
    assert ranges.speech_noise == ("white",) and ranges.speech_snr_db == (5, 12)
    for bad, needle in (("speech_noise: [traffic]", "speech_noise must be"), ("speech_snr_db: [20, 5]", "range must be")):
        path.write_text(f"base: lab\n{bad}\n")
        with pytest.raises(ValueError, match=needle):
            load_conditions(path)


def test_each_game_hears_a_held_out_voice_in_seeded_noise(atrium_speech):
    from ncbot.speech.fit import FIT_VOICES

    voices = {atrium_speech.hearing(seed).voice for seed in range(12)}
    assert len(voices) > 1 and not voices & set(FIT_VOICES)  # the fit heard other rates: these are held out
    said = torch.tensor([0, 3, 0])
    results, hearings = [], []
    for seed in (7, 7, 8):  # one game after another, as in a run: each game's ears start fresh
        hearings.append(atrium_speech.hearing(seed))
        results.append(hearings[-1].hear(said))
    first, again, other = hearings
    assert first.voice == again.voice and first.kind == again.kind == "babble"
    assert all(torch.equal(a, b) for a, b in zip(results[0], results[1]))  # one seed, one hearing
    assert all(10.0 <= h.snr_db <= 20.0 for h in first.log)  # atrium: 10-20 dB, drawn per utterance
    assert len({h.snr_db for h in first.log}) == 3
    assert not np.array_equal(first.log[0].samples, other.log[0].samples)  # another game, other noise
    assert np.array_equal(first.log[0].samples, again.log[0].samples)
    assert first.word_error_rate() is not None and len(atrium_speech.cache) >= 2


def test_robot_speaker_speaks_through_the_shared_cache(tmp_path):
    from ncbot.robot_sim.speech import Speaker
    from ncbot.speech.audio import read_wav
    from ncbot.speech.tts import ROBOT_VOICE, SpeechCache

    cache = SpeechCache()
    speaker = Speaker(tmp_path, ROBOT_VOICE, cache)
    first = speaker.say("I take this one.")
    second = speaker.say("I take this one.")
    assert first is second and first.dtype == np.int16 and len(cache) == 1  # synthesised once
    assert speaker.say("") is None and speaker.said[-1] == ""
    assert np.array_equal(read_wav(tmp_path / "utterance-0001.wav"), first)
    assert not Speaker(None).has_audio and Speaker(None).say("hello") is None


def test_logger_writes_audio_and_notes_beside_the_dialogue(tmp_path):
    from ncbot.logs import EpisodeLogger, LogReader
    from ncbot.speech.audio import raw_audio, samples_from_raw_audio

    samples = (np.sin(np.arange(8000) / 5.0) * 8000).astype(np.int16)
    with EpisodeLogger(tmp_path) as logger:
        logger.log_audio(raw_audio(samples), topic="/audio/user", t=1.5)
        with pytest.raises(ValueError, match="RawAudio"):
            logger.log_audio(b"pcm", topic="/audio/user")
        with pytest.raises(ValueError, match="/audio/"):
            logger.log_audio(raw_audio(samples), topic="/dialogue")
        with pytest.raises(ValueError, match="speaker"):
            logger.note_dialogue("robotx", heard="")
    (message,) = list(LogReader(tmp_path).messages(["/audio/user"]))
    assert np.array_equal(samples_from_raw_audio(message.data), samples)
    assert message.data.timestamp.ToNanoseconds() == 1_500_000_000


def test_misheard_replies_go_through_the_env_as_user_acts():
    """In loud white noise most replies are heard wrongly or as nothing: the dialogue goes on (the robot asks
    again), every misheard reply is an ordinary user act, and the game still ends within the env's cap."""
    from ncbot.envs import make_env
    from ncbot.modules.policies.masks import LookaheadOnlyPolicy
    from ncbot.robot_sim.conditions import ConditionRanges
    from ncbot.robot_sim.speech import GameSpeech
    from torchrl.envs.utils import step_mdp

    loud = GameSpeech("standard", ConditionRanges(name="loud", speech_noise=("white",), speech_snr_db=(-5.0, 0.0)))
    hearing = loud.hearing(3)
    env = make_env("standard", batch_size=(1,), seed=3, hearing=hearing)
    policy, td, actions = LookaheadOnlyPolicy(seed=3), env.reset(), []
    for _ in range(100):
        td = env.step(policy(td))
        actions.append(int(td["action"]))
        if bool(td["next", "done"]):
            break
        td = step_mdp(td)
    assert bool(td["next", "done"]) or len(actions) == 100
    misheard = [h for h in hearing.log if h.understood < 0 or hearing.texts[h.understood] != h.said]
    assert len(misheard) >= len(hearing.log) // 3 and hearing.word_error_rate() > 0.3
    assert any(a == b for a, b in zip(actions, actions[1:]))  # the robot asked again


def test_presets_carry_their_rooms_and_a_yaml_file_can_set_and_place_them(tmp_path):
    from ncbot.robot_sim.conditions import PRESETS, load_conditions

    lab, office, atrium = PRESETS["lab"], PRESETS["office"], PRESETS["atrium"]
    assert lab.speech_talkers == (0, 0) and lab.room_rt60[1] <= office.room_rt60[1] <= atrium.room_rt60[0]
    assert atrium.room_size[0][0] >= 15.0 and atrium.speech_talkers[0] >= 4 and atrium.person_mouth_height[0] < 1.3
    path = tmp_path / "hall.yaml"
    path.write_text("base: atrium\nspeech_snr_db: [3, 10]\nroom_rt60: [0.8, 1.0]\nspeech_talkers: [2, 2]\n"
                    "talker_positions: [[2.0, -1.0, 1.7]]\nroom_size: [[12, 14], [9, 10], [4, 5]]\n")
    hall = load_conditions(path)
    assert hall.room_rt60 == (0.8, 1.0) and hall.talker_positions == ((2.0, -1.0, 1.7),)
    assert hall.acoustics().room_size == ((12, 14), (9, 10), (4, 5))
    for bad, needle in (("room_rt60: [1.0, 0.5]", "room_rt60 range must be"),
                        ("room_rt60: [0.05, 0.5]", "room_rt60 must be"),
                        ("room_size: [[2, 3], [5, 6], [3, 3]]", "room_size must"),
                        ("speech_talkers: [0, 30]", "speech_talkers must"),
                        ("talker_positions: [[1.0, 2.0]]", "talker_positions must"),
                        ("speech_snr_db: [5, 10]\nspeech_talkers: [0, 0]", "babble noise needs talkers")):
        path.write_text(f"base: lab\n{bad}\n")
        with pytest.raises(ValueError, match=needle):
            load_conditions(path)


def test_each_game_hears_through_peppers_array_in_its_own_seeded_room():
    """A small office with `ears="array"`: each game's room is drawn from its seed (same seed, same room and the
    same four signals), the beam is aimed by the array itself until the camera's sheet aims it, and the answers
    to "where did you draw?" are heard in the same room."""
    import dataclasses

    from ncbot.robot_sim.conditions import PRESETS
    from ncbot.robot_sim.localise import SheetEstimate
    from ncbot.robot_sim.speech import ROOM_SALT, GameSpeech, aim, speech_summary
    from ncbot.speech.acoustic_scene import draw_layout
    from ncbot.speech.array import HOME_HEAD

    small = dataclasses.replace(PRESETS["office"], room_size=((5.0, 6.0), (4.5, 5.0), (2.7, 2.8)), room_rt60=(0.3, 0.4))
    speech = GameSpeech("standard", small, ears="array", enhancement="mvdr+vad")
    said = torch.tensor([0, 3])
    first, again = speech.hearing(7, HOME_HEAD, 0.0, bystander=True), speech.hearing(7, HOME_HEAD, 0.0, bystander=True)
    other = draw_layout(small.acoustics(), np.random.default_rng([8, ROOM_SALT]), HOME_HEAD)
    assert first.ears.room.layout == again.ears.room.layout != other
    assert first.ears.room.layout.talkers[0] == (0.9, 0.9, 1.6)  # the scene's bystander talks too
    first.hear(said[:1])
    aim(first, SheetEstimate(np.array([0.3, 0.02, 0.75]), 0.0, 0.22, 512))
    first.hear(said[1:])
    again.hear(said)
    assert [h.take.enhanced.steered_by for h in first.log] == ["doa", "camera"]
    assert np.array_equal(first.log[0].take.channels, again.log[0].take.channels)
    assert first.log[0].channels.shape[0] == 4 and first.log[0].samples.ndim == 1
    assert 20 <= first.log[0].snr_db <= 30 and first.log[1].take.beam_error_deg < 20
    ears = speech.answer_ears(7, first)
    assert ears.ears is first.ears and ears.hear_cell("top left").take.channels.shape[0] == 4
    room = speech_summary(first)["room"]
    assert 0.3 <= room["rt60_s"] <= 0.4 and abs(room["measured_rt60_s"] - room["rt60_s"]) <= 0.1 * room["rt60_s"] + 0.01
    assert 2 <= room["talkers"] <= 3
    with pytest.raises(ValueError, match="ears must be one of array, mono"):
        GameSpeech("standard", small, ears="stereo")
