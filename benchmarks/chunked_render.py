"""Peak memory and time of rendering a chunked hierarchy from the command line.

Runs ``surfsplat render MODEL -o OUT.png --width 1024 --height 1024 --technique ewa`` in a child
process under ``/usr/bin/time -v`` for three views: the overview without a budget, the overview
with ``--point-budget 2000000`` and a zoomed-in oblique view, one after the other (the machine is
shared). Each run is stored under a label (``--label before`` / ``after``) in
``benchmarks/results/chunked_render.json``; the Markdown table of every label is printed and saved
to ``benchmarks/results/chunked_render.md``. The model is not built here: give one
(``benchmarks/chunked_build.py`` writes them); its pictures go to ``--pictures`` (never the repository).

    python benchmarks/chunked_render.py /tmp/big64/big.ssh --label after --pictures /tmp/big64
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_description  # noqa: E402

RESULTS = HERE / "results"


def views(model: Path) -> dict[str, list[str]]:
    """Name -> extra ``surfsplat render`` arguments; the zoomed view looks at a point a quarter of the
    model's extent from its center, from a tenth of the extent away, obliquely."""
    manifest = json.loads((model / "manifest.json").read_text())
    lo, hi = manifest["bounds"]["min"], manifest["bounds"]["max"]
    extent = max(hi[0] - lo[0], hi[1] - lo[1])
    cx, cy, cz = ((a + b) / 2 for a, b in zip(lo, hi))
    target = (cx - extent / 4, cy - extent / 4, lo[2])
    eye = (target[0] - extent / 20, target[1] - extent / 20, target[2] + extent / 20)
    zoom = ["--eye", *map(str, eye), "--target", *map(str, target), "--up", "0", "0", "1", "--fov", "50"]
    return {"overview, no budget": [], "overview, --point-budget 2000000": ["--point-budget", "2000000"],
            "zoomed in, no budget": zoom}


def run(model: Path, name: str, extra: list[str], out: Path) -> dict:
    """One render under /usr/bin/time -v: wall seconds, peak RSS (MiB), the splats drawn."""
    command = ["/usr/bin/time", "-v", sys.executable, "-m", "surfsplat", "render", str(model), "-o", str(out),
               "--force", "--width", "1024", "--height", "1024", "--technique", "ewa", *extra]
    proc = subprocess.run(command, capture_output=True, text=True)
    text = proc.stdout + proc.stderr
    if proc.returncode != 0:
        raise SystemExit(f"{name}: render failed ({proc.returncode}):\n{text[-3000:]}")
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", text).group(1)) / 1024
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", text).group(1)
    seconds = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall.split(":"))))
    drawn = re.search(r"rendered (.*?) with", text)
    return {"view": name, "seconds": round(seconds, 1), "peak_rss_mib": round(rss),
            "drawn": drawn.group(1) if drawn else "", "picture": str(out)}


#: What the labels of the stored table mean (the stored series).
NOTES = """
`before`: the earlier chunked views (every cell's node arrays kept for the whole view, a cache of a
quarter of the available memory, the budget as one tolerance found by bisection). `after`: cells
cut and gathered one at a time into output arrays (with a budget allocated once at the cut's size,
else grown by half when full), a cache of at most 512 MiB of node arrays, covariances not read,
and the budget as one priority order over all cells (Potree's).
The pictures of the same cut are equal (103-110 dB PSNR between the series); under the budget
the priority cut draws 1,999,999 splats at 29.2 dB against the full cut's picture, the bisection
1,932,060 at 29.1 dB. Times vary with the other jobs (load 5-6 on the 2 cores during the rows
above); an earlier run of each series, on a quieter machine: before 90.8 / 74.8 / 15.1 s, after
55.0 / 30.2 / 9.8 s (peak RSS within 1 % of the rows above).
"""


def table(results: dict, header: str) -> str:
    lines = [header, "", "| label | view | wall s | peak RSS MiB | drawn |", "|---|---|---|---|---|"]
    names = ["overview, no budget", "overview, --point-budget 2000000", "zoomed in, no budget"]
    for label, rows in results.items():
        for r in sorted(rows, key=lambda r: names.index(r["view"]) if r["view"] in names else len(names)):
            lines.append(f"| {label} | {r['view']} | {r['seconds']:.1f} | {r['peak_rss_mib']:,} | {r['drawn']} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path, help="a chunked hierarchy directory (surfsplat build --chunked)")
    parser.add_argument("--label", default="after", help="name of this series in the table")
    parser.add_argument("--pictures", type=Path, default=Path("/tmp"), help="folder for the rendered pictures")
    parser.add_argument("--only", nargs="*", help="run only the views whose names start with these")
    args = parser.parse_args()
    manifest = json.loads((args.model / "manifest.json").read_text())
    store = RESULTS / "chunked_render.json"
    results = json.loads(store.read_text()) if store.exists() else {}
    rows = []
    for i, (name, extra) in enumerate(views(args.model).items()):
        if args.only and not any(name.startswith(o) for o in args.only):
            continue
        rows.append(run(args.model, name, extra, args.pictures / f"chunked_render_{args.label}_{i}.png"))
        print(rows[-1], flush=True)
    done = {r["view"] for r in rows}   # views not run this time keep their earlier row
    results[args.label] = [r for r in results.get(args.label, []) if r["view"] not in done] + rows
    store.write_text(json.dumps(results, indent=1))
    header = (f"# Rendering a chunked hierarchy: peak RSS and time (1024x1024, ewa, command line)\n\n"
              f"Machine: llvmpipe, 2-core EPYC ({machine_description()}), shared with other jobs. Model: "
              f"{args.model.name}, {manifest['points']:,} points in {len(manifest['cells'])} cells. Each row is "
              f"one `/usr/bin/time -v surfsplat render` child process (peak RSS: its maximum resident set, "
              f"memory-mapped pages it touched included).")
    text = table(results, header) + NOTES
    (RESULTS / "chunked_render.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
