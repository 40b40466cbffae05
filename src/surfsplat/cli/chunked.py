"""``surfsplat build --chunked``: a chunked hierarchy directory for clouds larger than memory.

The options go onto the ``build`` subcommand (:func:`add_build_options`); :func:`cmd_build` runs
the chunked build when ``--chunked`` is given and the one-file build otherwise; :func:`cmd_info`
describes a chunked hierarchy and leaves everything else to ``surfsplat info``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import progress
from ..errors import InputError
from ..hierarchy.chunked import (CELL_POINTS, CHUNK_POINTS, LOCAL_SCHEDULERS, build_chunked, is_chunked_hierarchy,
                                 read_manifest)
from . import commands
from . import options as opt


def add_build_options(p: argparse.ArgumentParser) -> None:
    """``--chunked``, ``--cell-points``, ``--chunk-points``, ``--scheduler``, ``--workers``."""
    g = p.add_argument_group("chunked build (clouds larger than memory; needs the dask extra)")
    g.add_argument("--chunked", action="store_true",
                   help="stream the input (LAS/LAZ, binary PLY) in chunks into a chunked hierarchy directory "
                        "-o MODEL.ssh: grid cells preprocessed with halos and built as Dask tasks, read lazily "
                        "by render")
    g.add_argument("--cell-points", type=opt.number(int, low=100, high=2**40), default=CELL_POINTS, metavar="N",
                   help="at most N points in a grid cell (one task's memory: ~0.5 KB a point; "
                        "default %(default)s)")
    g.add_argument("--chunk-points", type=opt.number(int, low=1, high=2**40), default=CHUNK_POINTS, metavar="N",
                   help="points read from the input at a time (default %(default)s)")
    g.add_argument("--scheduler", default="threads", metavar="NAME|tcp://HOST:PORT",
                   help=f"where the cell tasks run: {', '.join(LOCAL_SCHEDULERS)} (local; default %(default)s) "
                        "or the address of a Dask scheduler (its workers must see the output folder)")
    g.add_argument("--workers", type=opt.number(int, low=1, high=4096), metavar="N",
                   help="local threads or processes (default: the CPU count)")


def cmd_build(args) -> None:
    """``surfsplat build``: the chunked build with ``--chunked``, else the one-file .npz build."""
    if not args.chunked:
        for name in ("cell_points", "chunk_points", "workers"):
            if getattr(args, name) not in (None, {"cell_points": CELL_POINTS, "chunk_points": CHUNK_POINTS}.get(name)):
                raise InputError(f"--{name.replace('_', '-')} needs --chunked")
        commands.cmd_build(args)
        return
    if args.compact:
        raise InputError("--compact writes one-file hierarchies (.npz); a chunked hierarchy's cells are full files")
    check_chunked_output(Path(args.output), Path(args.input))
    options = opt.source_options(args)
    report = build_chunked(args.input, args.output, k=options.k, outliers=options.outliers,
                           sharp_angle=options.raw_sharp_angle, leaf_capacity=args.leaf_capacity,
                           cell_points=args.cell_points, chunk_points=args.chunk_points, scheduler=args.scheduler,
                           workers=args.workers)
    s = report.seconds
    progress.message(f"{report.points:,} splats ({report.input_points:,} points read) in {report.cells:,} cells "
                     f"({report.flipped} flipped to agree with their neighbours), {report.nodes:,} nodes, "
                     f"{report.bytes / 2**20:,.1f} MiB ({report.bytes / max(report.points, 1):.0f} B a splat) in "
                     f"{s['total']:.1f} s (stream {s['stream']:.1f}, preprocess {s['preprocess']:.1f}, "
                     f"orient {s['orient']:.1f}, build {s['build']:.1f}) -> {report.path}")


def check_chunked_output(out: Path, source: Path) -> None:
    """Before any work: the output folder is not the input, does not hold it, and is a chunked
    hierarchy if it exists (a build replaces only its own kind of folder; anything else is refused)."""
    commands.check_output(out, (source,), directory=True)
    if source.resolve().is_relative_to(out.resolve()):
        raise InputError(f"{out}: refusing to replace the folder holding the input {source}")
    if out.exists() and not is_chunked_hierarchy(out):
        raise InputError(f"{out}: exists and is not a chunked hierarchy; refusing to replace it "
                         f"(remove it or name another output)")


def cmd_info(args) -> None:
    """``surfsplat info``: a chunked hierarchy's manifest summary, else the point file or hierarchy."""
    if not is_chunked_hierarchy(args.input):
        commands.cmd_info(args)
        return
    m = read_manifest(args.input)
    cells = m["cells"]
    size = sum(int(v) for c in cells for v in c["files"].values())
    build = m.get("build", {})
    grid = m["grid"]
    print(f"file:       {args.input} (surfsplat chunked hierarchy, format {m['format_version']})")
    print(f"points:     {m['points']:,} ({build.get('input_points', 0):,} read from {build.get('input', '?')})")
    print(f"nodes:      {m['nodes']:,}")
    print(f"cells:      {len(cells):,} of side {grid['cell_size']:.4g} in a {' x '.join(map(str, grid['dims']))} grid; "
          f"{min(c['points'] for c in cells):,} to {max(c['points'] for c in cells):,} points each")
    print(f"origin:     {' '.join(f'{x:.10g}' for x in m['origin'])} (positions are stored relative to it)")
    print(f"bounds:     min {' '.join(f'{x:.10g}' for x in m['bounds']['min'])}  "
          f"max {' '.join(f'{x:.10g}' for x in m['bounds']['max'])}")
    print(f"cell files: {size / 2**20:,.1f} MiB ({size / max(int(m['points']), 1):.0f} B a splat)")
    attributes = m.get("attributes", [])
    print("attributes: " + (", ".join(f"{a['name']} ({a['dtype']})" for a in attributes) or "none")
          + (" (--color-by NAME)" if attributes else ""))
    seconds = build.get("seconds", {})
    if seconds:
        print(f"build:      {seconds.get('total', 0):.1f} s with {build.get('scheduler')}, k {build.get('k')}, "
              f"cells of at most {build.get('cell_points', 0):,} points")
