"""The release: a wheel built from the checkout installs in a fresh virtual environment and renders
there, outside the checkout (its shaders and py.typed are in it)."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import surfsplat

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.gl   # the installed package renders the demo scene
def test_the_wheel_installs_and_renders_outside_the_checkout(tmp_path):
    dist = tmp_path / "dist"
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(dist)],
                           capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr
    wheels = list(dist.glob("surfsplat-*.whl"))
    assert [w.name for w in wheels] == [f"surfsplat-{surfsplat.__version__}-py3-none-any.whl"]
    names = set(zipfile.ZipFile(wheels[0]).namelist())
    assert "surfsplat/py.typed" in names and "surfsplat/rendering/glsl/ewa.frag" in names
    assert {"surfsplat/web/static/index.html", "surfsplat/web/static/viewer.js"} <= names   # surfsplat export's page
    assert not any(name.startswith(("tests/", "benchmarks/")) for name in names)

    # a fresh environment that sees the installed dependencies but not the checkout
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True, timeout=300)
    python = venv / "bin" / "python"
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    install = subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", "--force-reinstall",
                              str(wheels[0])], capture_output=True, text=True, env=env, timeout=300)
    assert install.returncode == 0, install.stderr
    run = tmp_path / "elsewhere"
    run.mkdir()
    where = subprocess.run([str(python), "-c", "import surfsplat.rendering.renderer as r, surfsplat; "
                            "print(surfsplat.__file__)"], cwd=run, capture_output=True, text=True, env=env)
    assert where.returncode == 0, where.stderr
    assert str(venv) in where.stdout and str(ROOT) not in where.stdout
    demo = subprocess.run([str(venv / "bin" / "surfsplat"), "-q", "demo", "-o", "demo.png", "--width", "96",
                           "--height", "96"], cwd=run, capture_output=True, text=True, env=env, timeout=300)
    assert demo.returncode == 0, demo.stderr
    image = np.asarray(Image.open(run / "demo.png"))
    assert image.shape == (96, 96, 3) and (image < 250).any(axis=-1).mean() > 0.1   # the torus is drawn
