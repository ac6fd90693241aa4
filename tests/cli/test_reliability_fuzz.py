"""Property-based fuzzing of the CLI's error boundary: generated bad files, values and paths given to the
subcommands must end in exit code 2, ONE line on stderr, no traceback and no file left behind.

Runs in-process through `ncbot.pipelines.cli.app.main` (no interpreter start per example) so a few hundred inputs take
seconds. Examples per property: NCBOT_FUZZ_EXAMPLES (default 6, for CI; `NCBOT_FUZZ_EXAMPLES=200` for a deep run).
"""
from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path

import pytest
import torch
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ncbot.pipelines.checkpoint import FORMAT, atomic_save
from ncbot.pipelines.cli.app import main
from ncbot.pipelines.config import RunConfig
from tests.learning_helpers import TINY

FUZZ = settings(max_examples=int(os.environ.get("NCBOT_FUZZ_EXAMPLES", "6")), deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large])


def cli(*args: str) -> tuple[int, str, str]:
    """Run `ncbot ARGS` in this process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), pytest.raises(SystemExit) as done:
        main(list(args))
    return done.value.code, out.getvalue(), err.getvalue()


def fresh(tmp_path: Path) -> Path:
    """A new empty folder per Hypothesis example (pytest's tmp_path is shared by all examples of a test)."""
    import tempfile

    return Path(tempfile.mkdtemp(dir=tmp_path))


def files_under(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*")}


def assert_refused(folder: Path, *args: str) -> str:
    """The command exits 2 with one line and no traceback, and leaves nothing new under `folder`."""
    before = files_under(folder)
    code, _out, err = cli(*args)
    lines = err.strip().splitlines()
    assert code == 2, f"ncbot {' '.join(args)} -> exit {code}: {err[-1500:]}"
    assert len(lines) == 1 and lines[0].startswith("ncbot: error: "), err[-1500:]
    assert "Traceback" not in err
    assert files_under(folder) == before, f"left behind: {sorted(files_under(folder) - before)}"
    return lines[0]


# ------------------------------------------------------------------------------------------------- config files
def _fields(model: type = RunConfig, prefix: str = "") -> list[str]:
    """Every config key whose value ncbot checks (free-form strings and the options mapping excluded)."""
    keys = []
    for name, field in model.model_fields.items():
        annotation = field.annotation
        if isinstance(annotation, type) and issubclass(annotation, RunConfig.__mro__[1]):
            keys += _fields(annotation, f"{prefix}{name}.")
        elif f"{prefix}{name}" not in ("env.opponent", "eval.opponent", "env.options"):
            keys.append(f"{prefix}{name}")
    return keys


CHECKED_KEYS = _fields()
BAD_VALUES = st.one_of(
    st.sampled_from([".nan", ".inf", "-.inf", "{x: 1}", "[a, b]", "[]", "100000000000000000000000", "-1e400"]),
    st.text(alphabet="qzxjkw", min_size=1, max_size=12).map(lambda word: "zz" + word),
)
BINARY = st.binary(min_size=1, max_size=400).filter(lambda data: b"\x00" in data or not _is_utf8(data))


def _is_utf8(data: bytes) -> bool:
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@pytest.fixture()
def tiny_config(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


@FUZZ
@given(key=st.sampled_from(CHECKED_KEYS), value=BAD_VALUES)
def test_a_bad_value_of_any_config_key_is_one_line_naming_it(tmp_path: Path, tiny_config: Path, key: str,
                                                             value: str) -> None:
    tmp = fresh(tmp_path)
    line = assert_refused(tmp, "train", str(tiny_config), f"{key}={value}", "--out", str(tmp / "run"))
    assert key.split(".")[0] in line


@FUZZ
@given(data=BINARY)
def test_a_binary_config_file_is_one_line_naming_the_file(tmp_path: Path, data: bytes) -> None:
    tmp = fresh(tmp_path)
    config = tmp / "binary.yaml"
    config.write_bytes(data)
    line = assert_refused(tmp, "train", str(config), "--out", str(tmp / "run"))
    assert "binary.yaml" in line


YAML_NODES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True), st.text(max_size=8)),
    lambda children: st.one_of(st.lists(children, max_size=3), st.dictionaries(st.text(max_size=6), children, max_size=3)),
    max_leaves=8,
)


@FUZZ
@given(document=st.one_of(
    YAML_NODES.map(lambda node: yaml.safe_dump({"zz_unknown_section": node})),
    YAML_NODES.filter(lambda node: not isinstance(node, dict)).map(yaml.safe_dump),
    st.sampled_from(["env: [\n", "env:\n  game: standard\n game: x\n", "!!python/object/apply:os.system ['true']\n",
                     "env: !!python/name:os.system\n", "", "   \n", "a: &x [*x]\n", "env:\n\tgame: standard\n"]),
))
def test_a_malformed_config_file_is_one_line(tmp_path: Path, document: str) -> None:
    tmp = fresh(tmp_path)
    config = tmp / "bad.yaml"
    config.write_text(document)
    assert_refused(tmp, "train", str(config), "--out", str(tmp / "run"))


# ------------------------------------------------------------------------------------------------- checkpoints
def _valid_agent() -> dict:
    config = RunConfig.model_validate({"agent": {"hidden": [8]}})
    widths = [73, 8, 18]
    qnet = {}
    for layer, (inputs, outputs) in enumerate(zip(widths, widths[1:])):
        qnet[f"module.{2 * layer}.weight"] = torch.zeros(outputs, inputs)
        qnet[f"module.{2 * layer}.bias"] = torch.zeros(outputs)
    return {"format": FORMAT, "config": config.to_dict(), "n_features": 73, "n_actions": 18, "qnet": qnet}


def _mutations() -> st.SearchStrategy:
    def drop(key):
        return lambda data: {k: v for k, v in data.items() if k != key}

    def put(key, value):
        return lambda data: {**data, key: value}

    def reshape(data):
        qnet = dict(data["qnet"])
        qnet["module.0.weight"] = torch.zeros(5, 73)
        return {**data, "qnet": qnet}

    return st.sampled_from([
        drop("config"), drop("qnet"), drop("n_features"), drop("n_actions"), reshape,
        put("config", {"agent": {"hidden": [16]}}), put("config", "not a mapping"), put("n_actions", 90),
        put("n_actions", True), put("qnet", {}), put("config", {"env": {"game": "chess"}}),
        lambda data: {"format": FORMAT},
    ])


@FUZZ
@given(mutate=_mutations(), command=st.sampled_from(["eval", "ladder"]))
def test_an_inconsistent_checkpoint_is_one_line(tmp_path: Path, mutate, command: str) -> None:
    tmp = fresh(tmp_path)
    checkpoint = tmp / "checkpoint.pt"
    atomic_save(mutate(_valid_agent()), checkpoint)
    extra = ["--games", "1"] + (["--out", str(tmp / "ladder")] if command == "ladder" else [])
    line = assert_refused(tmp, command, str(checkpoint), *extra)
    assert "checkpoint.pt" in line


@FUZZ
@given(data=st.one_of(st.binary(max_size=300), st.integers(1, 2000).map(lambda cut: ("cut", cut))))
def test_a_damaged_or_foreign_checkpoint_file_is_one_line(tmp_path: Path, data) -> None:
    tmp = fresh(tmp_path)
    checkpoint = tmp / "checkpoint.pt"
    if isinstance(data, tuple):  # a real checkpoint cut short
        atomic_save(_valid_agent(), checkpoint)
        checkpoint.write_bytes(checkpoint.read_bytes()[: data[1]])
    else:
        checkpoint.write_bytes(data)
    line = assert_refused(tmp, "eval", str(checkpoint), "--games", "1")
    assert "checkpoint.pt" in line


def test_a_pickled_object_is_refused_never_run(tmp_path: Path) -> None:
    import pickle

    class Boom:
        def __reduce__(self):
            return (os.system, (f"touch {tmp_path / 'ran'}",))

    checkpoint = tmp_path / "evil.pt"
    checkpoint.write_bytes(pickle.dumps({"format": FORMAT, "x": Boom()}))
    torch.save({"format": FORMAT, "x": Boom()}, tmp_path / "evil2.pt")
    for path in (checkpoint, tmp_path / "evil2.pt"):
        assert_refused(tmp_path, "eval", str(path), "--games", "1")
    assert not (tmp_path / "ran").exists()


# ------------------------------------------------------------------------------------------------- output paths
GOOD_GRID = {"suites": {"s": {"standard": {"config": "tiny.yaml", "overrides": []}}},
             "grid": {"suite": ["s"], "game": ["standard"], "agent": ["proposed"], "temporal": [True]}}


FOLDER_OUTPUTS = [  # (command with TARGET where its output folder goes)
    ["train", "CONFIG", "--out", "TARGET"],
    ["eval", "CKPT", "--games", "1", "--out", "TARGET"],
    ["ladder", "CKPT", "--games", "1", "--out", "TARGET"],
    ["play", "--out", "TARGET"],
    ["vision", "generate", "cells", "--out", "TARGET"],
    ["vision", "eval", "--what", "cells", "--out", "TARGET"],
    ["robot", "play", "--out", "TARGET"],
    ["ablate", "GRID", "--out", "TARGET"],
]
FILE_OUTPUTS = [  # (command with TARGET where its output file goes, the suffix it needs)
    (["logs", "curve", "TMP", "-o", "TARGET"], ".png"),
    (["logs", "to-rerun", "TMP", "-o", "TARGET"], ".rrd"),
    (["vision", "train", "--out", "TARGET"], ".pt"),
    (["table", "TMP", "--out", "TARGET"], ".md"),
    (["robot", "urdf", "-o", "TARGET"], ".urdf"),
    (["robot", "render", "-o", "TARGET"], ".png"),
]


def _output_cases(tmp: Path) -> list[tuple[str, list[str]]]:
    """Each writing command with its output pointing at something of the wrong kind: (what, args)."""
    file, folder = tmp / "a_file.txt", tmp / "a_folder"
    cases = []
    for command in FOLDER_OUTPUTS:
        cases.append(("a file as the output folder", [str(file) if a == "TARGET" else a for a in command]))
        cases.append(("a folder below a file", [str(file / "sub") if a == "TARGET" else a for a in command]))
    for command, suffix in FILE_OUTPUTS:
        cases.append(("a folder as the output file", [str(folder) if a == "TARGET" else a for a in command]))
        cases.append(("a file below a file", [str(file / f"sub{suffix}") if a == "TARGET" else a for a in command]))
        cases.append(("a wrong suffix", [str(tmp / "out.wrongsuffix") if a == "TARGET" else a for a in command]))
    names = {"CONFIG": str(tmp / "tiny.yaml"), "CKPT": str(tmp / "run" / "checkpoint.pt"), "GRID": str(tmp / "grid.yaml"),
             "TMP": str(tmp)}
    return [(what, [names.get(a, a) for a in args]) for what, args in cases]


def test_every_writing_command_refuses_an_output_of_the_wrong_kind(tmp_path: Path) -> None:
    (tmp_path / "a_file.txt").write_text("x")
    (tmp_path / "a_folder").mkdir()
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(TINY))
    atomic_save(_valid_agent(), tmp_path / "run" / "checkpoint.pt")
    (tmp_path / "grid.yaml").write_text(yaml.safe_dump(GOOD_GRID))
    cases = _output_cases(tmp_path)
    for what, args in cases:
        line = assert_refused(tmp_path, *args)
        assert any(name in line for name in ("a_file", "a_folder", "wrongsuffix")), (what, args, line)
    assert len(cases) == 2 * len(FOLDER_OUTPUTS) + 3 * len(FILE_OUTPUTS)


# ------------------------------------------------------------------------------------------------- sizes and values
@FUZZ
@given(case=st.one_of(
    st.integers(10_000_001, 10**40).map(lambda n: ["eval", "CKPT", "--games", str(n)]),
    st.integers(10_000_001, 10**40).map(lambda n: ["ladder", "CKPT", "--games", str(n)]),
    st.integers(-10**30, -1).map(lambda n: ["eval", "CKPT", "--seed", str(n)]),
    st.integers(-10**30, -1).map(lambda n: ["train", "CONFIG", "--seed", str(n)]),
    st.integers(-10**9, 0).map(lambda n: ["train", "CONFIG", "--episodes", str(n)]),
    st.one_of(st.integers(-10**9, 7), st.integers(257, 10**12)).map(lambda n: ["vision", "read", "IMG", "--rho", str(n)]),
    st.one_of(st.integers(-10**9, 15), st.integers(4097, 10**12)).map(
        lambda n: ["robot", "render", "-o", "OUT/x.png", "--width", str(n)]),
    st.one_of(st.integers(-10**9, 15), st.integers(4097, 10**12)).map(
        lambda n: ["robot", "play", "--height", str(n)]),
    st.sampled_from([["ladder", "CKPT", "--opponents", ","], ["ladder", "CKPT", "--opponents", " , ,"],
                     ["robot", "render", "-o", "OUT/x.png", "--marks", "xb2,ob2"],
                     ["ablate", "GRID", "--seeds", "0"], ["ablate", "GRID", "--workers", "0"],
                     ["train", "--resume", "OUT", "--overwrite"]]),
))
def test_absurd_sizes_and_values_are_one_line(tmp_path: Path, case: list[str]) -> None:
    tmp = fresh(tmp_path)
    (tmp / "tiny.yaml").write_text(yaml.safe_dump(TINY))
    atomic_save(_valid_agent(), tmp / "checkpoint.pt")
    (tmp / "grid.yaml").write_text(yaml.safe_dump(GOOD_GRID))
    (tmp / "img.png").write_bytes(b"not an image")
    names = {"CKPT": str(tmp / "checkpoint.pt"), "CONFIG": str(tmp / "tiny.yaml"), "OUT": str(tmp / "out"),
             "IMG": str(tmp / "img.png"), "GRID": str(tmp / "grid.yaml")}
    args = [names.get(arg, arg.replace("OUT", str(tmp / "out"))) for arg in case]
    if args[0] == "train" and "--resume" not in args:
        args += ["--out", str(tmp / "run")]
    assert_refused(tmp, *args)


# ------------------------------------------------------------------------------------------------- ablation grids
def _grid_mutations() -> st.SearchStrategy:
    junk = st.one_of(st.text(max_size=5), st.integers(), st.none(), st.lists(st.integers(), max_size=2))

    def at(path, value):
        def apply(grid):
            grid = json.loads(json.dumps(grid))
            node = grid
            for key in path[:-1]:
                node = node[key]
            node[path[-1]] = value
            return grid
        return apply

    return st.one_of(
        junk.map(lambda v: at(["suites"], v)),
        junk.map(lambda v: at(["grid"], v)),
        st.text(max_size=5).map(lambda v: at(["grid", "suite"], v or "fast")),
        junk.map(lambda v: at(["suites", "s"], v)),
        junk.filter(lambda v: not isinstance(v, str)).map(lambda v: at(["suites", "s", "standard", "config"], v)),
        st.one_of(st.text(min_size=1, max_size=5), st.integers()).map(lambda v: at(["suites", "s", "standard", "overrides"], v)),
        st.sampled_from(["nope", "zz"]).map(lambda v: at(["grid", v], ["x"])),
        st.sampled_from([[], [[1]], [{"a": 1}]]).map(lambda v: at(["grid", "agent"], v)),
        st.just(at(["grid", "suite"], ["undefined_suite"])),
        st.just(at(["zz_unknown"], 1)),
    )


@FUZZ
@given(mutate=_grid_mutations())
def test_a_malformed_ablation_grid_is_one_line(tmp_path: Path, mutate) -> None:
    tmp = fresh(tmp_path)
    (tmp / "tiny.yaml").write_text(yaml.safe_dump(TINY))
    grid = tmp / "grid.yaml"
    grid.write_text(yaml.safe_dump(mutate(GOOD_GRID)))
    assert_refused(tmp, "ablate", str(grid), "--out", str(tmp / "runs"))


@pytest.mark.parametrize("text", ["suites: [\n", "!!python/object/apply:os.system ['true']\n", "\x89PNG\x00\x01"])
def test_an_ablation_grid_that_is_not_yaml_is_one_line(tmp_path: Path, text: str) -> None:
    grid = tmp_path / "grid.yaml"
    grid.write_bytes(text.encode("latin-1"))
    assert "grid.yaml" in assert_refused(tmp_path, "ablate", str(grid), "--out", str(tmp_path / "runs"))


# ------------------------------------------------------------------------------------------------- other readers
@FUZZ
@given(document=st.one_of(st.binary(max_size=200), YAML_NODES.map(lambda node: json.dumps(node).encode())))
def test_table_over_a_bad_eval_json_is_one_line(tmp_path: Path, document: bytes) -> None:
    tmp = fresh(tmp_path)
    run = tmp / "runs" / "s" / "standard" / "proposed-temporal" / "seed0"
    run.mkdir(parents=True)
    (run / "eval.json").write_bytes(document)
    assert_refused(tmp, "table", str(tmp / "runs"))


@FUZZ
@given(data=st.binary(max_size=400), command=st.sampled_from([["logs", "inspect"], ["logs", "episodes"],
                                                               ["logs", "show", "FILE", "0"]]))
def test_logs_over_a_file_that_is_not_mcap_is_one_line(tmp_path: Path, data: bytes, command: list[str]) -> None:
    tmp = fresh(tmp_path)
    path = tmp / "episodes-0000.mcap"
    path.write_bytes(data)
    args = [str(path) if arg == "FILE" else arg for arg in command]
    if "FILE" not in command:
        args.append(str(path))
    assert_refused(tmp, *args)


def test_resume_of_a_run_whose_config_yaml_is_bad_is_one_line(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for text in ("env: [\n", "!!python/name:os.system\n", "- a list\n", "env: {batch_size: 0}\n"):
        (run / "config.yaml").write_text(text)
        assert "config" in assert_refused(tmp_path, "train", "--resume", str(run))


# ------------------------------------------------------------------------------------------------- the boundary itself
@pytest.mark.parametrize("raised, code, expected", [
    (KeyError("a bug"), 1, "please report it"),
    (KeyboardInterrupt(), 130, "interrupted (Ctrl-C)"),
    (OSError(30, "Read-only file system", "/mnt/x"), 2, "'/mnt/x': the file system is read-only"),
    (OSError(28, "No space left on device", "/mnt/x/step.pt"), 2, "no space left on the device"),
    (MemoryError(), 2, "not enough memory"),
    (RuntimeError("[enforce fail at alloc_cpu.cpp:117] DefaultCPUAllocator: can't allocate memory"), 2, "not enough memory"),
    (OverflowError("Python int too large to convert to C long"), 2, "a number is too large"),
])
def test_the_boundary_sorts_bugs_from_expected_failures(monkeypatch, raised: BaseException, code: int,
                                                        expected: str) -> None:
    import ncbot.envs as envs

    def broken(*args, **kwargs):
        raise raised

    monkeypatch.setattr(envs, "make_env", broken)
    got, _out, err = cli("env", "describe")
    assert got == code and expected in err, err
    if code == 1:
        assert "Traceback" in err and "KeyError" in err
    else:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_ncbot_debug_shows_the_traceback_of_an_expected_failure(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv("NCBOT_DEBUG", "1")
    code, _out, err = cli("train", str(tmp_path / "missing.yaml"))
    assert code == 2 and "Traceback" in err and err.strip().splitlines()[-1].startswith("ncbot: error: config file")


def test_a_cv2_error_is_one_line(monkeypatch) -> None:
    import cv2

    import ncbot.envs as envs

    def broken(*args, **kwargs):
        raise cv2.error("OpenCV(4.9) error: (-4:Insufficient memory) Failed to allocate 40000000000 bytes")

    monkeypatch.setattr(envs, "make_env", broken)
    code, _out, err = cli("env", "describe")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "OpenCV could not process" in err
