"""Optional extras (pyproject.toml): without one, its commands stop with ONE line naming the pip command, exit 2,
and the base packages import without any optional dependency.

A missing extra is simulated in a subprocess by `sys.modules[name] = None` (import raises ModuleNotFoundError and
importlib.util.find_spec answers None, as for a package that is not installed), so the tests run on the full
set-up too.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ncbot.pipelines.extras import MissingExtra, OPTIONAL_MODULES, extra_line, require

ROOT = Path(__file__).resolve().parents[2]
BASE_PACKAGES = ("fileio", "envs", "modules", "vision", "speech", "logs", "robot_sim", "pipelines")
#: modules that exist only for an extra and may import it at the top (only that extra's commands import them)
EXTRA_ONLY_MODULES = {"ncbot.pipelines.serve.app"}


def _run_without(blocked: list[str], code: str, cwd: Path) -> subprocess.CompletedProcess:
    prelude = "import sys\nfor name in %r:\n    sys.modules[name] = None\n" % (blocked,)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", prelude + code], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=120)


def _ncbot_without(blocked: list[str], args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return _run_without(blocked, f"from ncbot.pipelines.cli.app import main\nmain({args!r})\n", cwd)


def _assert_one_line(result: subprocess.CompletedProcess, extra: str) -> None:
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert f"pip install 'ncbot[{extra}]'" in lines[0], lines[0]


def test_robot_render_without_the_robot_extra_is_one_line(tmp_path):
    result = _ncbot_without(["sapien"], ["robot", "render", "-o", str(tmp_path / "mouth.png")], tmp_path)
    _assert_one_line(result, "robot")
    assert "ncbot robot render" in result.stderr and "sapien" in result.stderr
    assert not (tmp_path / "mouth.png").exists()


def test_logs_to_rerun_without_the_rerun_extra_is_one_line(tmp_path):
    result = _ncbot_without(["rerun"], ["logs", "to-rerun", str(tmp_path), "-o", str(tmp_path / "run.rrd")], tmp_path)
    _assert_one_line(result, "rerun")
    assert "rerun-sdk" in result.stderr


def test_robot_serve_without_the_serve_extra_is_one_line(tmp_path):
    result = _ncbot_without(["fastapi", "uvicorn"], ["robot", "serve", "--out", str(tmp_path / "study")], tmp_path)
    _assert_one_line(result, "serve")


def test_base_packages_import_without_any_optional_dependency(tmp_path):
    code = f"""
import importlib, pkgutil
failed = []
for package in {["ncbot." + package for package in BASE_PACKAGES]!r}:
    for info in pkgutil.walk_packages(importlib.import_module(package).__path__, package + "."):
        if info.name in {sorted(EXTRA_ONLY_MODULES)!r}:
            continue
        try:
            importlib.import_module(info.name)
        except Exception as error:
            failed.append(f"{{info.name}}: {{error!r}}")
print("\\n".join(failed))
"""
    result = _run_without(sorted(OPTIONAL_MODULES), code, tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "", "modules that need an optional dependency at import:\n" + result.stdout


def test_require_and_the_error_boundary_name_the_extra(monkeypatch):
    from ncbot.pipelines.errors import one_line

    monkeypatch.setitem(sys.modules, "pyspiel", None)
    with pytest.raises(MissingExtra, match=r"pip install 'ncbot\[openspiel\]'"):
        require("openspiel", "pyspiel", what="openspiel-mcts opponents")
    # raised deeper, where no entry point checked first: the same one line
    error = ModuleNotFoundError("No module named 'pyspiel'", name="pyspiel")
    assert "pip install 'ncbot[openspiel]'" in one_line(error)
    # a base dependency that is missing is a broken install, not an extra: no advice to install an extra
    assert extra_line(ModuleNotFoundError("No module named 'yaml'", name="yaml")) is None


def _pytest_without(blocked: list[str], args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """pytest as on the base install plus pytest: the optional modules and pytest plugins of [test] missing."""
    env = {**os.environ, "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    prelude = "import sys\nfor name in %r:\n    sys.modules[name] = None\nimport pytest\n" % (blocked,)
    return subprocess.run([sys.executable, "-c", prelude + f"sys.exit(pytest.main({args!r}))"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


BASE_MISSING = sorted(OPTIONAL_MODULES) + ["pexpect", "hypothesis"]


def top_level_imports(path: Path) -> set[str]:
    """The modules a file imports at its top level (what its collection needs)."""
    import ast

    names = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
    return names


def modules_needing_extras() -> list[Path]:
    """Every test module whose top level imports an optional module, directly or through a tests.* helper."""
    files = {path: top_level_imports(path) for path in (ROOT / "tests").rglob("*.py")}
    by_name = {".".join(path.relative_to(ROOT).with_suffix("").parts): path for path in files}
    needing: set[Path] = set()
    changed = True
    while changed:
        changed = False
        for path, names in files.items():
            if path in needing:
                continue
            if any(name.split(".")[0] in BASE_MISSING or by_name.get(name) in needing for name in names):
                needing.add(path)
                changed = True
    return sorted(path for path in needing if path.name.startswith("test_"))


def test_the_suite_collects_on_the_base_install_with_skips_naming_the_extras(tmp_path):
    modules = modules_needing_extras()
    assert ROOT / "tests" / "serve" / "test_serve.py" in modules and len(modules) >= 5
    result = _pytest_without(BASE_MISSING, ["--collect-only", "-q", "-rs", "-p", "no:cacheprovider",
                                            *map(str, modules)], ROOT)
    assert result.returncode in (0, 5), result.stdout[-3000:] + result.stderr[-2000:]  # 5: every module skipped
    assert "error" not in result.stdout.lower().split("short test summary")[-1]
    assert "tests/serve/test_serve.py:0: needs the optional extra [serve] (httpx is not installed): pip install " \
           "'ncbot[serve]'" in result.stdout
    assert "needs the optional extra [test] (hypothesis is not installed)" in result.stdout


def test_a_test_that_reaches_a_missing_extra_is_skipped_naming_it(tmp_path):
    (tmp_path / "conftest.py").write_text("from tests.conftest import (ModuleNeedingExtras, pytest_make_collect_report,"
                                          " pytest_pycollect_makemodule, pytest_runtest_makereport)\n")
    (tmp_path / "test_imports.py").write_text("import httpx\n\ndef test_never():\n    pass\n")
    (tmp_path / "test_reaches.py").write_text(
        "import pytest\n\ndef test_speech():\n    import pocketsphinx\n\n"
        "def test_required():\n    from ncbot.pipelines.extras import require\n    require('rerun', 'rerun')\n\n"
        "def test_a_real_failure():\n    import no_such_module_anywhere\n")
    result = _pytest_without(BASE_MISSING, ["-q", "-rs", "-p", "no:cacheprovider", str(tmp_path)], ROOT)
    out = result.stdout
    assert "1 failed, 3 skipped" in out, out[-3000:]
    assert "test_imports.py:0: needs the optional extra [serve] (httpx is not installed)" in out
    assert "needs the optional extra [speech] (pocketsphinx is not installed)" in out
    assert "pip install 'ncbot[rerun]'" in out and "no_such_module_anywhere" in out
