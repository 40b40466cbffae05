"""Fuzzing the command line and the renderer: no traceback, no hang, no silently wrong picture.

Each case runs ``surfsplat.cli.main`` in-process on tiny inputs (16x16 images, clouds of tens of
points) with a random subcommand and option values drawn from each option's range and just outside
it (0, negative, huge, nan, inf, strings, integers beyond float's range), on degenerate clouds and
cameras. A case passes only as

* a clear error: exit status 2, a ``surfsplat[ command]: error:`` line, no traceback; or
* a correct result: exit status 0 and an output file that reads back (an image of the asked size; a
  PLY with finite values; a hierarchy), and no warning about non-finite pixels or NumPy overflow.

Seeded and deterministic. The normal run draws :data:`DEFAULT_CASES` cases; the long mode sets the
environment variable ``SURFSPLAT_FUZZ_CASES`` (e.g. 10000) and prints a table of the outcomes::

    SURFSPLAT_FUZZ_CASES=10000 pytest tests/test_fuzz_cli.py -s -k cli
"""

from __future__ import annotations

import contextlib
import io
import itertools
import os
import signal
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from surfsplat import scenes
from surfsplat.camera import Camera
from surfsplat.cli import main
from surfsplat.cloud import SplatCloud
from surfsplat.errors import InputError
from surfsplat.hierarchy import load_hierarchy
from surfsplat.io import load
import surfsplat.rendering.renderer as renderer_module
from surfsplat.rendering.options import FilterOptions, KernelOptions, RenderOptions, VisibilityOptions
from surfsplat.rendering.techniques import TECHNIQUES


DEFAULT_CASES = 400
CASES = int(os.environ.get("SURFSPLAT_FUZZ_CASES", DEFAULT_CASES))
SEED = int(os.environ.get("SURFSPLAT_FUZZ_SEED", 20240611))
#: Seconds a case may take before it counts as a hang.
TIME_LIMIT = 60

ERROR_PREFIXES = ("surfsplat: error: ", "surfsplat ")


# -- inputs ---------------------------------------------------------------------------------------

def _write_points(path: Path, points: np.ndarray) -> Path:
    with open(path, "w") as handle:
        handle.write(f"ply\nformat ascii 1.0\nelement vertex {len(points)}\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n")
        for p in points:
            handle.write(" ".join(repr(float(c)) for c in p) + "\n")
    return path


def _write_mesh(path: Path, vertices: np.ndarray, faces) -> Path:
    with open(path, "w") as handle:
        handle.write(f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float y\n"
                     f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\n"
                     "end_header\n")
        for p in vertices:
            handle.write(" ".join(repr(float(c)) for c in p) + "\n")
        for f in faces:
            handle.write(f"{len(f)} " + " ".join(map(str, f)) + "\n")
    return path


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    """Tiny and degenerate inputs: clouds, meshes, a splat file and a hierarchy."""
    folder = tmp_path_factory.mktemp("fuzz_inputs")
    rng = np.random.default_rng(1)
    sphere = rng.normal(size=(80, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    plane = np.c_[rng.uniform(-1, 1, (60, 2)), np.zeros(60)]
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    files = {
        "sphere": _write_points(folder / "sphere.ply", sphere),
        "plane": _write_points(folder / "plane.ply", plane),
        "one": _write_points(folder / "one.ply", np.array([[0.5, 0.5, 0.5]])),
        "coincident": _write_points(folder / "coincident.ply", np.zeros((2, 3))),
        "collinear": _write_points(folder / "collinear.ply", np.c_[np.linspace(0, 1, 20), np.zeros((20, 2))]),
        "nan": _write_points(folder / "nan.ply", np.full((10, 3), np.nan)),
        "some_nan": _write_points(folder / "some_nan.ply", np.r_[sphere, np.full((3, 3), np.nan)]),
        "huge": _write_points(folder / "huge.ply", sphere * 1e12),
        "tiny": _write_points(folder / "tiny.ply", sphere * 1e-12),
        "far_off": _write_points(folder / "far_off.ply", sphere + 1e7),
        "mixed_scale": _write_points(folder / "mixed.ply", np.r_[sphere * 1e-12, sphere * 1e12]),
        "tet": _write_mesh(folder / "tet.ply", tet, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
        "flat_mesh": _write_mesh(folder / "flat.ply", np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), [[0, 1, 2]]),
        "empty": folder / "empty.ply",
        "garbage": folder / "garbage.ply",
        "missing": folder / "missing.ply",
    }
    files["empty"].write_bytes(b"")
    files["garbage"].write_bytes(rng.integers(0, 256, 300, dtype=np.uint8).tobytes())
    splats = folder / "splats.ply"
    assert main(["-q", "preprocess", str(files["sphere"]), "-o", str(splats)]) == 0
    files["splats"] = splats
    model = folder / "model.npz"
    assert main(["-q", "build", str(files["sphere"]), "-o", str(model)]) == 0
    files["model"] = model
    return files


# -- cases ----------------------------------------------------------------------------------------

#: Values just outside or far outside any option's range.
WILD = ["0", "-1", "-0", "1e30", "-1e30", "1e308", "1e-30", "nan", "inf", "-inf", "abc", "", "1,5",
        "9223372036854775808", "1" + "0" * 400, "0x10", "2.5"]


def _value(rng, good: list[str]) -> str:
    """A valid value most of the time, else a wild one."""
    return str(rng.choice(good)) if rng.random() < 0.7 else str(rng.choice(WILD))


def _triple(rng, good: list[str]) -> list[str]:
    return [_value(rng, good) for _ in range(3)]


POINT_INPUTS = ["sphere", "plane", "one", "coincident", "collinear", "nan", "some_nan", "huge", "tiny", "far_off",
                "mixed_scale", "tet", "flat_mesh", "empty", "garbage", "missing", "splats"]


def _render_flags(rng) -> list[str]:
    args = ["--width", _value(rng, ["16", "16", "9", "1", "24"]), "--height", _value(rng, ["16", "16", "7", "1"])]
    if rng.random() < 0.02:
        args = ["--width", "32768", "--height", "32768"]   # valid, and more than the machine holds
    flags = {
        "--technique": lambda: str(rng.choice(list(TECHNIQUES) + ["nope"])),
        "--cutoff": lambda: _value(rng, ["1", "0.5", "4", "80", "0.001", "81", "0.0001"]),
        "--depth-epsilon": lambda: _value(rng, ["0", "1", "10", "1e6", "2e6"]),
        "--kernel": lambda: str(rng.choice(["pajarola", "gaussian", "box"])),
        "--kernel-a": lambda: _value(rng, ["6", "80", "81", "1e-6"]),
        "--kernel-b": lambda: _value(rng, ["1.5", "1e-6", "1e6"]),
        "--kernel-n": lambda: _value(rng, ["3", "1e-6", "1000", "1001"]),
        "--kernel-sigma": lambda: _value(rng, ["0.5", "1e-6", "1e6"]),
        "--fov": lambda: _value(rng, ["40", "1e-6", "179.999", "180", "90"]),
        "--supersample": lambda: _value(rng, ["1", "2", "3", "9"]),
        "--background": lambda: _triple(rng, ["0", "1", "0.5", "1.5"]),
        "--eye": lambda: _triple(rng, ["0", "3", "-3", "1e-12", "1e12", "0.5"]),
        "--target": lambda: _triple(rng, ["0", "1", "0.5", "1e12"]),
        "--up": lambda: _triple(rng, ["0", "1", "-1"]),
        "--light": lambda: _triple(rng, ["0", "1", "-1"]),
        "--k": lambda: _value(rng, ["3", "8", "2", "1000000"]),
        "--lod-tolerance": lambda: _value(rng, ["0", "1", "100"]),
        "--bit-depth": lambda: str(rng.choice(["8", "16", "12"])),
    }
    switches = ["--no-prefilter", "--cull-backfaces", "--no-separate-sides", "--deferred", "--no-lighting",
                "--transparent"]
    for name in rng.choice(list(flags), size=rng.integers(0, 6), replace=False):
        value = flags[name]()
        args += [name, *value] if isinstance(value, list) else [name, value]
    args += [s for s in switches if rng.random() < 0.2]
    return args


def make_case(rng, inputs: dict[str, Path], out: Path) -> list[str]:
    """One command line (without -q)."""
    command = rng.choice(["render", "render", "render", "render", "demo", "build", "info", "preprocess",
                          "phong", "sample", "bogus"])
    source = str(inputs[str(rng.choice(POINT_INPUTS + ["model"] * 2))])
    if command == "render":
        suffix = str(rng.choice([".png", ".png", ".jpg", ".txt"]))
        return ["render", source, "-o", str(out.with_suffix(suffix)), *_render_flags(rng)]
    if command == "demo":
        return ["demo", "--scene", str(rng.choice(["sphere", "nope"])), "-o", str(out.with_suffix(".png")),
                *_render_flags(rng), "--lod-tolerance", "4"]
    if command == "build":
        return ["build", source, "-o", str(out.with_suffix(".npz")), "--leaf-capacity",
                _value(rng, ["1", "8", "100", "2147483647", "2147483648"])]
    if command == "info":
        return ["info", source]
    if command == "preprocess":
        return ["preprocess", source, "-o", str(out.with_suffix(".ply")), "--k", _value(rng, ["3", "8", "50"]),
                "--shape", str(rng.choice(["ellipse", "circle"])), "--outliers",
                str(rng.choice(["drop", "cap", "keep"]))]
    if command == "phong":
        extra = (["--count", _value(rng, ["1", "10", "1000000"])] if rng.random() < 0.5
                 else ["--error", _value(rng, ["0.01", "1", "1e-9"])])
        return ["phong", source, "-o", str(out.with_suffix(".ply")), *extra, "--relax", _value(rng, ["0", "2"]),
                "--margin", _value(rng, ["0", "0.75", "10"])]
    if command == "sample":
        mesh = str(inputs[str(rng.choice(["tet", "tet", "flat_mesh", "sphere", "garbage"]))])
        args = ["sample", mesh, "-o", str(out.with_suffix(".ply")), "-n", _value(rng, ["1", "10", "200"]),
                "--seed", _value(rng, ["0", "1", "18446744073709551615"])]
        if rng.random() < 0.3:
            args += ["--sharp-angle", _value(rng, ["30", "179", "180"])]
        return args
    return ["bogus"]


# -- running and classifying ----------------------------------------------------------------------

class Hang(Exception):
    """A case ran past :data:`TIME_LIMIT`."""


def _alarm(signum, frame):
    raise Hang()


def _output(argv: list[str]) -> Path | None:
    for flag in ("-o", "--output"):
        if flag in argv:
            return Path(argv[argv.index(flag) + 1])
    return None


def _check_output(argv: list[str], stdout: str) -> str | None:
    """Why the output of a successful case is wrong, or None."""
    out = _output(argv)
    if out is None:
        return None if stdout.strip() else "printed nothing"
    if not out.is_file():
        return f"no output file {out}"
    if out.suffix in (".png", ".jpg"):
        with Image.open(out) as image:
            image.load()
            size = image.size
        if "--width" in argv and "--height" in argv:
            want = (int(argv[argv.index("--width") + 1]), int(argv[argv.index("--height") + 1]))
            if size != want:
                return f"image size {size}, asked {want}"
    elif out.suffix == ".ply":
        cloud = load(out)
        arrays = [a for a in (cloud.positions, cloud.normals, cloud.u, cloud.v, cloud.colors) if a is not None]
        if len(cloud) == 0 or not all(np.isfinite(a).all() for a in arrays):
            return "PLY with no points or non-finite values"
    elif out.suffix == ".npz":
        load_hierarchy(out)
    return None


def run_case(argv: list[str]) -> tuple[str, str]:
    """(outcome, detail): outcome one of "clear error", "correct", "crash", "hang", "wrong output"."""
    out = _output(argv)
    if out is not None and out.exists():
        out.unlink()
    stdout, stderr = io.StringIO(), io.StringIO()
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(TIME_LIMIT)
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr), warnings.catch_warnings():
            warnings.simplefilter("default")
            status = main(["-q", *argv])
    except Hang:
        return "hang", "ran past the time limit"
    except SystemExit as exc:
        return "crash", f"SystemExit({exc.code!r})"
    except BaseException as exc:   # anything main() lets through is a traceback for the user
        return "crash", f"{type(exc).__name__}: {exc}"[:300]
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    err = stderr.getvalue()
    if "Traceback" in err:
        return "crash", err[-300:]
    leaked = [line for line in err.splitlines()
              if "encountered in" in line or "non-finite splat weight" in line]
    if status == 2:
        errors = [line for line in err.splitlines() if line.startswith(ERROR_PREFIXES) and ": error: " in line]
        return ("clear error", errors[0]) if len(errors) == 1 else ("wrong output", f"exit 2, stderr {err[-300:]!r}")
    if status != 0:
        return "wrong output", f"exit status {status}: {err[-300:]!r}"
    if leaked:
        return "wrong output", f"leaked warning: {leaked[0]}"
    try:
        problem = _check_output(argv, stdout.getvalue())
    except Exception as exc:   # the output does not read back
        problem = f"output unreadable: {type(exc).__name__}: {exc}"
    return ("wrong output", problem) if problem else ("correct", "")


OUTCOMES = ("clear error", "correct", "crash", "hang", "wrong output")


@pytest.mark.gl
@pytest.mark.slow   # 18 s on 2 idle cores
def test_cli_fuzz(inputs, tmp_path):
    """Random command lines: each one a clear error or a correct result; a table in the long mode."""
    rng = np.random.default_rng(SEED)
    counts: Counter = Counter()
    failures: list[str] = []
    start = time.perf_counter()
    for i in range(CASES):
        argv = make_case(rng, inputs, tmp_path / f"out{i % 4}")
        outcome, detail = run_case(argv)
        counts[outcome] += 1
        if outcome not in ("clear error", "correct"):
            failures.append(f"case {i}: {outcome}: surfsplat {' '.join(argv)}\n    {detail}")
    elapsed = time.perf_counter() - start
    table = "\n".join([f"{'cases':>14} {CASES:7d}  ({elapsed:.1f} s)"] +
                      [f"{name + 's' if name != 'wrong output' else 'wrong outputs':>14} {counts[name]:7d}"
                       for name in OUTCOMES])
    print(f"\nCLI fuzz, seed {SEED}:\n{table}")
    for line in failures[:40]:
        print(line)
    assert not failures, f"{len(failures)} of {CASES} cases failed:\n" + "\n".join(failures[:20])
    assert counts["correct"] >= CASES // 10, f"too few correct results to exercise the renderer: {counts}"


# -- the renderer on adversarial inputs -----------------------------------------------------------

def _variants() -> dict[str, SplatCloud]:
    base = scenes.sphere(150)
    n = len(base)

    def with_(**arrays) -> SplatCloud:
        fields = {name: getattr(base, name) for name in ("positions",) + SplatCloud._OPTIONAL}
        fields.update(arrays)
        return SplatCloud(**fields)

    def one_bad(array, value):
        array = array.copy()
        array[0] = value
        return array

    return {
        "plain": base,
        "one": base.subset(np.arange(n) == 0),
        "coincident": with_(positions=np.zeros((n, 3), "f4")),
        "tiny": with_(positions=base.positions * 1e-12, u=base.u * 1e-12, v=base.v * 1e-12),
        "huge": with_(positions=base.positions * 1e12, u=base.u * 1e12, v=base.v * 1e12),
        "tiny_axes": with_(u=base.u * 1e-20, v=base.v * 1e-20),
        "needles": with_(v=base.v * 1e-9),
        "parallel_axes": with_(v=base.u.copy()),
        "zero_axes": with_(u=base.u * 0, v=base.v * 0),
        "huge_colors": with_(colors=np.full((n, 3), 1e38, "f4")),
        "nan_position": with_(positions=one_bad(base.positions, np.nan)),
        "inf_position": with_(positions=one_bad(base.positions, np.inf)),
        "nan_normal": with_(normals=one_bad(base.normals, np.nan)),
        "zero_normal": with_(normals=one_bad(base.normals, 0.0)),
        "nan_axis": with_(u=one_bad(base.u, np.nan)),
        "huge_axis": with_(u=one_bad(base.u, 1e30)),
        "nan_color": with_(colors=np.full((n, 3), np.nan, "f4")),
    }


CAMERAS = {
    "front": Camera(width=16, height=16),
    "inside": Camera(eye=(0.0, 0.0, 0.2), width=16, height=16),
    "on_surface": Camera(eye=(0.0, 0.0, 1.0), target=(0.0, 0.0, 0.0), width=16, height=16),
    "grazing_far": Camera(eye=(0.0, 0.0, 1e6), fov=1e-3, width=16, height=16),
}

OPTIONS = {
    "default": RenderOptions(),
    "deferred": RenderOptions(deferred=True),
    "extremes_high": RenderOptions(filter=FilterOptions(prefilter=False, cutoff=80.0),
                                   visibility=VisibilityOptions(depth_epsilon=1e6),
                                   kernel=KernelOptions(a=80.0, n=1e3), deferred=True),
    "extremes_low": RenderOptions(filter=FilterOptions(cutoff=1e-3), visibility=VisibilityOptions(depth_epsilon=0.0),
                                  kernel=KernelOptions(name="gaussian", b=1e-6, sigma=1e6)),
}


def test_adversarial_renders_have_only_finite_pixels(renderer):
    """Every render of degenerate splats, cameras and extreme options is finite, or a clear InputError
    (non-finite splats, out-of-range values); none needs the normalization pass's last-resort guard."""
    rendered = refused = 0
    for (cloud_name, cloud), (camera_name, camera), (options_name, options), technique in itertools.product(
            _variants().items(), CAMERAS.items(), OPTIONS.items(), TECHNIQUES):
        case = f"{cloud_name}, {camera_name}, {options_name}, {technique}"
        with warnings.catch_warnings():
            warnings.simplefilter("error")   # a non-finite pixel warning or a NumPy overflow fails
            try:
                frame = renderer.render(cloud, camera, technique, options=options)
            except InputError:
                assert cloud_name in ("nan_position", "inf_position", "nan_normal", "zero_normal", "nan_axis",
                                      "huge_axis", "nan_color"), case
                refused += 1
                continue
        rendered += 1
        for name in ("color", "weight", "alpha"):
            assert np.isfinite(getattr(frame, name)).all(), f"{case}: non-finite {name}"
        assert not np.isnan(frame.depth).any(), case
        assert ((frame.color >= 0) & (frame.color <= 1)).all(), case
    assert rendered > refused > 0


@pytest.mark.parametrize("kwargs", [dict(cutoff=1e30), dict(cutoff=1e-30), dict(cutoff=float("nan")),
                                    dict(cutoff=float("inf")), dict(cutoff="1")])
def test_filter_options_refuse_values_out_of_range(kwargs):
    with pytest.raises(InputError, match=r"cutoff must be a number in \[0.001, 80\], got"):
        FilterOptions(**kwargs)


@pytest.mark.parametrize("value", [1e30, float("inf"), float("nan"), -1.0, True])
def test_visibility_options_refuse_values_out_of_range(value):
    with pytest.raises(InputError, match=r"depth epsilon must be a number in \[0, 1e\+06\]"):
        VisibilityOptions(depth_epsilon=value)


@pytest.mark.parametrize("kwargs", [dict(n=1e30), dict(name="gaussian", b=1e200, sigma=1e-200),
                                    dict(name="gaussian", b=1.5, sigma=1e-300), dict(a=float("inf"))])
def test_kernel_options_refuse_values_out_of_range_without_overflow(kwargs):
    with pytest.raises(InputError, match="kernel"):
        KernelOptions(**kwargs)


def test_normalization_guard_shows_the_background_and_warns(renderer):
    """A non-finite accumulation (NaN colors uploaded behind the renderer's checks) shows the background
    and is counted in a warning, never a NaN pixel."""
    cloud = scenes.sphere(150)
    gpu = renderer.upload(cloud)
    try:
        gpu.buffers["color"].write(np.full((len(cloud), 3), np.nan, "f4").tobytes())
        with pytest.warns(RuntimeWarning, match="non-finite splat weight, color or depth"):
            frame = renderer.render(gpu, Camera(width=16, height=16), "ewa", background=(0.0, 1.0, 0.0))
    finally:
        gpu.release()
    assert np.isfinite(frame.color).all()
    assert np.allclose(frame.color[frame.weight == 0], (0.0, 1.0, 0.0))


def test_render_refuses_what_memory_cannot_hold(renderer, monkeypatch, tmp_path, capsys):
    """A render whose estimate exceeds the memory available is refused before anything is allocated,
    naming the size, the estimate and the limit; in the API and on the command line."""
    monkeypatch.setattr(renderer_module, "memory_limit", lambda: 50 * 2**20)
    need = renderer_module.render_memory(150, 4096, 4096)
    assert need > 50 * 2**20
    with pytest.raises(InputError, match=r"rendering 150 splats at 4096x4096 pixels needs about [\d,]+ MiB, "
                                         r"more than the 50 MiB of memory available"):
        renderer.render(scenes.sphere(150), Camera(width=4096, height=4096))
    assert renderer.render(scenes.sphere(150), Camera(width=16, height=16)).color.shape == (16, 16, 3)
    status = main(["-q", "demo", "--scene", "sphere", "-o", str(tmp_path / "big.png"), "--width", "8192",
                   "--height", "8192"])
    err = capsys.readouterr().err
    assert status == 2 and "MiB of memory available" in err and "Traceback" not in err
    assert not (tmp_path / "big.png").exists()


def test_sample_refuses_more_points_than_memory_holds(tmp_path, capsys):
    """``sample -n 10^12`` is one clear error, not a NumPy MemoryError traceback; --seed -1 a usage error."""
    mesh = _write_mesh(tmp_path / "tet.ply", np.eye(3).tolist() + [[0, 0, 0]], [[3, 1, 0], [3, 0, 2], [3, 2, 1],
                                                                                 [0, 1, 2]])
    assert main(["-q", "sample", str(mesh), "-n", str(10**12), "-o", str(tmp_path / "a.ply")]) == 2
    assert "MiB of memory available" in capsys.readouterr().err
    assert main(["-q", "sample", str(mesh), "-n", "10", "--seed", "-1", "-o", str(tmp_path / "a.ply")]) == 2
    assert "--seed: must be an integer >= 0" in capsys.readouterr().err
    assert main(["-q", "build", str(mesh), "-o", str(tmp_path / "a.npz"), "--leaf-capacity", str(2**63)]) == 2
    assert "--leaf-capacity: must be an integer" in capsys.readouterr().err
