"""The browser viewer as a Jupyter widget (anywidget): its state from Python, and its module run in
headless Chromium by a page that plays anywidget's part (the model's get, set, save_changes, on)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surfsplat.errors import InputError
from surfsplat.scenes import torus
from surfsplat.web.browser import Browser, file_url, find_chromium
from surfsplat.web.export import _script_json
from surfsplat.web.shaders import shader_bundle

anywidget = pytest.importorskip("anywidget", reason="the notebook widget needs anywidget (the notebook extra)")
from surfsplat.web.widget import widget  # noqa: E402

HOST = """<!doctype html><html><head><meta charset="utf-8"><style>body {{ margin: 0; }}</style></head><body>
<div id="cell"></div>
<script>window.calls = []; window.listeners = {{}};</script>
<script type="module">
const state = {state};
const model = {{
  get: (key) => state[key],
  set: (key, value) => {{ state[key] = value; window.calls.push([key, value]); }},
  save_changes: () => window.calls.push(['save']),
  on: (event, callback) => {{ window.listeners[event] = callback; }},
}};
window.model = model;
const source = URL.createObjectURL(new Blob([{esm}], {{type: 'text/javascript'}}));
const module = await import(source);
module.default.render({{model, el: document.getElementById('cell')}});
</script></body></html>
"""


def test_the_widget_holds_the_page_data_and_the_viewer():
    w = widget(torus(16, 8), height=300, ui=False)
    assert isinstance(w, anywidget.AnyWidget)
    assert w.data["header"]["count"] == 128 and set(w.data["streams"]) == {"position", "normal", "angle", "radii",
                                                                          "color"}
    assert w.data["header"]["supersample"] == 1
    assert w.shaders == json.loads(json.dumps(shader_bundle()))
    assert w.height == 300 and w.params == {"ui": "0"} and w.camera == {}
    assert "function surfsplatViewer(" in w._esm and "export default" in w._esm
    with pytest.raises(InputError, match="height"):
        widget(torus(16, 8), height=0)
    with pytest.raises(InputError, match="not drawn by the web viewer"):
        widget(torus(16, 8), technique="sketch")


def test_the_widget_takes_the_page_s_supersampling_as_export_does():
    assert widget(torus(16, 8), supersample=3).data["header"]["supersample"] == 3
    assert "position_fine" in widget(torus(16, 8), position_bits=24).data["streams"]
    for bad in (0, 5, 2.0, "2"):
        with pytest.raises(InputError, match="supersampling"):
            widget(torus(16, 8), supersample=bad)


@pytest.mark.browser
@pytest.mark.gl
@pytest.mark.skipif(find_chromium() is None, reason="no Chromium: install Debian's chromium package (.ci/run does)")
def test_the_widget_draws_in_a_cell_and_syncs_its_camera(tmp_path):
    w = widget(torus(120, 48), height=300)
    host = tmp_path / "host.html"
    state = {"data": w.data, "shaders": w.shaders, "params": w.params, "height": w.height, "camera": {}}
    host.write_text(HOST.format(state=_script_json(state), esm=_script_json(w._esm)), encoding="utf-8")
    with Browser() as browser:
        page = browser.page(file_url(host), 400, 320)
        try:
            page.wait_for("document.getElementById('cell').getAttribute('data-ready') === '1'", timeout=60)
            assert page.collect() == []
            size = page.evaluate("JSON.stringify([document.getElementById('cell').clientHeight, "
                                 "document.querySelector('#cell canvas').width])")
            assert json.loads(size) == [300, 400]
            image = page.canvas("#cell canvas")
            assert (image.min(axis=2) < 250).mean() > 0.05
            page.drag((200, 150), (260, 160))   # the view moves: the model's camera follows
            page.wait_for("window.calls.some(c => c[0] === 'camera') && window.calls.some(c => c[0] === 'save')",
                          timeout=10)
            moved = json.loads(page.evaluate("JSON.stringify(window.model.get('camera'))"))
            assert set(moved) == {"eye", "target", "up", "fov"}
            # Python sets the camera: the view takes it
            camera = {"eye": [0.0, 0.0, 4.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov": 30.0}
            page.evaluate(f"window.model.set('camera', {json.dumps(camera)}); window.listeners['change:camera']()")
            page.wait_for(f"document.getElementById('cell').surfsplat.camera.fov === {camera['fov']}", timeout=10)
            shown = json.loads(page.evaluate("JSON.stringify(document.getElementById('cell').surfsplat.camera)"))
            assert np.allclose(shown["eye"], camera["eye"]) and np.allclose(shown["target"], camera["target"])
            assert page.collect() == []
        finally:
            page.close()
