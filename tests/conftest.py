"""Shared pytest fixtures (the SAPIEN one: one render system per test process) and the `cuda` marker's skip."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def sapien_render_system():
    """The process-wide SAPIEN RenderSystem; FAILS (never skips) with the set-up recipe if no Vulkan device."""
    from ncbot.robot_sim.render_system import SimulatorUnavailable, get_render_system

    try:
        return get_render_system()
    except SimulatorUnavailable as error:
        pytest.fail(str(error), pytrace=False)


def pytest_collection_modifyitems(config, items):
    """Tests marked `cuda` are skipped, with the reason, where torch sees no CUDA GPU (scripts/device_check.sh runs
    them on a GPU machine: `python -m pytest -m cuda`)."""
    marked = [item for item in items if item.get_closest_marker("cuda") is not None]
    if not marked:
        return
    import torch

    if torch.cuda.is_available():
        return
    reason = f"needs a CUDA GPU: torch {torch.__version__} sees none (run scripts/device_check.sh on a GPU machine)"
    for item in marked:
        item.add_marker(pytest.mark.skip(reason=reason))
