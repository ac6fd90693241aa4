"""Shared pytest fixtures (the SAPIEN one: one render system per test process), the `cuda` marker's skip, and the
skips of tests whose optional extra is not installed (pyproject.toml; `pip install 'ncbot[EXTRA]'`).

On the base install plus pytest, a test module that imports an extra's module, a test that reaches one, and a test
marked `sapien` are skipped with the extra named, never collected as errors or failed. With the extra installed,
nothing is skipped: a SAPIEN test on a machine without Vulkan fails with the set-up recipe.
"""
from __future__ import annotations

import pytest

from ncbot.pipelines.extras import OPTIONAL_MODULES, MissingExtra, installed

#: modules only the tests import, and the extra that installs them
TEST_ONLY_MODULES = {"pexpect": ("test", "pexpect"), "hypothesis": ("test", "hypothesis")}


def skip_reason(extra: str, package: str) -> str:
    return f"needs the optional extra [{extra}] ({package} is not installed): pip install 'ncbot[{extra}]'"


def missing_extra(error: BaseException | None) -> str | None:
    """The skip reason when `error` (or its cause) is an optional module that is not installed, else None."""
    while error is not None:
        if isinstance(error, MissingExtra):
            return str(error)
        if isinstance(error, ModuleNotFoundError) and error.name:
            top = error.name.split(".")[0]
            known = OPTIONAL_MODULES.get(top) or TEST_ONLY_MODULES.get(top)
            if known is not None and not installed(top):
                return skip_reason(*known)
        error = error.__cause__
    return None


class ModuleNeedingExtras(pytest.Module):
    """A test module that cannot be imported because an extra is missing is skipped, naming the extra."""

    skip_reason: str | None = None

    def collect(self):
        try:
            return super().collect()
        except self.CollectError as error:
            self.skip_reason = missing_extra(error.__cause__)
            if self.skip_reason is None:
                raise
            pytest.skip(self.skip_reason, allow_module_level=True)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """The skip of a module needing an extra is reported at the module, not at this file."""
    outcome = yield
    report = outcome.get_result()
    reason = getattr(collector, "skip_reason", None)
    if report.skipped and reason is not None:
        report.longrepr = (str(collector.path), 0, f"Skipped: {reason}")


def pytest_pycollect_makemodule(module_path, parent):
    if module_path.name == "conftest.py":
        return None
    return ModuleNeedingExtras.from_parent(parent, path=module_path)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A test that reaches an optional module that is not installed is skipped with the extra named."""
    outcome = yield
    report = outcome.get_result()
    if report.failed and call.excinfo is not None:
        reason = missing_extra(call.excinfo.value)
        if reason is not None:
            report.outcome = "skipped"
            report.longrepr = (str(item.path), item.location[1] or 0, f"Skipped: {reason}")


@pytest.fixture(scope="session")
def sapien_render_system():
    """The process-wide SAPIEN RenderSystem; FAILS (never skips) with the set-up recipe if no Vulkan device."""
    if not installed("sapien"):
        pytest.skip(skip_reason("robot", "sapien"))
    from ncbot.robot_sim.render_system import SimulatorUnavailable, get_render_system

    try:
        return get_render_system()
    except SimulatorUnavailable as error:
        pytest.fail(str(error), pytrace=False)


def pytest_collection_modifyitems(config, items):
    """Tests marked `sapien` are skipped, naming the extra, where sapien is not installed; tests marked `cuda` are
    skipped, with the reason, where torch sees no CUDA GPU (scripts/device_check.sh runs them on a GPU machine:
    `python -m pytest -m cuda`)."""
    if not installed("sapien"):
        reason = skip_reason("robot", "sapien")
        for item in items:
            if item.get_closest_marker("sapien") is not None:
                item.add_marker(pytest.mark.skip(reason=reason))
    marked = [item for item in items if item.get_closest_marker("cuda") is not None]
    if not marked:
        return
    import torch

    if torch.cuda.is_available():
        return
    reason = f"needs a CUDA GPU: torch {torch.__version__} sees none (run scripts/device_check.sh on a GPU machine)"
    for item in marked:
        item.add_marker(pytest.mark.skip(reason=reason))


@pytest.fixture(autouse=True)
def _progress_on_again():
    """`--no-progress` silences every bar of the process (`ncbot.pipelines.progress.silence`); a command run in this
    process by one test must not silence the bars another test reads."""
    yield
    from ncbot.pipelines.progress import silence

    silence(False)
