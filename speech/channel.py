"""An ASR channel model: which words the recogniser hears for the words said, and with what confidence, per
noise kind and SNR, fitted from real round trips (TTS -> noise -> pocketsphinx) and sampled in batches.

Why: the real recogniser costs ~0.05 CPU s per utterance, far too slow for a training env stepping thousands of
games a second; sampling this model costs microseconds per batch and reproduces the recogniser's confusions,
deletions, insertions and its per-word confidence distribution (figures in docs/speech.md).

Model (counts, so the file is small and exact; probabilities are made at load): per (noise kind, SNR level)
``substitutions[said, heard]`` (heard index V = deleted), ``insertions[heard]`` (words heard where nothing was
said), confidence histograms of correctly heard words (per word), of substituted and of inserted words.
A query SNR between two fitted levels draws each game's level from the two neighbours in proportion (a mixture).
"""
from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ncbot.fileio.atomic import atomic_write_text
from ncbot.speech.align import align
from ncbot.speech.asr import Heard
from ncbot.speech.noise import NOISE_KINDS

BINS = 20  # confidence histogram bins over [0, 1]
CLEAN_DB = 40.0  # where "clean" sits on the SNR axis when interpolating between levels
PRIOR = 2.0  # pseudo-counts of the pooled confidence histogram added to each word's own
FORMAT = "ncbot-asr-channel/1"
DEFAULT_CHANNEL = Path(__file__).with_name("data") / "asr_channel.json"


@dataclass
class ChannelModel:
    """Counts per noise kind K and SNR level S (``snr_db[s]`` None = clean) over the vocabulary ``words`` (V)."""

    words: tuple[str, ...]
    kinds: tuple[str, ...]
    snr_db: tuple[float | None, ...]
    substitutions: np.ndarray  # (K, S, V, V + 1) int: said word -> heard word, column V = deleted
    insertions: np.ndarray  # (K, S, V) int: words heard with no said word
    correct_confidence: np.ndarray  # (K, S, V, BINS) int: confidences of correctly heard words
    substituted_confidence: np.ndarray  # (K, S, BINS) int
    inserted_confidence: np.ndarray  # (K, S, BINS) int
    utterances: np.ndarray  # (K, S) int: round trips counted
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        k, s, v = len(self.kinds), len(self.snr_db), len(self.words)
        shapes = {
            "substitutions": (k, s, v, v + 1),
            "insertions": (k, s, v),
            "correct_confidence": (k, s, v, BINS),
            "substituted_confidence": (k, s, BINS),
            "inserted_confidence": (k, s, BINS),
            "utterances": (k, s),
        }
        for name, shape in shapes.items():
            value = np.asarray(getattr(self, name), dtype=np.int64)
            if value.shape != shape:
                raise ValueError(f"channel model {name} has shape {value.shape}, expected {shape}")
            setattr(self, name, value)
        unknown = [kind for kind in self.kinds if kind not in NOISE_KINDS]
        if unknown or not self.kinds:
            raise ValueError(f"channel model kinds must be among {', '.join(NOISE_KINDS)}, got {self.kinds}")
        positions = [CLEAN_DB if s is None else float(s) for s in self.snr_db]
        if not positions or len(set(positions)) != len(positions) or max(positions) > CLEAN_DB:
            raise ValueError(f"channel model SNR levels must be distinct and at most {CLEAN_DB} dB, got {self.snr_db}")

    # ----------------------------------------------------------------------------------------------- fitting
    @classmethod
    def fit(
        cls,
        trips: Iterable[tuple[str, float | None, Sequence[str], Heard]],
        words: Sequence[str],
        snr_db: Sequence[float | None],
        kinds: Sequence[str] = NOISE_KINDS,
        meta: dict[str, Any] | None = None,
    ) -> ChannelModel:
        """Count ``(kind, snr_db, said words, heard)`` round trips; a clean trip (None) counts for every kind."""
        words, kinds, snr_db = tuple(words), tuple(kinds), tuple(snr_db)
        index = {w: i for i, w in enumerate(words)}
        k, s, v = len(kinds), len(snr_db), len(words)
        model = cls(
            words, kinds, snr_db,
            np.zeros((k, s, v, v + 1), np.int64), np.zeros((k, s, v), np.int64),
            np.zeros((k, s, v, BINS), np.int64), np.zeros((k, s, BINS), np.int64),
            np.zeros((k, s, BINS), np.int64), np.zeros((k, s), np.int64), dict(meta or {}),
        )
        for kind, snr, said, heard in trips:
            if snr not in snr_db:
                raise ValueError(f"round trip at SNR {snr} is not one of the model's levels {snr_db}")
            level = snr_db.index(snr)
            for kind_index in range(k) if snr is None else [kinds.index(kind)]:
                model._count(kind_index, level, said, heard, index)
        return model

    def _count(self, k: int, s: int, said: Sequence[str], heard: Heard, index: dict[str, int]) -> None:
        v = len(self.words)
        for word in list(said) + list(heard.words):
            if word not in index:
                raise ValueError(f"word {word!r} is not in the channel model's vocabulary")
        self.utterances[k, s] += 1
        for i, j in align(said, heard.words):
            bin_ = None if j is None else min(int(heard.confidences[j] * BINS), BINS - 1)
            if j is None:
                self.substitutions[k, s, index[said[i]], v] += 1
            elif i is None:
                self.insertions[k, s, index[heard.words[j]]] += 1
                self.inserted_confidence[k, s, bin_] += 1
            else:
                self.substitutions[k, s, index[said[i]], index[heard.words[j]]] += 1
                if said[i] == heard.words[j]:
                    self.correct_confidence[k, s, index[said[i]], bin_] += 1
                else:
                    self.substituted_confidence[k, s, bin_] += 1

    def summary(self) -> list[dict[str, Any]]:
        """Per (kind, level): round trips, words said, word error rate, deletion and insertion rates, and the
        mean confidence of correctly heard words (bin centres), as fitted."""
        v, centres = len(self.words), (np.arange(BINS) + 0.5) / BINS
        rows = []
        for k, kind in enumerate(self.kinds):
            for s, snr in enumerate(self.snr_db):
                counts = self.substitutions[k, s]
                said = int(counts.sum())
                correct = int(np.trace(counts[:, :v]))
                inserted = int(self.insertions[k, s].sum())
                histogram = self.correct_confidence[k, s].sum(0)
                rows.append({
                    "kind": kind, "snr_db": snr, "round_trips": int(self.utterances[k, s]), "words": said,
                    "word_error_rate": (said - correct + inserted) / max(said, 1),
                    "deleted": int(counts[:, v].sum()) / max(said, 1), "inserted": inserted / max(said, 1),
                    "correct_confidence": float(histogram @ centres / max(histogram.sum(), 1)),
                })
        return rows

    # ------------------------------------------------------------------------------------------- save / load
    def save(self, path: str | Path) -> Path:
        """Write the model as JSON atomically (a temporary file in the same folder, then renamed)."""
        data = {
            "format": FORMAT,
            "words": list(self.words),
            "kinds": list(self.kinds),
            "snr_db": list(self.snr_db),
            "bins": BINS,
            "meta": self.meta,
        }
        for name in ("substitutions", "insertions", "correct_confidence", "substituted_confidence",
                     "inserted_confidence", "utterances"):
            data[name] = getattr(self, name).tolist()
        return atomic_write_text(json.dumps(data, separators=(",", ":")), path)

    @classmethod
    def load(cls, path: str | Path = DEFAULT_CHANNEL) -> ChannelModel:
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"ASR channel model {path} not found: fit one with `python -m ncbot.speech.fit`")
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as error:
            raise ValueError(f"{path} is not a JSON ASR channel model ({error})") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT or data.get("bins") != BINS:
            raise ValueError(f"{path} is not an ASR channel model of format {FORMAT} with {BINS} bins")
        return cls(
            tuple(data["words"]), tuple(data["kinds"]), tuple(data["snr_db"]),
            *(np.array(data[name], dtype=np.int64) for name in (
                "substitutions", "insertions", "correct_confidence", "substituted_confidence",
                "inserted_confidence", "utterances")),
            meta=data.get("meta", {}),
        )

    # ---------------------------------------------------------------------------------------------- sampling
    def encode(self, texts: Sequence[str], width: int | None = None) -> torch.Tensor:
        """Word ids (U, W) int64 of ``texts`` padded with V (the "no word" id); unknown words raise ValueError."""
        index = {w: i for i, w in enumerate(self.words)}
        split = [text.split() for text in texts]
        width = max([1, *(len(s) for s in split)]) if width is None else width
        ids = torch.full((len(texts), width), len(self.words), dtype=torch.int64)
        for row, said in enumerate(split):
            if len(said) > width:
                raise ValueError(f"utterance {texts[row]!r} has more than {width} words")
            for col, word in enumerate(said):
                if word not in index:
                    raise ValueError(f"word {word!r} is not in the channel model's vocabulary")
                ids[row, col] = index[word]
        return ids

    def sample(
        self, said: torch.Tensor, snr_db: torch.Tensor | float | None, kind: str = "white",
        generator: torch.Generator | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Heard word ids and confidences for a batch of said word ids (B, W) (padding V) at ``snr_db``
        (scalar or (B,); None or inf = clean). Returns (B, 2W) int64 ids (V = nothing heard in that slot; slot
        2i is what became of said word i, slot 2i+1 a word inserted after it) and (B, 2W) float32 confidences
        (0 where nothing). Words a game's vocabulary lacks are the caller's to drop: misheard is a valid result."""
        if kind not in self.kinds:
            raise ValueError(f"noise kind {kind!r} is not in the channel model; kinds: {', '.join(self.kinds)}")
        if said.dim() != 2:
            raise ValueError(f"said word ids must be (B, W), got shape {tuple(said.shape)}")
        t = self._tables
        v, batch, width = len(self.words), said.shape[0], said.shape[1]
        level = self._levels(snr_db, batch, generator)  # (B,) row into the tables of this kind
        base = self.kinds.index(kind) * len(self.snr_db) + level
        rand = torch.rand((batch, width, 6), generator=generator)

        def draw(cdf: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
            index = torch.searchsorted(cdf.contiguous(), u.unsqueeze(-1).float().contiguous())
            return index.squeeze(-1).clamp_max(cdf.shape[-1] - 1)

        lvl = base.unsqueeze(1).expand(batch, width)
        heard = draw(t["confusion"][lvl, said], rand[..., 0])  # (B, W) in 0..V
        correct = (heard == said) & (said < v)
        conf_cdf = torch.where(
            correct.unsqueeze(-1), t["correct"][lvl, said.clamp_max(v - 1)], t["substituted"][lvl]
        )
        confidence = (draw(conf_cdf, rand[..., 1]) + rand[..., 2]) / BINS
        confidence = torch.where(heard < v, confidence, torch.zeros(()))
        inserted = (rand[..., 3] < t["insert_rate"][lvl]) & (said < v)
        extra = torch.where(inserted, draw(t["inserted_word"][lvl], rand[..., 4]), torch.full_like(heard, v))
        extra_conf = (draw(t["inserted"][lvl], rand[..., 5]) + torch.rand((batch, width), generator=generator)) / BINS
        extra_conf = torch.where(inserted, extra_conf, torch.zeros(()))
        ids = torch.stack([heard, extra], dim=2).reshape(batch, 2 * width)
        confidences = torch.stack([confidence, extra_conf], dim=2).reshape(batch, 2 * width).float()
        return ids, confidences

    def sample_heard(
        self, texts: Sequence[str], snr_db: float | None, kind: str = "white", generator: torch.Generator | None = None
    ) -> list[Heard]:
        """The same sampling as ``sample`` for a few texts, as ``Heard`` results (tests, benches)."""
        ids, confidences = self.sample(self.encode(texts), snr_db, kind, generator)
        return [
            Heard(tuple(self.words[i] for i in row.tolist() if i < len(self.words)),
                  tuple(c for i, c in zip(row.tolist(), conf.tolist()) if i < len(self.words)))
            for row, conf in zip(ids, confidences)
        ]

    def _levels(self, snr_db: torch.Tensor | float | None, batch: int, generator: torch.Generator | None) -> torch.Tensor:
        """Each game's SNR level: a query between two fitted levels picks one of them in proportion."""
        positions = torch.tensor([CLEAN_DB if s is None else float(s) for s in self.snr_db], dtype=torch.float64)
        query = torch.full((batch,), float("inf"), dtype=torch.float64) if snr_db is None else (
            torch.as_tensor(snr_db, dtype=torch.float64).expand(batch))
        query = query.clamp(float(positions.min()), CLEAN_DB)
        ascending, order = torch.sort(positions)
        if len(ascending) == 1:
            return order.expand(batch).clone()
        upper = torch.searchsorted(ascending, query).clamp(1, len(ascending) - 1)
        low, high = ascending[upper - 1], ascending[upper]
        weight = (query - low) / (high - low)
        pick_high = torch.rand(batch, generator=generator, dtype=torch.float64) < weight
        return order[torch.where(pick_high, upper, upper - 1)]

    @cached_property
    def _tables(self) -> dict[str, torch.Tensor]:
        """Cumulative distributions per (kind, level), flattened to K*S rows, for inverse-CDF sampling."""
        k, s, v = len(self.kinds), len(self.snr_db), len(self.words)
        counts = self.substitutions.astype(np.float64).reshape(k * s, v, v + 1)
        unseen = counts.sum(-1, keepdims=True) == 0
        confusion = np.where(unseen, np.eye(v, v + 1), counts)  # a word never said at a level: heard as itself
        nothing = np.zeros((k * s, 1, v + 1))
        nothing[..., v] = 1.0  # the padding id is always heard as nothing
        confusion = np.concatenate([confusion, nothing], axis=1)
        correct = self.correct_confidence.astype(np.float64).reshape(k * s, v, BINS)
        pooled = correct.sum(1, keepdims=True) + 1.0 / BINS
        correct = correct + PRIOR * pooled / pooled.sum(-1, keepdims=True)
        said_words = self.substitutions.sum((-1, -2)).reshape(k * s)
        inserted = self.insertions.sum(-1).reshape(k * s)

        def cdf(x: np.ndarray) -> torch.Tensor:
            x = x + 1e-12
            return torch.from_numpy(np.cumsum(x / x.sum(-1, keepdims=True), -1)).float()

        return {
            "confusion": cdf(confusion),
            "correct": cdf(correct),
            "substituted": cdf(self.substituted_confidence.reshape(k * s, BINS) + 1.0 / BINS),
            "inserted": cdf(self.inserted_confidence.reshape(k * s, BINS) + 1.0 / BINS),
            "inserted_word": cdf(self.insertions.reshape(k * s, v) + 1e-3),
            "insert_rate": torch.from_numpy(inserted / np.maximum(said_words, 1)).float(),
        }
