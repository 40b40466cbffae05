"""The viewer's full-quality frame with the hidden splats skipped per block (``passes.HIZ_BLOCK`` 8) and not (0),
alternated frame by frame in one scripted viewer (``surfsplat.view(..., frames=N)``, a still camera: every frame
is a full-quality one), and whether the two pictures are the same.

    xvfb-run -a python benchmarks/viewer_frame.py MODEL.ply [--frames 9] [--size 1280 720]

Writes benchmarks/results/viewer_frame.md and .json (the first frame of each kind, a warm-up, is left out).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_description, save_results  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model")
    parser.add_argument("--frames", type=int, default=9)
    parser.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    args = parser.parse_args()

    import surfsplat.viewer as viewer
    from surfsplat.rendering import passes
    from surfsplat.viewer import app

    draw = app.Viewer.render
    times: dict[int, list] = {0: [], 8: []}
    images: dict[int, np.ndarray] = {}
    count = [0]

    def render(self, full: bool) -> None:
        if not full:
            return draw(self, full)
        block = 8 if count[0] % 2 == 0 else 0
        count[0] += 1
        passes.HIZ_BLOCK = block
        self.ctx.finish()
        start = time.perf_counter()
        draw(self, full)
        self.ctx.finish()
        times[block].append(time.perf_counter() - start)
        images[block] = self.full_image()

    app.Viewer.render = render
    viewer.view(args.model, frames=args.frames, size=tuple(args.size))
    passes.HIZ_BLOCK = 8
    row = {"model": args.model, "size": args.size, "off_ms": 1e3 * float(np.median(times[0][1:])),
           "on_ms": 1e3 * float(np.median(times[8][1:])), "off_frames_ms": [round(1e3 * t) for t in times[0]],
           "on_frames_ms": [round(1e3 * t) for t in times[8]],
           "same_picture": bool(np.array_equal(images[0], images[8]))}
    text = "\n".join([
        f"Machine: {machine_description()}, GL: llvmpipe; {time.strftime('%Y-%m-%d')}; command: "
        f"`python {' '.join(shlex.quote(a) for a in sys.argv)}`", "",
        "The viewer's full-quality `ewa` frames (drawn into its texture, waited for), the test on and off "
        "alternated; medians without each kind's first frame. The machine is shared: read the ratio.", "",
        "| model | size | off: ms | on: ms | ratio | same picture | off: frames ms | on: frames ms |",
        "|---|---|---:|---:|---:|---|---|---|",
        f"| {Path(args.model).name} | {args.size[0]}x{args.size[1]} | {row['off_ms']:,.0f} | {row['on_ms']:,.0f} | "
        f"{row['on_ms'] / row['off_ms']:.2f} | {'yes' if row['same_picture'] else 'no'} | "
        f"{', '.join(map(str, row['off_frames_ms']))} | {', '.join(map(str, row['on_frames_ms']))} |"]) + "\n"
    save_results("viewer_frame", text, row)


if __name__ == "__main__":
    main()
