"""Shared fixtures: the headless GL renderer (checked for GL errors) and the shared data folder."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def gl_renderer():
    """One Renderer on the headless EGL context for the whole session."""
    from surfsplat.rendering.renderer import Renderer

    return Renderer()


@pytest.fixture
def renderer(gl_renderer):
    """The session renderer; asserts that no OpenGL error is pending before and after the test."""
    assert gl_renderer.ctx.error == "GL_NO_ERROR"
    yield gl_renderer
    assert gl_renderer.ctx.error == "GL_NO_ERROR"


#: The team's development data (../shared/data beside the repository), see SOURCES.md there.
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared data folder; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data folder {SHARED_DATA} is absent")
    return SHARED_DATA
