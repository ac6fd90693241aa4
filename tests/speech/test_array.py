"""Pepper's microphone array in a simulated room, with the real parts: pyroomacoustics' image-source room, flite and
espeak-ng voices, WebRTC's VAD, SRP-PHAT and pocketsphinx. The geometry, the room's reverberation, the SNR at the
array, the beams, the voice activity detection and the array's own direction estimate."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ncbot.speech import SAMPLE_RATE


@pytest.fixture(scope="module")
def voices():
    from ncbot.speech.fit import babble_texts
    from ncbot.speech.roundtrip import babble_pool
    from ncbot.speech.trial_sets import TUNING_BABBLE_VOICES
    from ncbot.speech.tts import SpeechCache

    return {"cache": SpeechCache(), "pool": babble_pool(babble_texts()[:12], TUNING_BABBLE_VOICES)}


def _room(rt60=0.3, talkers=((0.3, 2.0, 1.6),), mouth=(1.21, 0.0, 1.5)):
    from ncbot.speech.room import Room, RoomLayout

    return Room(RoomLayout((7.0, 6.0, 3.0), rt60, (2.5, 3.0), mouth, talkers))


def test_pepper_head_microphones_sit_on_the_head_and_turn_with_it():
    from ncbot.speech.array import HOME_HEAD, HeadPose, mic_positions

    mics = mic_positions(HeadPose((0.0, 0.0, 1.0)))
    assert mics.shape == (3, 4)
    assert np.allclose(mics[2], 1.209) and np.isclose(mics[0, 0] - mics[0, 2], 0.066)  # on top, front ahead of rear
    assert np.isclose(mics[1, 0] - mics[1, 1], 0.068)  # front left is left of front right
    looking_down = mic_positions(HeadPose((0.0, 0.0, 1.0), pitch=math.radians(30)))
    assert looking_down[0].mean() > 0.09  # pitching down carries the top of the head forward
    turned = mic_positions(HeadPose((0.0, 0.0, 1.0), yaw=math.pi / 2))
    assert np.allclose(turned[1, 0], mics[0, 0]) and np.allclose(turned[2], mics[2])
    home = mic_positions(HOME_HEAD)
    assert 1.17 < home[2].mean() < 1.22  # Pepper is 1.21 m tall; the mics are near the top of its head
    doubled = mic_positions(HeadPose((0.0, 0.0, 1.0)), scale=2.0)
    assert np.isclose(doubled[0, 0] - doubled[0, 2], 0.132)


def test_the_room_rings_as_long_as_asked_and_keeps_everyone_inside():
    from ncbot.speech.room import Room, RoomLayout

    rooms = {rt60: _room(rt60) for rt60 in (0.3, 0.7)}
    for rt60, room in rooms.items():
        assert abs(room.measured_rt60 - rt60) <= 0.1 * rt60 + 1e-9  # calibrated to the simulation's own decay
        assert len(room.rirs) == 2 and len(room.rirs[0]) == 4
    assert rooms[0.7].rirs[0][0].size > rooms[0.3].rirs[0][0].size
    with pytest.raises(ValueError, match=r"talker 0 at \(9.0, 0.0, 1.6\) m .* is not inside the 7 x 6 x 3 m room"):
        Room(RoomLayout((7.0, 6.0, 3.0), 0.4, (2.5, 3.0), (1.21, 0.0, 1.5), ((9.0, 0.0, 1.6),)))


def test_the_array_hears_four_signals_with_the_reply_at_the_asked_snr(voices):
    from ncbot.speech.listening import ArrayRecorder, GAP_SECONDS

    clean, _ = voices["cache"].speak("yes please", _voice())
    room = _room()
    for kind in ("babble", "white"):
        recorder = ArrayRecorder(room, kind, voices["pool"])
        speech, noise, (start, stop) = recorder.parts(clean, 5.0, np.random.default_rng(1))
        snr = 10 * np.log10(np.mean(speech[:, start:stop] ** 2) / np.mean(noise[:, start:stop] ** 2))
        assert abs(snr - 5.0) < 1e-6 and speech.shape[0] == 4 and stop - start == clean.size
        assert GAP_SECONDS[0] * SAMPLE_RATE <= start <= GAP_SECONDS[1] * SAMPLE_RATE
        assert np.all(speech[:, :start - 10] == 0)  # the turn-taking gap holds noise alone
        take = recorder.record(clean, 5.0, np.random.default_rng(1))
        assert take.channels.dtype == np.int16 and take.channels.shape == speech.shape
        assert np.array_equal(take.channels, recorder.record(clean, 5.0, np.random.default_rng(1)).channels)
        assert not np.array_equal(take.channels[0], take.channels[3])  # four microphones, four signals
    clean_take = ArrayRecorder(room, "babble", voices["pool"]).record(clean, None, np.random.default_rng(2))
    assert np.abs(clean_take.channels[:, :clean_take.speech_span[0] - 10]).max() == 0  # no noise: silence around


def test_diffuse_noise_has_a_diffuse_fields_coherence():
    from ncbot.speech.listening import diffuse_noise
    from scipy.signal import coherence

    mics = np.array([[0.0, 0.1, 0.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    noise = diffuse_noise(mics, 4 * SAMPLE_RATE, np.random.default_rng(0))
    frequencies, near = coherence(noise[0], noise[1], fs=SAMPLE_RATE, nperseg=512)
    _, far = coherence(noise[0], noise[2], fs=SAMPLE_RATE, nperseg=512)
    low = (frequencies > 100) & (frequencies < 500)
    assert near[low].mean() > 0.8 > 0.4 > far[low].mean()  # sin(kd)/(kd): close microphones hear alike
    assert np.allclose(noise.std(axis=1), noise.std(axis=1).mean(), rtol=0.05)


def test_voice_activity_detection_cuts_the_reply_out_of_the_window(voices):
    from ncbot.speech.listening import ArrayRecorder
    from ncbot.speech.vad import speech_span

    clean, _ = voices["cache"].speak("my name is sam", _voice())
    take = ArrayRecorder(_room(), "white", []).record(clean, 20.0, np.random.default_rng(3))
    start, stop = speech_span(take.channels[0].astype(float))
    true_start, true_stop = take.speech_span
    assert abs(start - true_start) < 0.3 * SAMPLE_RATE and abs(stop - true_stop) < 0.45 * SAMPLE_RATE
    assert speech_span(np.zeros(SAMPLE_RATE)) is None  # silence: nothing to hear
    assert speech_span(np.random.default_rng(0).standard_normal(SAMPLE_RATE)) is None  # steady hiss is not speech


def test_the_array_finds_the_person_by_itself_when_the_camera_cannot(voices):
    from ncbot.speech.array import angle_between
    from ncbot.speech.doa import estimate_direction
    from ncbot.speech.ears import ArrayEars
    from ncbot.speech.enhance import Enhancement

    clean, _ = voices["cache"].speak("yes i would like to play", _voice())
    room = _room(0.4, talkers=())
    ears = ArrayEars(room, "white", enhancement=Enhancement.parse("mvdr+vad"))
    take = ears.take(clean, 15.0, np.random.default_rng(4))
    assert take.enhanced.steered_by == "doa" and take.beam_error_deg < 10.0
    side = _room(0.4, talkers=(), mouth=(0.6, 1.1, 1.5))  # a person to the robot's left front
    channels = ArrayEars(side, "white").recorder.record(clean, 15.0, np.random.default_rng(5)).channels
    assert angle_between(estimate_direction(channels, side.mics), side.direction_to(side.layout.mouth)) < 10.0
    ears.camera_direction = room.direction_to(np.array([1.21, 0.0, 1.5]))
    assert ears.take(clean, 15.0, np.random.default_rng(4)).enhanced.steered_by == "camera"


def test_the_beam_hears_through_a_talker_that_one_microphone_cannot(voices):
    """At 0 dB against one talker beside the robot, pocketsphinx hears the person through the MVDR beam far better
    than through one microphone (same windows, same recogniser settings, seeded)."""
    from ncbot.speech.align import word_errors
    from ncbot.speech.asr import Recogniser
    from ncbot.speech.ears import ArrayEars
    from ncbot.speech.enhance import Enhancement

    room = _room(0.3, talkers=((0.2, 1.8, 1.6),))
    texts = ["yes please", "my name is sam", "hello", "no thank you", "yes i would like to play", "good game"]
    errors = {}
    for spec in ("none+vad", "mvdr+vad"):
        ears = ArrayEars(room, "babble", voices["pool"], Enhancement.parse(spec), room.direction_to(room.layout.mouth))
        recogniser, wrong = Recogniser(), 0
        for i, text in enumerate(texts):
            clean, _ = voices["cache"].speak(text, _voice(i))
            take = ears.take(clean, 0.0, np.random.default_rng([6, i]))
            wrong += word_errors(text.split(), recogniser.recognise(take.samples).words)
            assert take.samples.dtype == np.int16 and take.enhanced.cpu_s > 0
        errors[spec] = wrong / sum(len(t.split()) for t in texts)
    assert errors["mvdr+vad"] <= errors["none+vad"] - 0.25, errors


def test_enhancement_specs_read_and_bad_ones_are_one_line():
    from ncbot.speech.enhance import Enhancement

    assert Enhancement.parse("mvdr+vad") == Enhancement()
    assert Enhancement.parse("ds+postfilter+doa") == Enhancement("ds", False, True, "doa")
    for spec in ("mvdr+vad", "none", "ds+vad+postfilter+doa"):
        assert Enhancement.parse(spec).spec == spec
    for bad in ("gsc+vad", "mvdr+loud", "mvdr+vad+vad", ""):
        with pytest.raises(ValueError, match="is not beamformer"):
            Enhancement.parse(bad)


def test_a_rooms_layout_is_drawn_from_its_seed_with_the_bystander_among_the_talkers():
    from ncbot.speech.acoustic_scene import TALKER_APART_DEG, AcousticRanges, draw_layout

    ranges = AcousticRanges(room_size=((8, 12), (6, 9), (3, 4)), rt60=(0.5, 0.9), talkers=(3, 5))
    first = draw_layout(ranges, np.random.default_rng(7), bystanders=((0.9, 0.9, 1.6),))
    assert first == draw_layout(ranges, np.random.default_rng(7), bystanders=((0.9, 0.9, 1.6),))
    assert first != draw_layout(ranges, np.random.default_rng(8), bystanders=((0.9, 0.9, 1.6),))
    assert first.talkers[0] == (0.9, 0.9, 1.6) and 3 <= len(first.talkers) <= 5 and 0.5 <= first.rt60 <= 0.9
    person = math.atan2(first.mouth[1], first.mouth[0] + 0.038)
    for x, y, _ in first.talkers[1:]:
        apart = abs((math.degrees(math.atan2(y, x + 0.038) - person) + 180) % 360 - 180)
        assert apart >= TALKER_APART_DEG - 1e-6
    fixed = AcousticRanges(talker_positions=((2.0, -1.0, 1.7),))
    assert draw_layout(fixed, np.random.default_rng(0)).talkers == ((2.0, -1.0, 1.7),)
    for bad, needle in ((AcousticRanges(rt60=(0.9, 0.5)), "room_rt60"), (AcousticRanges(talkers=(0, 20)), "speech_talkers"),
                        (AcousticRanges(room_size=((2.0, 3.0), (5, 6), (3, 3))), "room_size"),
                        (AcousticRanges(talker_positions=((1.0, 2.0),)), "talker_positions")):
        with pytest.raises(ValueError, match=needle):
            bad.validate("hall")


def test_the_four_channels_survive_an_mcap_file_and_mono_stays_mono(tmp_path):
    from ncbot.logs import EpisodeLogger, LogReader
    from ncbot.speech.audio import channels_from_raw_audio, raw_audio, samples_from_raw_audio

    channels = (np.random.default_rng(0).standard_normal((4, 3200)) * 3000).astype(np.int16)
    with EpisodeLogger(tmp_path) as logger:
        logger.log_audio(raw_audio(channels), topic="/audio/user", t=0.5)
        logger.log_audio(raw_audio(channels[2]), topic="/audio/user/enhanced", t=0.5)
    array, mono = [m.data for m in LogReader(tmp_path).messages(["/audio/user", "/audio/user/enhanced"])]
    assert array.number_of_channels == 4 and np.array_equal(channels_from_raw_audio(array), channels)
    assert np.array_equal(samples_from_raw_audio(mono), channels[2])
    with pytest.raises(ValueError, match="expected mono audio, got 4 channels"):
        samples_from_raw_audio(array)


def _voice(i: int = 0):
    from ncbot.speech.trial_sets import TUNING_VOICES

    return TUNING_VOICES[i % len(TUNING_VOICES)]
