"""Shared pytest fixtures. Only the SAPIEN one lives here: one render system per test process."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def sapien_render_system():
    """The process-wide SAPIEN RenderSystem; FAILS (never skips) with the set-up recipe if no Vulkan device."""
    from robot_sim.render_system import SimulatorUnavailable, get_render_system

    try:
        return get_render_system()
    except SimulatorUnavailable as error:
        pytest.fail(str(error), pytrace=False)
