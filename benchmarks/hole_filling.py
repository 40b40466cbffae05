"""The default pictures before and after a change of the defaults (``--compare``): hole filling
(``RenderOptions.fill_holes``, the default) or edge coverage (``VisibilityOptions.edge_coverage``) with
the automatic culling of closed meshes (against both off: the defaults before).

Each source is rendered as ``surfsplat render`` renders it by default (automatic camera, headlight, ``ewa``
unless named; a mesh sampled for the view), once with ``fill_holes=False`` and once with the fill, at
``--size``. Reported per source: the pixels the fill changed, the hole pixels of the picture (pixels the
fill rule finds enclosed: :func:`surfsplat.reference.fill_holes` on the frame) before and after, the
largest color change, and the time of a frame with and without the fill pass (best of ``--repeat``).
PNGs of both and of the changed pixels (red) go to ``--images`` (not the repo).

    python benchmarks/hole_filling.py [--size 512] [--images /tmp/hole_filling] [--compare fill]

Writes benchmarks/results/hole_filling.md and .json (``--compare edge-coverage``: edge_coverage_default.md).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, machine_description, markdown_table  # noqa: E402

import surfsplat  # noqa: E402
from surfsplat import RenderOptions, VisibilityOptions, reference, scenes_faulty  # noqa: E402
from surfsplat.rendering.passes import FILL_DEPTH_PX, FILL_GAP_PX, FILL_ITERATIONS  # noqa: E402
from surfsplat.rendering.renderer import default_renderer  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
#: ``--compare``: (results name, options before, options after, what changes).
COMPARISONS = {
    "fill": ("hole_filling", RenderOptions(fill_holes=False), RenderOptions(fill_holes=True), "the hole filling"),
    "edge-coverage": ("edge_coverage_default",
                      RenderOptions(visibility=VisibilityOptions(edge_coverage=False, cull_backfaces=False)),
                      RenderOptions(), "edge coverage and automatic culling (before: neither, back faces drawn)"),
}


def sources() -> list[tuple[str, object, str]]:
    """(name, source, technique) of the pictures compared: the development data where it is there."""
    items: list[tuple[str, object, str]] = []
    for name, file in (("bunny", "bunny.ply"), ("CAD part", "featuretype.ply"), ("frag", "frag_115.ply"),
                       ("LAS sample", "simple.las")):
        if (DATA / file).exists():
            items.append((name, str(DATA / file), "ewa"))
    items.append(("demo torus", "demo:torus", "ewa"))
    items.append(("faulty scan", surfsplat.preprocess(scenes_faulty.faulty_scan().cloud), "ewa"))
    items.append(("bunny flat", str(DATA / "bunny.ply"), "flat") if (DATA / "bunny.ply").exists() else None)
    return [item for item in items if item is not None]


def holes(frame) -> int:
    """Pixels of ``frame`` the fill rule (as many iterations as the fill pass runs) finds enclosed."""
    return int(reference.fill_holes(frame.color, frame.weight, frame.depth, frame.alpha, frame.camera.focal_px,
                                    FILL_GAP_PX, FILL_DEPTH_PX, FILL_ITERATIONS)[4].sum())


def best_time(view, technique, size, options, repeat) -> tuple[object, float]:
    """The frame of ``view`` and its best time of ``repeat`` (seconds: drawing and read-back)."""
    results = [view.render(technique=technique, width=size, height=size, options=options) for _ in range(repeat)]
    return results[-1].frame, min(r.seconds for r in results)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--images", type=Path, default=Path("/tmp/hole_filling"))
    parser.add_argument("--compare", choices=list(COMPARISONS), default="fill")
    args = parser.parse_args()
    name, before, after, what = COMPARISONS[args.compare]
    args.images.mkdir(parents=True, exist_ok=True)
    rows = []
    for source_name, source, technique in sources():
        view = surfsplat.prepare(source)
        off, t_off = best_time(view, technique, args.size, before, args.repeat)
        on, t_on = best_time(view, technique, args.size, after, args.repeat)
        off, t_off2 = best_time(view, technique, args.size, before, args.repeat)   # alternated: a shared machine
        t_off = min(t_off, t_off2)
        diff = np.abs(on.color - off.color).max(axis=-1)
        changed = diff > 0
        slug = f"{args.compare}_{source_name.replace(' ', '_')}"
        for frame, tag in ((off, "off"), (on, "on")):
            Image.fromarray((np.clip(frame.color, 0, 1) * 255 + 0.5).astype(np.uint8)).save(
                args.images / f"{slug}_{tag}.png")
        marked = (np.clip(off.color, 0, 1) * 255 + 0.5).astype(np.uint8)
        marked[changed] = (255, 0, 0)
        Image.fromarray(marked).save(args.images / f"{slug}_changed.png")
        visible = int(np.count_nonzero(diff > 1 / 255))
        rows.append([source_name, technique, int(changed.sum()), visible, holes(off), holes(on),
                     round(float(diff.max()), 3), int(np.count_nonzero(off.alpha > 0)),
                     int(np.count_nonzero(on.alpha > 0)), round(t_off * 1000), round(t_on * 1000)])
        print(rows[-1], flush=True)
    columns = ["source", "technique", "pixels changed", "by > 1/255", "holes before", "holes after", "max change",
               "covered before", "covered after", "frame ms before", "frame ms after"]
    machine = machine_description(default_renderer().ctx.info["GL_RENDERER"])
    save(name, machine, "python benchmarks/hole_filling.py " + shlex.join(sys.argv[1:]), columns, rows,
         f"Default pictures at {args.size}x{args.size} (automatic camera, headlight), before and after {what}. "
         "Holes: pixels the fill rule finds enclosed (its gaps of up to 3 px).")


def save(name: str, machine: str, command: str, columns: list[str], rows: list[list], note: str) -> None:
    """Print the table and write ``results/{name}.md`` (machine, date, command, note, table) and ``.json``."""
    date = time.strftime("%Y-%m-%d")
    text = "\n".join([f"Machine: {machine}", f"Date: {date}", f"Command: `{command.strip()}`", "", note, ""]
                     + markdown_table(columns, rows))
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.md").write_text(text + "\n")
    (RESULTS / f"{name}.json").write_text(json.dumps({"machine": machine, "date": date, "command": command.strip(),
                                                      "columns": columns, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
