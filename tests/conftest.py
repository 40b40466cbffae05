"""Shared fixtures (the headless GL renderer, reset and checked for GL errors around each test; the shared
data folder) and the test tiers.

Tiers: markers registered in pyproject.toml ([tool.pytest.ini_options] markers). They only select:
``python3 -m pytest -q`` runs every test of every tier, as CI does.

- ``gl``: needs an OpenGL 3.3 context (headless EGL: a GPU driver or Mesa llvmpipe; or a window's).
  Set here for the tests using the ``renderer``, ``gl_renderer`` or ``xvfb_display`` fixture; set in
  the test modules for the tests that render through the API or the command line, in process or in a
  child: ``pytestmark = pytest.mark.gl`` where most of a module renders, ``@pytest.mark.gl`` on the
  test where a few do. A new rendering test without those fixtures needs the marker written.
- ``viewer``: needs a window (a virtual X server, Xvfb, and glfw): every test of test_viewer.py, set here
  (the window-less camera math there too, so ``-m viewer`` is the viewer's whole file), and any test
  using the ``xvfb_display`` fixture.
- ``slow``: takes over about 10 s on 2 cores; set in the test modules.
- ``data``: reads the development data in ``../shared/data`` (skips where it is absent); set here for
  the tests using the ``shared_data`` fixture.

For example::

    python3 -m pytest -q -m "not gl and not viewer"   # neither OpenGL nor a display needed
    python3 -m pytest -q -m "not slow"                # the quick tests
    python3 -m pytest -q -m "gl and not slow"         # the quick rendering tests
"""

from __future__ import annotations

from pathlib import Path

import pytest

#: Marker -> the fixtures whose use sets it (pytest_collection_modifyitems).
FIXTURE_MARKERS = {"gl": {"renderer", "gl_renderer", "xvfb_display"}, "viewer": {"xvfb_display"},
                   "data": {"shared_data"}}
#: Test modules every test of which gets the marker.
MODULE_MARKERS = {"viewer": {"test_viewer.py"}}


def pytest_collection_modifyitems(config, items):
    """Set the tiers' markers that follow from a test's fixtures or module (see the module docstring)."""
    for item in items:
        fixtures = set(getattr(item, "fixturenames", ()))
        for marker in FIXTURE_MARKERS.keys() | MODULE_MARKERS.keys():
            wanted = fixtures & FIXTURE_MARKERS.get(marker, set()) or item.path.name in MODULE_MARKERS.get(marker, ())
            if wanted and not item.get_closest_marker(marker):
                item.add_marker(marker)


@pytest.fixture(scope="session")
def gl_renderer():
    """One Renderer on the headless EGL context for the whole session."""
    from surfsplat.rendering.renderer import Renderer

    return Renderer()


def reset_gl_state(renderer) -> None:
    """Put ``renderer`` and its context back into the state a fresh one starts a frame from.

    Frees the cached upload (``Renderer.forget_upload``: the next render uploads its cloud), binds the
    renderer's own 1x1 framebuffer (``Renderer.park``: a framebuffer a test bound and released can no
    longer be the current one when the renderer creates its targets), disables every capability moderngl
    switches (blending, depth test, face culling, rasterizer discard, program point size: ``Renderer.draw``
    enables the ones each pass needs) and sets what it leaves to the defaults: moderngl's blend function and
    equation, OpenGL's depth function, fill mode, polygon offset, point size, winding and culled face.
    """
    import moderngl

    ctx = renderer.ctx
    renderer.forget_upload()
    renderer.park()
    ctx.enable_only(moderngl.NOTHING)
    ctx.blend_func = moderngl.DEFAULT_BLENDING
    ctx.blend_equation = moderngl.FUNC_ADD
    ctx.depth_func = "<"
    ctx.wireframe = False
    ctx.polygon_offset = (0.0, 0.0)
    ctx.point_size = 1.0
    ctx.front_face = "ccw"
    ctx.cull_face = "back"


@pytest.fixture
def renderer(gl_renderer):
    """The session renderer in a clean state (:func:`reset_gl_state`) before and after the test; asserts that
    no OpenGL error is pending before and after it, and that the test left the headless context alive."""
    from surfsplat.rendering import context

    assert gl_renderer.ctx.error == "GL_NO_ERROR"
    reset_gl_state(gl_renderer)
    yield gl_renderer
    assert context._headless is gl_renderer.ctx, (
        "the test released the headless context (reset_default_renderer / reset_headless_context): "
        "the session renderer is unusable; do that in a child process")
    error = gl_renderer.ctx.error
    reset_gl_state(gl_renderer)
    assert error == "GL_NO_ERROR"


#: The team's development data (../shared/data beside the repository), see SOURCES.md there.
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared data folder; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data folder {SHARED_DATA} is absent")
    return SHARED_DATA


@pytest.fixture(scope="session")
def phong_sphere():
    """Phong splats of the unit sphere (Botsch 2004, eq. 2), made directly: 600 disks of the Fibonacci
    sphere whose planes lean 4 degrees off the sphere's normal at their centres (the shading normal), with
    the sphere's linear normal field ``alpha = beta = r`` (the normal at ``p + s u + t v`` is
    ``p + s u + t v`` on the unit sphere, to first order in ``r``)."""
    import numpy as np

    from surfsplat.scenes import sphere

    base = sphere(600, color="bands", coverage=1.0)
    lean = np.radians(4.0)
    r = np.linalg.norm(base.u, axis=1, keepdims=True)
    u = (np.cos(lean) * base.u / r + np.sin(lean) * base.normals) * r   # turned about v, out of the tangent plane
    field = np.concatenate([r, r], axis=1)
    return base.replace(u=u.astype(np.float32), normal_field=field.astype(np.float32))
