"""Speech with the real engines: flite / espeak-ng speak, pocketsphinx hears (a handful of utterances, fast)."""
from __future__ import annotations

import numpy as np
import pytest

from ncbot.speech import SAMPLE_RATE
from ncbot.speech.align import align, word_errors
from ncbot.speech.asr import Recogniser
from ncbot.speech.noise import add_noise, babble_noise_at, mix_at, white_noise_at
from ncbot.speech.tts import PERSON_VOICE, ROBOT_VOICE, Voice, parse_voice, speak

SENTENCES = ("hello pepper nice to meet you", "can we play a game", "no thank you")


@pytest.fixture(scope="module")
def recogniser() -> Recogniser:
    return Recogniser()


def mean_confidence(recogniser: Recogniser, snr_db: float | None) -> float:
    confidences = []
    for seed, text in enumerate(SENTENCES):
        noisy = add_noise(speak(text, PERSON_VOICE), "white", snr_db, np.random.default_rng(seed))
        confidences += recogniser.recognise(noisy).confidences
    return float(np.mean(confidences)) if confidences else 0.0


def test_tts_gives_16khz_mono_int16_and_two_distinct_voices():
    person, robot = speak("your turn pepper", PERSON_VOICE), speak("your turn pepper", ROBOT_VOICE)
    for samples in (person, robot):
        assert samples.dtype == np.int16 and samples.ndim == 1
        assert 0.5 < samples.size / SAMPLE_RATE < 4.0  # three words at a normal rate
        assert np.abs(samples).max() > 1000  # audible, not silence
    assert person.size != robot.size or not np.array_equal(person, robot)
    # espeak-ng's exact-zero runs (~21 % of its samples) are filled by the noise floor the decoder needs
    assert np.mean(robot == 0) < 0.02
    assert speak("  ", PERSON_VOICE).size == 0
    assert np.array_equal(speak("yes", ROBOT_VOICE), speak("yes", ROBOT_VOICE))  # the floor is seeded


def test_voice_specs_parse_and_reject_unknown_engines_and_voices():
    assert parse_voice("flite:slt") == PERSON_VOICE and parse_voice(ROBOT_VOICE.spec) == ROBOT_VOICE
    assert parse_voice("espeak-ng:en-us+f3@1.2") == Voice("espeak-ng", "en-us+f3", 1.2)
    with pytest.raises(ValueError, match="engine:name"):
        parse_voice("slt")
    with pytest.raises(ValueError, match="rate"):
        parse_voice("flite:slt@9")
    with pytest.raises(ValueError, match="engine"):
        Voice("festival", "kal")
    with pytest.raises(ValueError, match="flite voice"):
        Voice("flite", "nobody")


def test_round_trip_recognises_clean_utterances(recogniser):
    for text in SENTENCES:
        heard = recogniser.recognise(speak(text, PERSON_VOICE))
        assert heard.text == text
        assert len(heard.confidences) == len(heard.words)
        assert all(0.0 <= c <= 1.0 for c in heard.confidences)
        assert np.mean(heard.confidences) > 0.6


def test_confidence_falls_with_noise(recogniser):
    clean, at_20, at_5 = (mean_confidence(recogniser, snr) for snr in (None, 20.0, 5.0))
    assert clean > 0.8
    assert clean > at_5 + 0.25 and at_20 > at_5


def test_misheard_is_a_result_not_a_crash(recogniser):
    silence = recogniser.recognise(np.zeros(SAMPLE_RATE, dtype=np.int16))
    assert len(silence.words) == len(silence.confidences)
    noise = recogniser.recognise(white_noise_at(np.full(SAMPLE_RATE, 300, np.int16), -10.0, np.random.default_rng(0)))
    nothing = recogniser.recognise(np.zeros(0, dtype=np.int16))
    assert nothing.words == ()
    # speech outside the vocabulary comes out as vocabulary words (the small LM forces it)
    unknown = recogniser.recognise(speak("what a lovely day", PERSON_VOICE))
    for heard in (silence, noise, unknown):
        assert set(heard.words) <= set(recogniser.vocabulary)
    with pytest.raises(ValueError, match="int16"):
        recogniser.recognise(np.zeros(100, dtype=np.float32))


def test_recogniser_rejects_words_the_dictionary_lacks():
    with pytest.raises(ValueError, match="not in the pocketsphinx dictionary"):
        Recogniser(["hello zzqxv"])


def test_noise_is_added_at_the_requested_snr():
    rng = np.random.default_rng(0)
    clean = (3000 * np.sin(np.arange(SAMPLE_RATE) / 7.0)).astype(np.int16)
    for snr in (20.0, 10.0, 0.0):
        noisy = white_noise_at(clean, snr, rng)
        noise = noisy.astype(np.float64) - clean
        measured = 10 * np.log10(np.mean(clean.astype(np.float64) ** 2) / np.mean(noise**2))
        assert abs(measured - snr) < 0.3
    babble = babble_noise_at(clean, 10.0, [speak("good game", PERSON_VOICE)], rng)
    assert babble.dtype == np.int16 and babble.shape == clean.shape
    with pytest.raises(ValueError, match="pool"):
        babble_noise_at(clean, 10.0, [], rng)
    with pytest.raises(ValueError, match="noise kind"):
        add_noise(clean, "pink", 10.0, rng)
    with pytest.raises(ValueError, match="shape"):
        mix_at(clean, np.zeros(3), 10.0)


def test_alignment_counts_substitutions_deletions_and_insertions():
    assert word_errors("your turn pepper".split(), "your turn pepper".split()) == 0
    assert word_errors("your turn pepper".split(), "your done".split()) == 2
    assert word_errors("yes".split(), "yes please".split()) == 1
    assert word_errors("well done".split(), []) == 2
    assert align(["a", "b"], ["b"]) == [(0, None), (1, 0)]


def test_audio_round_trips_through_an_mcap_file_and_a_wav(tmp_path):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory
    from mcap_protobuf.writer import Writer

    from ncbot.speech.audio import AUDIO_TOPICS, raw_audio, read_wav, samples_from_raw_audio, write_wav

    said = {"robot": speak("your turn", ROBOT_VOICE), "user": speak("this one", PERSON_VOICE)}
    with open(tmp_path / "game.mcap", "wb") as stream:
        writer = Writer(stream)
        for speaker, samples in said.items():
            writer.write_message(AUDIO_TOPICS[speaker], raw_audio(samples), log_time=1, publish_time=1)
        writer.finish()
    with open(tmp_path / "game.mcap", "rb") as stream:
        messages = list(make_reader(stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    assert {m.channel.topic for m in messages} == {AUDIO_TOPICS[s] for s in said}
    for message in messages:
        assert message.schema.name == "foxglove.RawAudio"
        speaker = next(s for s, t in AUDIO_TOPICS.items() if t == message.channel.topic)
        assert np.array_equal(samples_from_raw_audio(message.decoded_message), said[speaker])
    assert np.array_equal(read_wav(write_wav(tmp_path / "user.wav", said["user"])), said["user"])
    with pytest.raises(ValueError, match="int16"):
        raw_audio(np.zeros(10))
