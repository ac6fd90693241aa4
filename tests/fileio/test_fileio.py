"""ncbot.fileio.atomic: the one atomic write (what a reader or a crash can see, permissions, durability, cleanup)."""
from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from ncbot.fileio import TEMP_GLOB, atomic_path, atomic_write_bytes, atomic_write_text, fsync_folder


@pytest.fixture
def umask():
    """Set a umask for one test and restore the previous one."""
    previous = os.umask(0o022)
    os.umask(previous)

    def set_umask(mask: int) -> None:
        os.umask(mask)

    yield set_umask
    os.umask(previous)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_writes_bytes_and_text_creating_folders_and_leaving_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b" / "data.bin"
    assert atomic_write_bytes(b"\x00\x01", target) == target
    assert target.read_bytes() == b"\x00\x01"
    text = tmp_path / "notes.md"
    atomic_write_text("é line\n", text)
    assert text.read_bytes() == "é line\n".encode("utf-8")
    assert not list(tmp_path.rglob(TEMP_GLOB)) and not list(tmp_path.rglob("*.tmp"))


@pytest.mark.parametrize("mask, expected", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_permissions_are_the_usual_ones_under_the_umask(tmp_path: Path, umask, mask: int, expected: int) -> None:
    umask(mask)
    target = tmp_path / "file.json"
    atomic_write_text("{}", target)
    assert _mode(target) == expected  # not tempfile.mkstemp's 0600
    with atomic_path(tmp_path / "figure.png") as temp:
        Path(temp).write_bytes(b"png")
    assert _mode(tmp_path / "figure.png") == expected


def test_replaces_an_existing_file_in_one_rename(tmp_path: Path) -> None:
    target = tmp_path / "eval.json"
    target.write_text("old")
    before = target.stat().st_ino
    with atomic_path(target) as temp:
        assert temp.parent == tmp_path and temp.name.startswith(".eval.json.") and temp.name.endswith(".tmp")
        assert [p.name for p in tmp_path.glob(TEMP_GLOB)] == [temp.name]  # what a kill here would leave
        temp.write_text("new")
        assert target.read_text() == "old"  # readers see the old file until the rename
    assert target.read_text() == "new" and target.stat().st_ino != before


def test_a_failed_write_keeps_the_old_file_and_removes_the_temp(tmp_path: Path) -> None:
    target = tmp_path / "checkpoint.pt"
    target.write_bytes(b"good")
    with pytest.raises(RuntimeError, match="disk on fire"):
        with atomic_path(target) as temp:
            temp.write_bytes(b"half")
            raise RuntimeError("disk on fire")
    assert target.read_bytes() == b"good"
    assert os.listdir(tmp_path) == ["checkpoint.pt"]
    with pytest.raises(TypeError):
        atomic_write_bytes("not bytes", tmp_path / "other.bin")  # type: ignore[arg-type]
    assert os.listdir(tmp_path) == ["checkpoint.pt"]


def test_the_file_is_fsynced_before_the_rename_and_the_folder_after(tmp_path: Path, monkeypatch) -> None:
    events: list[tuple[str, str]] = []
    real_fsync, real_replace = os.fsync, os.replace

    def recording_fsync(fd: int) -> None:
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        real_fsync(fd)

    def recording_replace(src, dst) -> None:
        events.append(("replace", str(dst)))
        real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", recording_fsync)
    monkeypatch.setattr(os, "replace", recording_replace)
    target = tmp_path / "weights.pt"
    atomic_write_bytes(b"w", target)
    assert [kind for kind, _ in events] == ["fsync", "replace", "fsync"]
    assert events[0][1].startswith(str(tmp_path / ".weights.pt.")) and events[0][1].endswith(".tmp")
    assert events[1][1] == str(target) and events[2][1] == str(tmp_path)


def test_fsync_folder_is_a_no_op_where_it_cannot_work(tmp_path: Path) -> None:
    fsync_folder(tmp_path)
    fsync_folder(tmp_path / "missing")


def test_no_other_atomic_write_in_the_packages() -> None:
    """One atomic write: temp files and renames appear nowhere else in the ncbot packages."""
    root = Path(__file__).resolve().parents[2]
    needles = ("os.replace(", "os.rename(", ".rename(", "mkstemp(", "NamedTemporaryFile(")
    found = [f"{path.relative_to(root)}: {needle}"
             for package in ("envs", "modules", "vision", "speech", "logs", "robot_sim", "pipelines")
             for path in sorted((root / package).rglob("*.py"))
             for needle in needles if needle in path.read_text()]
    assert not found, "write through fileio (atomic_path / atomic_write_bytes / atomic_write_text) instead:\n" + "\n".join(found)
