"""Checkpoints: what they hold (this module alone says so), written atomically (`ncbot.fileio.atomic_path`) and read
back with `weights_only=True`.

Two kinds live in a run folder:
- `checkpoint.pt` (`agent_state`): the final agent (Q-network weights + resolved config + counters): what `ncbot
  eval` loads.
- `checkpoints/step-NNNNNNNNN.pt` (`training_state`): the periodic training state that `ncbot train --resume DIR`
  continues from (`restore`): the Q-network, the learner (objective with its target parameters, optimiser, target
  updater's counter, board-symmetry generator), epsilon, the replay buffer, the hooks' states under their
  `checkpoint_key` (search targets: `teacher`), RNG, counters, evaluation history and the first MCAP file written
  after it.
A crash can leave a stray `.NAME.*.tmp` file but never a half-written checkpoint under its final name; every run
removes such leftovers once it holds the folder's lock (`ncbot.pipelines.run_folder`). Loaders check keys and weight
shapes against the stored config (`load_agent_checkpoint`, `check_training_state`) for a one-line reason.
Checkpoints of the previous layout load: a recurrent objective's state then lacks its value estimator's gamma (a
plain attribute then), which the run's config gives.
"""
from __future__ import annotations

import errno
import os
import pickle
import re
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from ncbot.fileio import atomic_path

FORMAT = "ncbot-dqn/1"
FINAL_NAME = "checkpoint.pt"
MCAP_KEY = "mcap_next_file"  # in a periodic checkpoint: the first log file written after it
PERIODIC_DIR = "checkpoints"
PERIODIC_PATTERN = re.compile(r"^step-(\d{9})\.pt$")


def atomic_save(obj: Any, path: str | os.PathLike) -> Path:
    """torch.save `obj` to `path` atomically."""
    with atomic_path(path) as temp:
        try:
            torch.save(obj, temp)
        except RuntimeError as error:  # torch's zip writer turns a failed write (a full disk) into a RuntimeError
            raise write_error(error, temp, path) from None
    return Path(path)


def write_error(error: RuntimeError, temp: Path, path: str | os.PathLike) -> OSError:
    """The OSError behind a failed torch.save: ENOSPC when the disk is (nearly) full, else EIO naming the file."""
    try:
        stats = os.statvfs(temp.parent)
        full = stats.f_bavail * stats.f_frsize < 2**20
    except OSError:
        full = False
    reason = "no space left on the device" if full else f"torch could not write it ({str(error).splitlines()[0][:100]})"
    return OSError(errno.ENOSPC if full else errno.EIO, f"cannot write {str(path)!r}: {reason}")


def load_checkpoint(path: str | os.PathLike) -> dict[str, Any]:
    """Load an ncbot checkpoint safely (`weights_only=True`); one-line errors for missing or corrupt files."""
    path = Path(path)
    if path.is_dir():
        if not (path / FINAL_NAME).is_file():
            raise FileNotFoundError(f"run folder {str(path)!r} holds no {FINAL_NAME} (expected a checkpoint .pt or a "
                                    "run folder of a finished ncbot train)")
        path = path / FINAL_NAME
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {str(path)!r} not found (expected a .pt file written by ncbot train)")
    if path.suffix != ".pt":
        hint = " (a run config: train it with ncbot train FILE)" if path.suffix in (".yaml", ".yml") else ""
        raise ValueError(f"{str(path)!r} is not a checkpoint{hint}; expected a checkpoint .pt or a run folder")
    not_torch = _not_a_torch_file(path)
    if not_torch is not None:
        raise ValueError(f"checkpoint {str(path)!r} is not a torch file: {not_torch} (expected a .pt file written by "
                         "ncbot train)")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:  # weights_only refused a pickled object: never run, never loaded
        raise ValueError(f"checkpoint {str(path)!r} is not ncbot's: it holds Python objects beyond tensors, "
                         "which ncbot never loads (expected a .pt file written by ncbot train)") from None
    except (Exception, MemoryError) as error:  # noqa: BLE001 - torch's unpickler raises anything on a foreign file
        reason = _reason(error)
        raise ValueError(f"checkpoint {str(path)!r} is damaged ({reason}; expected a .pt file "
                         "written by ncbot train)") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"checkpoint {str(path)!r} is not an ncbot DQN checkpoint (expected format {FORMAT})")
    return data


ZIP_MAGIC = b"PK\x03\x04"  # torch.save's format since torch 1.6
PICKLE_PROTOCOL = 0x80  # the first byte of a pickle (protocol 2+): torch's legacy format and plain pickles


def _not_a_torch_file(path: Path) -> str | None:
    """What the file is when its first bytes are neither a zip archive nor a pickle (torch's two formats), else None:
    such a file is empty, text or other bytes, never a checkpoint, whatever torch's unpickler would say of it."""
    with open(path, "rb") as file:
        head = file.read(512)
    if not head:
        return "it is empty"
    if head.startswith(ZIP_MAGIC) or head[0] == PICKLE_PROTOCOL:
        return None
    text = head.decode("utf-8", errors="ignore")  # a character cut at byte 512 is dropped, not a sign of binary
    if len(text.encode("utf-8")) >= len(head) - 3 and all(c.isprintable() or c.isspace() for c in text):
        return "it is a text file"
    return "its first bytes are neither a zip archive nor a pickle"


def _reason(error: BaseException) -> str:
    """Why torch could not read a file, in a few words (its own messages run over lines and name other causes)."""
    text = str(error)
    if isinstance(error, (EOFError, zipfile.BadZipFile)) or "zip archive" in text or "central directory" in text:
        return "truncated or not a torch zip file"
    if isinstance(error, OSError) and error.errno is not None:
        return error.strerror or "cannot be read"
    if isinstance(error, (MemoryError, OverflowError)):
        return "sizes in the file are absurd"
    first = text.splitlines()[0] if text else type(error).__name__
    return first if len(first) <= 100 else first[:first.rfind(" ", 0, 100)] + " ..."


def periodic_path(run_dir: str | os.PathLike, frames: int) -> Path:
    return Path(run_dir) / PERIODIC_DIR / f"step-{frames:09d}.pt"


def periodic_frames(path: str | os.PathLike) -> int:
    """The frames a periodic checkpoint was saved at, from its name (``periodic_path``'s inverse)."""
    match = PERIODIC_PATTERN.match(Path(path).name)
    if match is None:
        raise ValueError(f"{str(path)!r} is not a periodic checkpoint (expected {PERIODIC_DIR}/step-NNNNNNNNN.pt)")
    return int(match.group(1))


def periodic_checkpoints(run_dir: str | os.PathLike) -> list[Path]:
    """Periodic checkpoints of a run, oldest first."""
    folder = Path(run_dir) / PERIODIC_DIR
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if PERIODIC_PATTERN.match(p.name))


def checkpoint_rate(found: list[Path], since: float | None = None) -> float | None:
    """Frames per second of the process training the run, from its periodic checkpoints (``periodic_checkpoints``):
    between the two newest it wrote, or, with one, from its start. ``since``: when that process started (its lock);
    older checkpoints are an earlier process's (a resumed run), whose pace and pauses say nothing of this one's, so
    the newest of them only gives the frames it resumed from. None when there is nothing to measure."""
    points = [(path.stat().st_mtime, periodic_frames(path)) for path in found]
    if since is not None:
        before = [frames for written, frames in points if written < since]
        points = [(since, before[-1] if before else 0)] + [(w, f) for w, f in points if w >= since]
    if len(points) < 2:
        return None
    (older_time, older_frames), (newer_time, newer_frames) = points[-2:]
    return (newer_frames - older_frames) / (newer_time - older_time) if newer_time > older_time else None


def save_periodic(state: dict[str, Any], run_dir: str | os.PathLike, frames: int, keep: int) -> Path:
    """Write one periodic checkpoint and delete the oldest beyond `keep`."""
    path = atomic_save({"format": FORMAT, **state}, periodic_path(run_dir, frames))
    for old in periodic_checkpoints(run_dir)[:-keep]:
        old.unlink(missing_ok=True)
    return path


AGENT_KEYS = {"config": dict, "n_features": int, "n_actions": int, "qnet": dict}
TRAINING_KEYS = {"learner": dict, "egreedy": dict, "history": list, "frames": int, "updates": int, "episodes": int,
                 "wall_time": (int, float)}
def game_actions(game: str) -> int:
    """The game moves (one per square) + 9 other dialogue acts (docs/env.md): 18 on 3x3, 90 on Ultimate."""
    from ncbot.envs.games import make_game

    return make_game(game).n_cells + 9


def qnet_shapes(n_features: int, n_actions: int, hidden: list[int]) -> dict[str, tuple[int, ...]]:
    """The state-dict shapes `ncbot.modules.networks.qnet.make_qnet` gives these sizes (checked before any weight is loaded)."""
    widths = [n_features, *hidden, n_actions]
    shapes: dict[str, tuple[int, ...]] = {}
    for layer, (inputs, outputs) in enumerate(zip(widths, widths[1:])):
        shapes[f"module.{2 * layer}.weight"] = (outputs, inputs)
        shapes[f"module.{2 * layer}.bias"] = (outputs,)
    return shapes


def _require(data: dict[str, Any], keys: dict[str, Any], path: Path, expected: str) -> None:
    for key, kind in keys.items():
        if key not in data:
            raise ValueError(f"checkpoint {str(path)!r} has no {key!r}; expected {expected}")
        if isinstance(data[key], bool) or not isinstance(data[key], kind):
            raise ValueError(f"checkpoint {str(path)!r}: {key!r} is a {type(data[key]).__name__}; expected {expected}")


def check_qnet(data: dict[str, Any], config: Any, path: Path) -> None:
    """The Q-network weights match the sizes the config builds; ValueError naming the first mismatch."""
    if getattr(config.agent, "memory", "none") != "none":  # the recurrent network of modules/networks/recurrent.py
        from ncbot.modules.networks.recurrent import recurrent_qnet_shapes

        expected = recurrent_qnet_shapes(data["n_features"], data["n_actions"], config.agent)
    else:
        expected = qnet_shapes(data["n_features"], data["n_actions"], list(config.agent.hidden))
    weights = data["qnet"]
    if set(weights) != set(expected):
        missing = sorted(set(expected) - set(weights)) or sorted(set(weights) - set(expected))
        raise ValueError(f"checkpoint {str(path)!r}: Q-network weights do not match agent.hidden="
                         f"{list(config.agent.hidden)} ({len(weights)} tensors, expected {len(expected)}; first "
                         f"difference {missing[0]!r})")
    for key, shape in expected.items():
        got = tuple(getattr(weights[key], "shape", ()))
        if got != shape:
            raise ValueError(f"checkpoint {str(path)!r}: weights {key!r} have shape {got} but its config "
                             f"(agent.hidden={list(config.agent.hidden)}, {data['n_features']} features, "
                             f"{data['n_actions']} actions) expects {shape}")


def load_agent_checkpoint(path: str | os.PathLike) -> tuple[Any, dict[str, Any]]:
    """(validated RunConfig, checkpoint dict) of a saved agent: keys, config and weight shapes checked, so a
    foreign or inconsistent file is one line naming what is wrong instead of a KeyError or size mismatch."""
    from ncbot.pipelines.config import config_from_dict

    data = load_checkpoint(path)
    path = Path(path) / FINAL_NAME if Path(path).is_dir() else Path(path)
    expected = "an ncbot train checkpoint (config, n_features, n_actions, qnet)"
    _require(data, AGENT_KEYS, path, expected)
    try:
        config = config_from_dict(data["config"])
    except ValueError as error:
        raise ValueError(f"checkpoint {str(path)!r} holds an invalid config ({error})") from None
    if data["n_actions"] != game_actions(config.env.game):
        raise ValueError(f"checkpoint {str(path)!r} has {data['n_actions']} actions but plays {config.env.game} "
                         f"({game_actions(config.env.game)} actions)")
    check_qnet(data, config, path)
    return config, data


def check_training_state(state: dict[str, Any], path: Path, config: Any) -> None:
    """A periodic checkpoint can be resumed under `config`: training keys present, Q-network shapes match."""
    expected = "a periodic checkpoint of ncbot train (network, learner, counters, history)"
    _require(state, {**AGENT_KEYS, **TRAINING_KEYS}, path, expected)
    if state.get("cpu_time") is not None:  # absent or None in a checkpoint written before CPU time was kept
        _require(state, {"cpu_time": (int, float)}, path, expected)
    check_qnet(state, config, path)


def newest_resumable(run_dir: str | os.PathLike,
                     check: Callable[[dict[str, Any], Path], None] | None = None) -> tuple[dict[str, Any], Path, list[str]]:
    """(state, path, notes) of the newest periodic checkpoint that loads, holds training state and passes `check`;
    damaged newer ones are skipped (named in `notes`), never deleted. One-line errors when none qualifies."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise FileNotFoundError(f"run folder {str(run_dir)!r} not found (expected the --out folder of an earlier ncbot train)")
    found = periodic_checkpoints(run_dir)
    if not found:
        raise FileNotFoundError(f"no periodic checkpoint in {str(run_dir / PERIODIC_DIR)!r} to resume from")
    notes: list[str] = []
    for candidate in reversed(found):
        try:
            state = load_checkpoint(candidate)
            if "learner" not in state:
                raise ValueError(f"checkpoint {str(candidate)!r} holds no training state to resume from")
            if check is not None:
                check(state, candidate)
        except ValueError as error:
            notes.append(f"skipped {candidate.name}: {error}")
            continue
        return state, candidate, notes
    raise ValueError(f"no checkpoint in {str(run_dir / PERIODIC_DIR)!r} can be resumed from ({len(found)} tried); "
                     f"newest: {notes[0].split(': ', 1)[1]}")


def latest_training_state(run_dir: str | os.PathLike) -> dict[str, Any]:
    """The newest resumable training state of a run, read only (`--resume` goes through pipelines.run_folder,
    which also holds the run's lock and checks the run's identity)."""
    return newest_resumable(run_dir)[0]


# --- what a run's checkpoints hold ---------------------------------------------------------------------------------

def agent_state(config: Any, parts: Any, run_id: str) -> dict[str, Any]:
    """The final agent (`checkpoint.pt`): every tensor on the CPU, so a GPU run's agent loads on any machine."""
    from ncbot.modules.device import to_cpu

    counters = parts.counters
    return agent_checkpoint(config, parts.env.n_features, parts.env.n_actions, to_cpu(parts.qnet.state_dict()),
                            run_id, frames=counters["frames"], updates=counters["updates"],
                            episodes=counters["episodes"])


def agent_checkpoint(config: Any, n_features: int, n_actions: int, qnet: dict[str, Any], run_id: str,
                     **counters: Any) -> dict[str, Any]:
    """What a final agent file holds, for a training run (`agent_state`) and an agent that learned from play
    (`ncbot.pipelines.online`): the format, the resolved config, the network's sizes and weights, the counters."""
    return {"format": FORMAT, "config": config.to_dict(), "n_features": n_features, "n_actions": n_actions,
            "qnet": qnet, **counters, "run_id": run_id}


def training_state(config: Any, parts: Any, run_id: str, wall_time: float, cpu_time: float | None,
                   log_next: int | None) -> dict[str, Any]:
    """What a periodic checkpoint holds (see module doc): everything `restore` loads back, every tensor on the CPU."""
    from ncbot.modules.device import to_cpu

    counters = parts.counters
    hooks = {hook.checkpoint_key: hook.state_dict() for hook in parts.hooks if hook.checkpoint_key}
    cuda_rng = {"cuda_rng": torch.cuda.get_rng_state(parts.device)} if parts.device.type == "cuda" else {}
    return to_cpu({
        "config": config.to_dict(), "n_features": parts.env.n_features, "n_actions": parts.env.n_actions,
        "qnet": parts.qnet.state_dict(), "learner": parts.learner.state_dict(),
        "egreedy": parts.agent.egreedy.state_dict(),
        "buffer": parts.buffer.state_dict() if config.checkpoint.save_buffer else None, "teacher": None, **hooks,
        "rng": torch.get_rng_state(), "history": parts.history, "run_id": run_id,
        "frames": counters["frames"], "updates": counters["updates"], "episodes": counters["episodes"],
        "wall_time": wall_time, "cpu_time": cpu_time, **cuda_rng, MCAP_KEY: log_next,
    })


def restore(parts: Any, state: dict[str, Any], state_path: Any) -> None:
    """Load a periodic checkpoint's training state into the run's parts (networks, learner, epsilon, buffer, hooks,
    RNG, counters, history); a state that does not fit the config is one line naming the checkpoint."""
    try:
        parts.qnet.load_state_dict(state["qnet"])
        parts.learner.load_state_dict(_learner_state(parts.learner, state["learner"]))
        parts.agent.egreedy.load_state_dict(state["egreedy"])
        if state.get("buffer") is not None:
            parts.buffer.load_state_dict(state["buffer"])
            _storage_to(parts.buffer, parts.device)
        for hook in parts.hooks:
            if hook.checkpoint_key and state.get(hook.checkpoint_key) is not None:
                hook.load_state_dict(state[hook.checkpoint_key])
        torch.set_rng_state(state["rng"])
        if state.get("cuda_rng") is not None and parts.device.type == "cuda":
            torch.cuda.set_rng_state(state["cuda_rng"], parts.device)
    except (RuntimeError, KeyError, TypeError, ValueError) as error:  # the checkpoint's parts do not fit this config
        raise ValueError(f"checkpoint {str(state_path)!r} does not fit the run's config "
                         f"({str(error).splitlines()[0][:160]})") from None
    parts.counters.update({k: state[k] for k in ("frames", "updates", "episodes")})
    parts.counters["wall_offset"] = state["wall_time"]
    parts.counters["cpu_offset"] = state.get("cpu_time")  # None: a checkpoint written before CPU time was kept
    parts.history = list(state["history"])


def _learner_state(learner: Any, state: dict[str, Any]) -> dict[str, Any]:
    """A learner's state as this layout keeps it: an objective's value-estimator buffers that the previous layout did
    not store (a recurrent objective's gamma) are the run's own (they come from its config, not from learning)."""
    objective = state["loss"]
    missing = {key: value for key, value in learner.objective.state_dict().items()
               if key.startswith("_value_estimator.") and key not in objective}
    return {**state, "loss": {**objective, **missing}} if missing else state


def _storage_to(buffer: Any, device: torch.device) -> None:
    """A replay storage loaded from a (CPU) checkpoint onto the run's device: TorchRL fills an empty storage with
    the checkpoint's own tensors, on the CPU."""
    storage = buffer.storage
    if device.type != "cpu" and getattr(storage, "_storage", None) is not None:
        storage._storage = storage._storage.to(device)
