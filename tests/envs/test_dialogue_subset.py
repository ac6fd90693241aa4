"""The dialogue data budget's env option: the act filter and the simulated user learnt from a seeded subset
of k example dialogues, the vocabulary fixed; the authored dialogues 13-24 used only for k > 12.

Real env rollouts hashed with envs/fingerprint.py: k = 12 (the whole dozen) must be bit-identical to the
paper set without a subset, so `env.dialogues: paper` is unchanged by the second dozen.
"""
from __future__ import annotations

from pathlib import Path

import pytest
import torch
import yaml

import ncbot.envs.dialogue as dlg
from ncbot.envs import make_env
from ncbot.envs.fingerprint import fingerprint
from ncbot.pipelines.config import load_config

torch.set_num_threads(1)
ROOT = Path(__file__).resolve().parents[2]
PAPER = {"game": "standard", "first": "alternate", "dialogues": "paper", "taken_squares": "refused"}


def _fingerprint(**kwargs) -> str:
    return fingerprint(kwargs, "mask", steps=300, batch=16)


def test_a_dozen_is_the_paper_set_bit_for_bit_and_more_or_fewer_change_it() -> None:
    paper = _fingerprint(**PAPER)
    assert _fingerprint(**PAPER, dialogue_subset=None) == paper
    assert _fingerprint(**PAPER, dialogue_subset=(12, 7)) == paper  # all 12 in file order, whatever the seed
    assert _fingerprint(**PAPER, dialogue_subset=(24, 0)) != paper
    assert _fingerprint(**PAPER, dialogue_subset=(4, 0)) != paper


@pytest.mark.parametrize("game", ["standard", "ultimate"])
def test_every_subset_keeps_the_vocabulary_and_the_feature_size(game: str) -> None:
    whole = dlg.build_dialogue_model(game, "paper")
    for k in (1, 2, 4, 8, 12, 24):
        model = dlg.build_dialogue_model(game, "paper", (k, 1))
        assert model.words == whole.words and len(model.words) == 39
    sizes = {make_env(game, dialogues="paper", dialogue_subset=(k, 0)).n_features for k in (1, 24)}
    assert sizes == {73 if game == "standard" else 289}
    # fewer dialogues: fewer examples and fewer distinct user utterances; 24: more than the dozen
    one, dozen, two_dozen = (dlg.build_dialogue_model(game, "paper", (k, 0)) for k in (1, 12, 24))
    assert one.n_examples < dozen.n_examples < two_dozen.n_examples
    assert len(one.utterance_texts) < len(dozen.utterance_texts) < len(two_dozen.utterance_texts)


def test_subsets_are_seeded_and_nested_around_the_dozen() -> None:
    chosen = dlg.dialogue_set("paper")
    ids = lambda k, seed: [d["id"] for d in dlg.subset_examples("standard", chosen, k, seed)]  # noqa: E731
    dozen = [d["id"] for d in dlg.load_dialogues("standard", chosen.path)]
    assert ids(4, 3) == ids(4, 3) and ids(4, 3) != ids(4, 4) and set(ids(4, 3)) <= set(dozen)
    assert ids(12, 9) == dozen and ids(13, 0)[:12] == dozen and len(set(ids(24, 0))) == 24
    with pytest.raises(ValueError, match="between 1 and 12 .*compact"):
        dlg.subset_examples("standard", dlg.dialogue_set("compact"), 13, 0)


def test_the_authored_dozen_has_the_paper_shape_and_words() -> None:
    data = yaml.safe_load(dlg.PAPER_EXTRA_FILE.read_text())["dialogues"]
    for game in ("standard", "ultimate"):
        mine = [d for d in data if d["game"] == game]
        assert [d["id"] for d in mine] == [f"{game}-paper-{n}" for n in range(13, 25)]
        for dialogue in mine:
            for turn in dialogue["turns"]:
                if str(turn["user"]).startswith("GameMove"):
                    assert turn["robot"] == "Request(userGameMove)"
    assert "OURS (authored" in dlg.PAPER_EXTRA_FILE.read_text()


def test_a_word_outside_the_fixed_vocabulary_is_one_clear_error() -> None:
    chosen = dlg.dialogue_set("paper")
    dialogue = dict(dlg.load_dialogues("standard", chosen.path)[0])
    dialogue["turns"] = [dict(t) for t in dialogue["turns"]]
    dialogue["turns"][0]["says"] = "hello banana"
    words = dlg.build_dialogue_model("standard", "paper").words
    with pytest.raises(ValueError, match="'banana', outside the paper set's fixed vocabulary of 39 words"):
        dlg.fit_dialogue_model("standard", [dialogue], chosen, vocabulary=words)


def test_config_key_is_validated_in_one_line() -> None:
    config = ROOT / "pipelines" / "configs" / "paper" / "standard_proposed_temporal.yaml"
    assert load_config(config).env.subset is None
    assert load_config(config, ["env.dialogue_subset.k=4", "env.dialogue_subset.seed=2"]).env.subset == (4, 2)
    assert load_config(config, ["env.dialogue_subset={k: null, seed: 3}"]).env.subset is None
    with pytest.raises(ValueError, match=r"^config key 'env.dialogue_subset.k' must be > 0 and <= 24, got 0$"):
        load_config(config, ["env.dialogue_subset.k=0"])
    with pytest.raises(ValueError, match=r"must be <= 12 with env.dialogues: compact"):
        load_config(ROOT / "pipelines" / "configs" / "default.yaml", ["env.dialogue_subset.k=24"])
    with pytest.raises(ValueError, match=r"^unknown config key 'env.dialogue_subset.size'; allowed: k, seed$"):
        load_config(config, ["env.dialogue_subset.size=3"])
