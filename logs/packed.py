"""The packed form of an episode's steps: one fixed-width binary row per step, one message per episode.

Why: training and evaluation produce thousands of episodes per minute, and one JSON message per action cost
several times the env step itself (measured in logs/README.md). Here a whole batch is turned into rows with
one numpy call per field, and an episode is written as the bytes of its rows in a protobuf
`ncbot.EpisodeSteps` message (zstd then squeezes the many zero bytes). The row layout is a numpy structured
dtype (`row_dtype`); every message names it by version and sizes (`layout`, e.g. "ncbot-rows-v1:18,73,9,39"),
so a reader knows exactly how to cut the bytes.

Row fields: act, reward, step (env turn counter), user_act, user_move, user_utterance, mask / win / a_hat
(bit-packed over the actions: action mask, winning available actions, available actions with negative
look-ahead reward), cells (board after the step), q (float16 Q-values, 0 where unavailable), obs (float16
features), conf (float16 value of each vocabulary word's feature after the user spoke = ASR confidence).
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from ncbot.logs.names import NameTables

SCHEMA_NAME = "ncbot.EpisodeSteps"


def row_dtype(n_actions: int, n_features: int, n_cells: int, n_words: int) -> np.dtype:
    """The structured dtype of one step row for a game of these sizes."""
    bits = (n_actions + 7) // 8
    return np.dtype([("act", "<u2"), ("reward", "<f4"), ("step", "<i2"), ("user_act", "i1"), ("user_move", "i1"),
                     ("user_utterance", "<i2"), ("mask", "u1", (bits,)), ("win", "u1", (bits,)),
                     ("a_hat", "u1", (bits,)), ("cells", "u1", (n_cells,)), ("q", "<f2", (n_actions,)),
                     ("obs", "<f2", (n_features,)), ("conf", "<f2", (n_words,))])


LAYOUT_PREFIX = "ncbot-rows-v1:"


def layout_text(dtype: np.dtype) -> str:
    """The layout tag written in every message: version and the four sizes that fix `row_dtype`."""
    sizes = (dtype.fields["q"][0].shape[0], dtype.fields["obs"][0].shape[0], dtype.fields["cells"][0].shape[0],
             dtype.fields["conf"][0].shape[0])
    return LAYOUT_PREFIX + ",".join(map(str, sizes))


def dtype_from_layout(text: str) -> np.dtype:
    if not text.startswith(LAYOUT_PREFIX):
        raise ValueError(f"unknown packed step layout {text[:40]!r}: this ncbot reads {LAYOUT_PREFIX}A,F,C,W "
                         "(the file was written by another ncbot version)")
    return row_dtype(*(int(size) for size in text[len(LAYOUT_PREFIX):].split(",")))


def batch_rows(arrays: dict[str, np.ndarray], names: NameTables) -> tuple[np.ndarray, list[str]]:
    """All (B, T) steps of a batch as rows, and the names of the optional fields that were present."""
    batch, steps = arrays["action"].shape[:2]
    mask = arrays["action_mask"].astype(bool).reshape(batch, steps, -1)
    n_actions = mask.shape[-1]
    features = arrays.get("observation")
    word_columns = [column for _, column in names.word_columns()]
    next_features = arrays.get("next.observation")
    n_words = len(word_columns) if next_features is not None else 0
    board = arrays["next.board"].reshape(batch, steps, -1)
    dtype = row_dtype(n_actions, 0 if features is None else features.shape[-1], board.shape[-1], n_words)
    rows = np.zeros((batch, steps), dtype)
    present = []
    action = arrays["action"]
    rows["act"] = (action.argmax(-1) if action.ndim == 3 and action.shape[-1] > 1 else action).reshape(batch, steps)
    rows["reward"] = arrays["next.reward"].reshape(batch, steps)
    rows["mask"] = np.packbits(mask, axis=-1, bitorder="little")
    rows["cells"] = board
    for key, field in (("turn", "step"), ("next.user_act", "user_act"), ("next.user_move", "user_move"),
                       ("next.user_utterance", "user_utterance")):
        if key in arrays:
            rows[field] = arrays[key].reshape(batch, steps)
            present.append(field)
        else:
            rows[field] = -1
    if "winning_actions" in arrays:
        rows["win"] = np.packbits(arrays["winning_actions"].astype(bool) & mask, axis=-1, bitorder="little")
        present.append("win")
    if "lookahead_reward" in arrays:
        rows["a_hat"] = np.packbits(mask & (arrays["lookahead_reward"] < 0), axis=-1, bitorder="little")
        present.append("a_hat")
    if "action_value" in arrays:
        rows["q"] = np.where(mask, arrays["action_value"], 0.0)
        present.append("q")
    if features is not None:
        rows["obs"] = features
        present.append("obs")
    if n_words:
        rows["conf"] = next_features[..., word_columns]
        present.append("conf")
    return rows, present


@lru_cache(maxsize=1)
def message_class() -> Any:
    """The protobuf class of `ncbot.EpisodeSteps`, built at run time (no protoc step)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    proto = descriptor_pb2.FileDescriptorProto(name="ncbot/episode_steps.proto", package="ncbot", syntax="proto3")
    message = proto.message_type.add(name="EpisodeSteps")
    field = descriptor_pb2.FieldDescriptorProto
    for number, (name, kind, label) in enumerate([
            ("episode", field.TYPE_INT64, field.LABEL_OPTIONAL), ("n", field.TYPE_UINT32, field.LABEL_OPTIONAL),
            ("layout", field.TYPE_STRING, field.LABEL_OPTIONAL), ("present", field.TYPE_STRING, field.LABEL_REPEATED),
            ("rows", field.TYPE_BYTES, field.LABEL_OPTIONAL)], start=1):
        message.field.add(name=name, number=number, type=kind, label=label)
    pool = descriptor_pool.DescriptorPool()
    pool.Add(proto)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(SCHEMA_NAME))


def descriptor_set() -> bytes:
    """The FileDescriptorSet registered as the MCAP schema of the packed channel."""
    from google.protobuf import descriptor_pb2

    proto = descriptor_pb2.FileDescriptorProto()
    message_class().DESCRIPTOR.file.CopyToProto(proto)
    return descriptor_pb2.FileDescriptorSet(file=[proto]).SerializeToString()


def encode(episode_id: int, n: int, dtype: np.dtype, rows: bytes, present: list[str]) -> bytes:
    """One episode's `n` rows (their raw bytes, layout `dtype`) as a serialised `ncbot.EpisodeSteps`."""
    return message_class()(episode=episode_id, n=n, layout=layout_text(dtype), present=present,
                           rows=rows).SerializeToString()


def decode(message: Any) -> tuple[int, np.ndarray, set[str]]:
    """(episode id, rows, present fields) of a decoded `ncbot.EpisodeSteps` message."""
    rows = np.frombuffer(message.rows, dtype_from_layout(message.layout))
    if len(rows) != message.n:
        raise ValueError(f"packed episode {message.episode} holds {len(rows)} rows, expected {message.n}")
    return int(message.episode), rows, set(message.present)


def unpack_steps(rows: np.ndarray, present: set[str], names: NameTables) -> list[dict[str, Any]]:
    """The rows as one dict per step (keys: step, act, reward, mask, A, A_hat, q, on, val, cells, user_act,
    user_utterance, user_move, words), the same fields as /step, /dialogue and /board."""
    n_actions = rows.dtype.fields["q"][0].shape[0]
    mask = np.unpackbits(rows["mask"], axis=-1, bitorder="little")[:, :n_actions].astype(bool)
    win = np.unpackbits(rows["win"], axis=-1, bitorder="little")[:, :n_actions].astype(bool)
    a_hat = np.unpackbits(rows["a_hat"], axis=-1, bitorder="little")[:, :n_actions].astype(bool)
    q_values = np.round(rows["q"].astype(np.float64), 3)
    features = rows["obs"].astype(np.float64)
    confidences = np.round(rows["conf"].astype(np.float64), 3)
    word_columns = names.word_columns()
    table = names.utterance_words() if "conf" in present else None
    result = []
    for i, row in enumerate(rows):
        available = np.flatnonzero(mask[i]).tolist()
        step: dict[str, Any] = {"step": int(row["step"]) if "step" in present else i, "act": int(row["act"]),
                                "reward": round(float(row["reward"]), 4), "mask": available}
        if "win" in present:
            step["A"] = np.flatnonzero(win[i]).tolist() or available
        if "a_hat" in present:
            step["A_hat"] = np.flatnonzero(a_hat[i]).tolist()
        if "q" in present:
            step["q"] = q_values[i, available].tolist()
        if "obs" in present:
            values = features[i]
            nonzero = np.flatnonzero(values)
            ones = values[nonzero] == 1.0
            step["on"] = nonzero[ones].tolist()
            step["val"] = [[int(k), round(float(values[k]), 3)] for k in nonzero[~ones]]
        step["cells"] = (row["cells"] + 48).tobytes().decode()
        for name in ("user_act", "user_utterance", "user_move"):
            step[name] = int(row[name])
        words = []
        utterance = step["user_utterance"]
        if table is not None and step["user_act"] >= 0 and 0 <= utterance < table.shape[0] - 1:
            words = [[word_columns[k][0], float(confidences[i, k])] for k in np.flatnonzero(table[utterance])]
        step["words"] = words
        result.append(step)
    return result
