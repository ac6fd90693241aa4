"""The ASR channel model (fitted from real flite -> noise -> pocketsphinx round trips, saved, loaded, sampled)
and the understanding of heard words as the closest example utterance."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from ncbot.speech.align import word_errors
from ncbot.speech.asr import Heard, Recogniser, dialogue_sentences
from ncbot.speech.channel import DEFAULT_CHANNEL, ChannelModel
from ncbot.speech.roundtrip import RoundTripper, Trial
from ncbot.speech.tts import PERSON_VOICE, speak
from ncbot.speech.understand import closest_text, closest_utterance, utterance_table

SENTENCES = ("hello pepper nice to meet you", "can we play a game", "no thank you")


@pytest.fixture(scope="module")
def recogniser() -> Recogniser:
    return Recogniser()


def test_channel_model_fit_save_load_sample(recogniser, tmp_path):
    tripper = RoundTripper(recogniser)
    trials = [Trial(text, PERSON_VOICE, "white", snr, seed) for seed, text in enumerate(SENTENCES)
              for snr in (None, 5.0)]
    trips = tripper.run_all(trials)
    model = ChannelModel.fit(((t.trial.kind, t.trial.snr_db, t.said, t.heard) for t in trips),
                             recogniser.vocabulary, (None, 5.0), ("white",))
    assert model.utterances.tolist() == [[3, 3]]
    assert model.substitutions[0, 0].sum() == sum(len(s.split()) for s in SENTENCES)
    clean, noisy = model.summary()
    assert clean["word_error_rate"] == 0.0 and clean["words"] == 14 and clean["round_trips"] == 3
    assert noisy["correct_confidence"] < clean["correct_confidence"]
    path = model.save(tmp_path / "channel.json")
    loaded = ChannelModel.load(path)
    assert loaded.words == model.words and loaded.snr_db == (None, 5.0)
    assert np.array_equal(loaded.substitutions, model.substitutions)
    assert not list(tmp_path.glob(".channel.json.*"))  # the atomic write leaves no temporary file

    said = loaded.encode(list(SENTENCES) * 4)
    v = len(loaded.words)
    ids, confidences = loaded.sample(said, torch.tensor([float("inf"), 5.0] * 6), "white",
                                     torch.Generator().manual_seed(0))
    assert ids.shape == confidences.shape == (12, 2 * said.shape[1])
    assert ids.dtype == torch.int64 and confidences.dtype == torch.float32
    assert ((ids >= 0) & (ids <= v)).all()
    assert (confidences[ids == v] == 0).all() and ((confidences >= 0) & (confidences <= 1)).all()
    # clean round trips were all heard right, so clean sampling repeats what was said
    assert [h.text for h in loaded.sample_heard(list(SENTENCES), None)] == list(SENTENCES)
    again = loaded.sample(said, 5.0, "white", torch.Generator().manual_seed(1))
    assert torch.equal(again[0], loaded.sample(said, 5.0, "white", torch.Generator().manual_seed(1))[0])
    with pytest.raises(ValueError, match="noise kind"):
        loaded.sample(said, 5.0, "babble")
    with pytest.raises(ValueError, match="vocabulary"):
        loaded.encode(["hello martian"])


def test_channel_model_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="ncbot.speech.fit"):
        ChannelModel.load(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ValueError, match="not a JSON"):
        ChannelModel.load(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ValueError, match="format"):
        ChannelModel.load(tmp_path / "other.json")


def test_committed_channel_model_hears_worse_in_more_noise():
    model = ChannelModel.load(DEFAULT_CHANNEL)
    assert model.meta["round_trips"] >= 2000 and set(model.kinds) == {"white", "babble"}
    texts = ["hello pepper nice to meet you", "your turn pepper", "well done"] * 200
    said = [t.split() for t in texts]
    generator = torch.Generator().manual_seed(0)
    for kind in model.kinds:
        rates = []
        for snr in (None, 20.0, 10.0, 5.0):
            heard = model.sample_heard(texts, snr, kind, generator)
            rates.append(sum(word_errors(s, h.words) for s, h in zip(said, heard)) / sum(map(len, said)))
        assert rates[0] < 0.1 and rates == sorted(rates) and rates[-1] > 0.4


def test_closest_utterance_understands_misheard_words_and_silence(recogniser):
    texts = sorted(set(dialogue_sentences()))
    assert closest_text(["your", "turn", "pepper"], [0.9, 0.9, 0.9], texts) == texts.index("your turn pepper")
    # one word misheard, with low confidence: still the same sentence
    assert closest_text(["hello", "pepper", "nice", "to", "meet", "done"], [0.9] * 5 + [0.1], texts) == texts.index(
        "hello pepper nice to meet you")
    assert closest_text([], [], texts) == -1  # nothing heard: silence
    assert closest_text(["goodbye"], [0.9], texts) == texts.index("goodbye")
    assert closest_text(["goodbye"], [0.05], texts) == -1  # too doubtful to act on: as if nothing was heard
    # a batch through one matrix product, words outside the table (id >= V) ignored
    table = utterance_table(texts, recogniser.vocabulary)
    v = len(recogniser.vocabulary)
    ids = torch.tensor([[recogniser.vocabulary.index("yes"), v], [v, v]])
    result = closest_utterance(ids, torch.tensor([[0.9, 0.0], [0.0, 0.0]]), table)
    assert result.tolist() == [texts.index("yes"), -1]
    # real audio: a clean sentence is understood as itself
    heard = recogniser.recognise(speak("thank you goodbye", PERSON_VOICE))
    assert texts[closest_text(heard.words, heard.confidences, texts)] == "thank you goodbye"


def test_channel_hearing_maps_env_utterances_to_env_word_columns(tmp_path):
    from ncbot.envs import make_env

    from ncbot.speech.hearing import ChannelHearing, heard_tensors

    env = make_env("standard", batch_size=(1,))
    texts = [env.user_utterance(u) for u in range(len(env.model.utterance_texts))]
    model = ChannelModel.load(DEFAULT_CHANNEL)
    hearing = ChannelHearing(model, texts, env.words, snr_db=None, kind="white")
    utterance = torch.arange(len(texts) + 1)  # every utterance, then silence (id U)
    columns, confidence, understood = hearing.hear(utterance, torch.Generator().manual_seed(0))
    assert columns.shape == confidence.shape and columns.shape[0] == len(texts) + 1
    assert int(understood[-1]) == -1 and (columns[-1] == len(env.words)).all()
    # clean: nearly every utterance is heard as its own words and understood as itself
    right = sum(sorted(env.words[c] for c in row.tolist() if c < len(env.words)) == sorted(texts[u].split())
                for u, row in enumerate(columns[:-1]))
    assert right >= len(texts) - 2
    assert (understood[:-1] == torch.arange(len(texts))).float().mean() > 0.9
    noisy = ChannelHearing(model, texts, env.words, snr_db=(5.0, 5.0), kind="babble")
    _, noisy_confidence, _ = noisy.hear(utterance.repeat(20), torch.Generator().manual_seed(0))
    assert noisy_confidence[noisy_confidence > 0].mean() < confidence[confidence > 0].mean() - 0.1
    # the real recogniser's words in the same form
    columns, confidence, understood = heard_tensors(Heard(("your", "turn"), (0.9, 0.8)), texts, env.words)
    assert [env.words[c] for c in columns[0].tolist()] == ["your", "turn"]
    assert texts[int(understood[0])].startswith("your turn")


def test_recogniser_hearing_hears_env_utterances_for_real(recogniser):
    from ncbot.envs.dialogue import build_dialogue_model

    from ncbot.speech.hearing import RecogniserHearing

    dialogue = build_dialogue_model("standard")
    hearing = RecogniserHearing(dialogue.utterance_texts, dialogue.words, recogniser)
    silence = len(dialogue.utterance_texts)
    columns, confidence, understood = hearing.hear(torch.tensor([0, silence, 3]))
    assert columns.shape == confidence.shape and columns.shape[0] == 3
    assert understood.tolist() == [0, -1, 3]  # clean: understood as said; silence stays silence
    assert (columns[1] == len(dialogue.words)).all() and (confidence[1] == 0).all()
    assert [h.said for h in hearing.log] == [dialogue.utterance_texts[0], dialogue.utterance_texts[3]]
    assert all(h.samples.dtype == np.int16 for h in hearing.log)
    assert hearing.word_error_rate() == 0.0 and hearing.mean_confidence() > 0.6
    with pytest.raises(ValueError, match="babble_pool"):
        RecogniserHearing(dialogue.utterance_texts, dialogue.words, recogniser, snr_db=10.0, kind="babble")
