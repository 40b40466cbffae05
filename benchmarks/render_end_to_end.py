"""``surfsplat render FILE -o out.png --width 1024 --height 1024`` end to end, on real data, with its parts.

Two inputs (the cases of ``benchmarks/preprocess_real.py``):

* ``featuretype.ply`` (shared data: a 6k-vertex CAD part): its closed surface is sampled for the view;
* a photogrammetry-like scan of 342,000 noisy points made from ``frag_115.ply``
  (:func:`preprocess_real.noisy_scan`), saved as a binary PLY without normals: preprocessed.

Per case and tree (``--baseline SRC``: the ``src`` directory of another checkout, run alternately with
this one): the command's wall and CPU seconds (user + system of the child, best of ``--repeats`` by
CPU; the machine may be shared: the load average before each run is kept), the parts of one run in
a process of its own (import, reading, each preprocessing or sampling stage, framing, upload, each
pass of the drawing, read-back, PNG writing: wall seconds, the passes each finished before the next;
each part's least time over ``--repeats`` such runs),
whether the two trees' PNGs are equal pixel for pixel, and for the mesh the picture against the mesh's
own (``render_mesh``, 4 x 4 supersampled, same camera: PSNR over both silhouettes and inside the eroded
one, hole pixels; :func:`surfsplat.metrics.compare`).

    python benchmarks/render_end_to_end.py [--size 1024] [--repeats 3] [--baseline /path/to/old/src]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine_description, save_results  # noqa: E402
from common import markdown_table  # noqa: E402

DATA = Path(os.environ.get("SURFSPLAT_DATA", "/work/shared/data"))

#: Functions timed in the breakdown: (module, attribute, label). Missing ones (older trees) are skipped.
PARTS = [
    ("surfsplat.pipeline.sources", "read_source", "read (and preprocess)"),
    ("surfsplat.pipeline.framing", "resolve_camera", "automatic camera"),
    ("surfsplat.pipeline.models", "MeshModel.surface", "mesh sampling (all its stages)"),
    ("surfsplat.rendering.renderer", "Renderer.__init__", "OpenGL context"),
    ("surfsplat.rendering.renderer", "Renderer.upload", "upload"),
    ("surfsplat.rendering.renderer", "Renderer.draw", "drawing (all passes)"),
    ("surfsplat.rendering.renderer", "Renderer._read_tile", "read-back"),
    ("surfsplat.rendering.frame", "Frame.save", "PNG writing"),
]
PASSES = ["ClearPass", "ComputeVisibilityPass", "VisibilityPass", "CracksPass", "HizPass", "AccumulationPass",
          "NormalizationPass", "FillPass"]


def breakdown_worker(args: list[str]) -> dict:
    """One ``surfsplat render`` in this process with its parts timed (see the module docstring)."""
    times: dict[str, float] = {}
    start = time.perf_counter()
    import surfsplat.cli as cli
    times["import"] = time.perf_counter() - start

    def add(label, seconds):
        times[label] = times.get(label, 0.0) + seconds

    def timed(fn, label):
        @functools.wraps(fn)
        def run(*a, **k):
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                add(label, time.perf_counter() - t)
        return run

    for module, attr, label in PARTS:
        try:
            owner = importlib.import_module(module)
            *path, name = attr.split(".")
            for part in path:
                owner = getattr(owner, part)
            fn = getattr(owner, name)
        except (ImportError, AttributeError):
            continue
        wrapped = timed(fn, label)
        setattr(owner, name, wrapped)
        if not path:   # imported by name elsewhere
            for other in list(sys.modules.values()):
                if other is not None and getattr(other, name, None) is fn:
                    setattr(other, name, wrapped)
    passes = importlib.import_module("surfsplat.rendering.passes")
    for name in PASSES:
        cls = getattr(passes, name, None)
        if cls is None:
            continue

        def run(self, renderer, frame, _fn=cls.run, _name=name):
            t = time.perf_counter()
            _fn(self, renderer, frame)
            renderer.ctx.finish()
            add(f"  pass {_name}", time.perf_counter() - t)
        cls.run = run
    progress = importlib.import_module("surfsplat.progress")
    stage = progress.stage

    @contextlib.contextmanager
    def staged(name, *a, **k):
        t = time.perf_counter()
        with stage(name, *a, **k) as s:
            yield s
        add("  stage: loading the file" if name.startswith("loading ") else f"  stage: {name}", time.perf_counter() - t)

    for module in list(sys.modules.values()):
        if module is not None and module.__name__.startswith("surfsplat") and getattr(module, "stage", None) is stage:
            module.stage = staged
    t = time.perf_counter()
    sys.argv = ["surfsplat", "render", *args]
    with contextlib.suppress(SystemExit):
        cli.main()
    times["command (after import)"] = time.perf_counter() - t
    times["process (import + command)"] = time.perf_counter() - start
    return times


def quality_worker(path: str, size: int) -> dict:
    """The default render of a mesh file against ``render_mesh`` of the same camera."""
    from surfsplat import metrics
    from surfsplat.api import prepare, render_mesh

    view = prepare(path)
    camera = view.camera(None, size, size)
    result = view.render(camera, width=size, height=size)
    score = metrics.compare(result.frame, render_mesh(path, camera))
    return {"splats": int(result.splats), "psnr": float(score["psnr"]), "psnr_inner": float(score["psnr_inner"]),
            "holes": int(score["holes"])}


def run_command(src: str, path: str, out: str, size: int) -> tuple[float, float, float]:
    """``surfsplat render`` in a fresh process with ``src`` first on the path: (wall s, CPU s, load)."""
    env = dict(os.environ, PYTHONPATH=src)
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.perf_counter()
    subprocess.run([sys.executable, "-m", "surfsplat", "render", path, "-o", out, "--width", str(size),
                    "--height", str(size), "-q"], env=env, check=True, capture_output=True)
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, load


def in_process(src: str, flag: str, *args: str) -> dict:
    """A worker of this script in a fresh process with ``src`` first on the path."""
    result = subprocess.run([sys.executable, __file__, flag, *args], env=dict(os.environ, PYTHONPATH=src),
                            capture_output=True, text=True, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--baseline", help="src directory of another checkout to compare with")
    parser.add_argument("--breakdown-worker", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    parser.add_argument("--quality-worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.breakdown_worker is not None:
        print(json.dumps(breakdown_worker(args.breakdown_worker)))
        return
    if args.quality_worker:
        print(json.dumps(quality_worker(args.quality_worker, args.size)))
        return
    from PIL import Image

    from preprocess_real import noisy_scan
    from surfsplat.io import save_ply

    here = str(Path(__file__).resolve().parents[1] / "src")
    trees = [("before", args.baseline), ("after", here)] if args.baseline else [("this tree", here)]
    data: dict = {"machine": machine_description(), "date": time.strftime("%Y-%m-%d"), "size": args.size,
                  "command": "python benchmarks/render_end_to_end.py " + " ".join(sys.argv[1:]), "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        scan = Path(tmp) / "scan.ply"
        save_ply(noisy_scan(), scan)
        cases = {"featuretype.ply (CAD mesh)": str(DATA / "featuretype.ply"),
                 "noisy scan, 342k points (from frag_115.ply)": str(scan)}
        for case, path in cases.items():
            entry: dict = {"runs": {label: [] for label, _ in trees}, "parts": {}, "quality": {}}
            for _ in range(args.repeats):
                for label, src in trees:   # alternating: the machine's load hits both alike
                    out = str(Path(tmp) / f"{label}.png")
                    wall, cpu, load = run_command(src, path, out, args.size)
                    entry["runs"][label].append({"wall": wall, "cpu": cpu, "load": load})
                    print(case, label, f"wall {wall:.2f} s, CPU {cpu:.2f} s, load {load:.2f}", flush=True)
            if len(trees) == 2:
                a, b = (np.asarray(Image.open(Path(tmp) / f"{label}.png")) for label, _ in trees)
                entry["pixels differing"] = int((a != b).any(axis=-1).sum())
            for _ in range(args.repeats):
                for label, src in trees:   # each part's least time over the repeats
                    parts = in_process(src, "--breakdown-worker", path, "-o", str(Path(tmp) / "parts.png"),
                                       "--width", str(args.size), "--height", str(args.size), "-q")
                    old = entry["parts"].setdefault(label, {})
                    for part, seconds in parts.items():
                        old[part] = min(seconds, old.get(part, float("inf")))
            for label, src in trees:
                if path.endswith("featuretype.ply"):
                    entry["quality"][label] = in_process(src, "--quality-worker", path, "--size", str(args.size))
            data["cases"][case] = entry
    save_results("render_end_to_end", report(data, [label for label, _ in trees]), data)


def report(data: dict, labels: list[str]) -> str:
    """The Markdown page of :func:`main`'s measurements."""
    lines = [f"Machine: {data['machine']}", f"Date: {data['date']}", f"Command: {data['command']}", "",
             f"`surfsplat render FILE -o out.png --width {data['size']} --height {data['size']}` in a fresh "
             "process; best run by CPU seconds (user + system), with the 1-minute load average before it "
             "(the machine is shared: ratios within one run are steadier than the absolute times).", ""]
    rows = []
    for case, entry in data["cases"].items():
        for label in labels:
            runs = entry["runs"][label]
            best = min(runs, key=lambda r: r["cpu"])
            rows.append([case, label, round(best["wall"], 2), round(best["cpu"], 2), round(best["load"], 2),
                         round(float(np.median([r["wall"] for r in runs])), 2), len(runs)])
    lines += markdown_table(["case", "tree", "wall s", "CPU s", "load", "median wall s", "runs"], rows)
    for case, entry in data["cases"].items():
        lines += ["", f"## {case}", ""]
        if "pixels differing" in entry:
            lines += [f"PNG pixels differing between the trees: {entry['pixels differing']:,}", ""]
        if entry["quality"]:
            q = [[label, v["splats"], round(v["psnr"], 2), round(v["psnr_inner"], 2), v["holes"]]
                 for label, v in entry["quality"].items()]
            lines += ["Against `render_mesh` (4 x 4), same camera:", ""]
            lines += markdown_table(["tree", "splats drawn", "PSNR dB", "PSNR inside dB", "hole pixels"], q) + [""]
        parts = list(dict.fromkeys(k for label in labels for k in entry["parts"][label]))
        lines += ["Parts of a run (wall seconds, each part's least over the runs; indented: within the line "
                  "above):", ""]
        lines += markdown_table(["part", *labels],
                                [[p, *[round(entry["parts"][label].get(p, float("nan")), 3) for label in labels]]
                                 for p in parts])
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
