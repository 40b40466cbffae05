"""The subcommands: each turns parsed flags into typed options, calls :mod:`surfsplat.api` or the
library function that does the work, writes the output and reports what it did."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from .. import api, progress
from ..pipeline import DEMO_PREFIX, View, check_source, is_hierarchy_file, load_cloud
from ..camera import camera_flags
from ..camera_path import interpolate_cameras
from ..errors import InputError
from ..io.atomic import check_writable, same_file
from ..io.camera_file import save_camera
from ..io.camera_formats import load_cameras
from ..io.npz import read_npz
from ..io.image_maps import check_map_path, normals_from_depth, save_coverage, save_depth, save_normals
from ..io.video import check_video_path, write_video
from ..rendering.frame import check_image_path
from ..geometry.phong import phong_splats
from ..geometry.preprocess import neighbour_spacing, preprocess
from ..geometry.sampling import sample_mesh
from ..cloud import SplatCloud
from ..hierarchy import build_hierarchy, load_hierarchy, save_hierarchy
from ..hierarchy.nodes import is_majority_voted
from ..hierarchy.storage import COMPACT_VERSION
from ..colors import describe_attributes
from ..io import load, load_mesh, save_ply
from ..web import export
from . import options as opt


#: The flags naming input files (besides the positional inputs).
INPUT_FLAGS = ("camera", "cameras", "path")


def inputs_of(args) -> tuple[Path, ...]:
    """Every input file the parsed flags name: the positional input(s) (``demo:NAME`` is none) and
    the files of ``--camera``, ``--cameras``, ``--path``."""
    named = []
    for flag in ("input", "mesh", *INPUT_FLAGS):
        value = getattr(args, flag, None)
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, (str, Path)) and not str(item).startswith(DEMO_PREFIX):
                named.append(Path(item))
    return tuple(named)


def refuse_overwriting_inputs(out: Path, inputs: tuple[Path, ...]) -> None:
    """InputError when ``out`` is one of the input files: the same file (device and inode), so a
    symbolic or hard link to an input counts as the input. Outputs are otherwise replaced."""
    for path in inputs:
        if same_file(out, path):
            raise InputError(f"{out}: refusing to overwrite the input file {path} (the same file)")


def check_output(out, inputs: tuple[Path, ...], *, directory: bool = False) -> Path:
    """Before any work: ``out`` can be written (its folder exists) and is none of ``inputs``; an
    existing output is replaced when the command writes it (atomically, :mod:`surfsplat.io.atomic`)."""
    out = Path(out)
    refuse_overwriting_inputs(out, inputs)
    return check_writable(out, directory=directory)


def check_image_outputs(args, inputs: tuple[Path, ...] = ()) -> tuple[Path, Path | None, Path | None]:
    """Before any work: the image, depth, normal, coverage and camera outputs can be written (suffix,
    folder, none of them an input nor another output). Returns (image, depth or None, camera file or None)."""
    inputs = tuple(dict.fromkeys(inputs + inputs_of(args)))
    for flag in OUTPUT_FLAGS:   # an input named as an output is the first thing to say
        if getattr(args, flag, None):
            refuse_overwriting_inputs(Path(getattr(args, flag)), inputs)
    named = [Path(getattr(args, flag)).resolve() for flag in OUTPUT_FLAGS if getattr(args, flag, None)]
    if len(set(named)) < len(named):
        raise InputError(f"{args.output}: two outputs of one render name the same file")
    out = check_writable(check_image_path(args.output))
    depth = Path(args.depth) if getattr(args, "depth", None) else None
    if depth is not None:
        check_writable(check_map_path("depth", depth))
    for kind in ("normals", "coverage"):
        if getattr(args, kind, None):
            check_writable(check_map_path(kind, getattr(args, kind)))
    camera_file = Path(args.save_camera) if args.save_camera else None
    if camera_file is not None:
        check_writable(camera_file)
    return out, depth, camera_file


def save_outputs(frame, camera_file: Path | None, depth: Path | None) -> None:
    """Write the depth array and the camera file (replaced atomically; see :mod:`surfsplat.io.atomic`)."""
    if depth is not None:
        convention = save_depth(frame.depth, depth, *depth_range(frame))
        progress.message(f"depth ({convention}) -> {depth}")
    if camera_file is not None:
        save_camera(frame.camera, camera_file)
        progress.message(f"camera -> {camera_file}")


def save_maps(frame, args) -> None:
    """Write the normal and coverage maps ``--normals``, ``--coverage`` ask for
    (:mod:`surfsplat.io.image_maps`)."""
    if getattr(args, "normals", None):
        save_normals(normals_from_depth(frame.depth, frame.camera), args.normals)
        progress.message(f"normals (camera space, from the depth map) -> {args.normals}")
    if getattr(args, "coverage", None):
        save_coverage(frame.alpha, args.coverage, bit_depth=args.bit_depth)
        progress.message(f"coverage -> {args.coverage}")


def depth_range(frame) -> tuple[float, float]:
    """(near, far) of a depth PNG: the frame's camera's clip planes, else the drawn depths' range."""
    if frame.camera.near is not None and frame.camera.far is not None:
        return float(frame.camera.near), float(frame.camera.far)
    finite = frame.depth[np.isfinite(frame.depth)]
    near = float(finite.min()) if finite.size and finite.min() > 0 else 1.0
    return near, max(float(finite.max()) if finite.size else 0.0, 2.0 * near)


def prepared(source, args) -> View:
    """The view plan of ``source`` with the source and LOD flags of ``args``, loaded once."""
    return View(source, source_options=opt.source_options(args), lod=opt.lod_options(args))


def render_args(args) -> dict:
    """The technique, lighting, background, render options and supersampling the flags ask for
    (:meth:`surfsplat.pipeline.View.render`'s arguments)."""
    return dict(technique=args.technique, lights=opt.lights(args), background=args.background,
                options=opt.render_options(args), supersample=args.supersample)


def draw_and_save(plan: View, camera, args, outputs) -> None:
    """Draw a prepared view with a resolved camera as the render flags in ``args`` ask; save the image,
    and the depth and camera files of ``outputs`` (:func:`check_image_outputs`)."""
    out, depth, camera_file = outputs
    result = plan.render(camera, **render_args(args))
    result.frame.save(out, transparent=args.transparent, bit_depth=args.bit_depth)
    progress.message(f"rendered {result.describe()} with {args.technique} at {camera.width}x{camera.height} "
                     f"in {result.seconds:.2f} s -> {out}")
    save_outputs(result.frame, camera_file, depth)
    save_maps(result.frame, args)


def render_and_save(source, args, inputs: tuple[Path, ...] = ()) -> None:
    """Load ``source``, render it as the render flags in ``args`` ask, save the image (and depth, camera)."""
    outputs = check_image_outputs(args, inputs)
    check_source(source)
    camera = opt.camera_spec(args)
    width, height = opt.image_size(args, camera)
    opt.render_options(args)   # every option checked before the source is read
    plan = prepared(source, args)
    camera = plan.camera(camera, width, height)
    progress.message(f"camera: {camera_flags(camera)}")
    draw_and_save(plan, camera, args, outputs)


#: The flags naming output files, filled per job from a pattern.
OUTPUT_FLAGS = ("output", "depth", "normals", "coverage", "save_camera")


def job_for(args, many: bool, required: tuple[str, ...], **fields) -> argparse.Namespace:
    """A copy of ``args`` whose output flags have the pattern ``fields`` (``{stem}``, ``{name}``)
    filled in; with ``many`` jobs each pattern must contain one of the ``required`` fields."""
    job = argparse.Namespace(**vars(args))
    for flag in OUTPUT_FLAGS:
        pattern = getattr(args, flag, None)
        if not pattern:
            continue
        if many and not any("{" + key + "}" in pattern for key in required):
            wanted = " or ".join("{" + key + "}" for key in required)
            raise InputError(f"{pattern}: several outputs need a pattern with {wanted}, e.g. out/{{{required[0]}}}.png")
        try:
            setattr(job, flag, pattern.format(**fields))
        except (KeyError, IndexError, ValueError) as exc:
            raise InputError(f"{pattern}: bad output pattern ({exc}); use "
                             f"{' or '.join('{' + key + '}' for key in fields)}") from None
    return job


def check_jobs(jobs: list, inputs: tuple[Path, ...]) -> list:
    """Every job's outputs checked before any work (distinct, writable, not an input): their
    :func:`check_image_outputs`."""
    paths = [Path(getattr(job, flag)).resolve() for job in jobs for flag in OUTPUT_FLAGS if getattr(job, flag, None)]
    if len(set(paths)) < len(paths):
        raise InputError(f"{jobs[0].output}: several outputs map to the same file; use another pattern "
                         f"(are the names unique?)")
    return [check_image_outputs(job, inputs) for job in jobs]


def cmd_render(args) -> None:
    """``surfsplat render``: point/splat/mesh files or hierarchies to images (or ``--mesh``: the
    triangles); several inputs render one after another, every output checked before the first."""
    if getattr(args, "cameras", None):
        render_views(args)
        return
    inputs = tuple(Path(source) for source in args.input)
    jobs = []
    for source in args.input:
        job = job_for(args, len(args.input) > 1, ("stem", "name"), stem=Path(source).stem, name=Path(source).name)
        job.input = source
        jobs.append(job)
    check_jobs(jobs, inputs)
    with progress.stage(f"rendering {len(jobs)} inputs", unit="images", total=len(jobs), show=len(jobs) > 1) as done:
        for job in jobs:
            if job.mesh:
                render_mesh_and_save(job, (Path(job.input),))
            else:
                render_and_save(job.input, job, (Path(job.input),))
            done.update()


def render_views(args) -> None:
    """``render INPUT --cameras FILE``: every camera of FILE (:func:`~surfsplat.io.camera_formats.load_cameras`)
    to its own output, ``{name}`` in the patterns being the view's name; every output is checked
    before the model is loaded (once) and the first view rendered."""
    if len(args.input) != 1 or args.mesh:
        raise InputError("--cameras renders one INPUT (not with --mesh)")
    if args.camera or args.eye is not None or args.target is not None or args.up is not None:
        raise InputError("give either --cameras FILE or --camera/--eye/--target/--up, not both")
    source = args.input[0]
    inputs = (Path(source), Path(args.cameras))
    check_source(source)
    views = load_cameras(args.cameras, width=args.width, height=args.height)
    jobs = [job_for(args, len(views) > 1, ("name",), name=name, stem=Path(source).stem) for name, _ in views]
    outputs = check_jobs(jobs, inputs)
    plan = prepared(source, args)
    with progress.stage(f"rendering {len(jobs)} views", unit="images", total=len(jobs), show=len(jobs) > 1) as done:
        for job, (_, camera), job_outputs in zip(jobs, views, outputs):
            draw_and_save(plan, camera, job, job_outputs)
            done.update()


def cmd_turntable(args) -> None:
    """``surfsplat turntable``: frames orbiting the model about its up axis, as GIF, MP4 or WebM."""
    out = check_video_path(args.output)
    check_output(out, inputs_of(args))
    check_source(args.input)
    camera = opt.camera_spec(args)
    width, height = opt.image_size(args, camera)
    draw = render_args(args)
    seconds = args.seconds or args.frames / 24.0
    cameras = path_cameras(args)
    plan = prepared(args.input, args)
    if cameras is None:
        cameras = plan.orbit(camera, args.frames, args.degrees, args.elevation, width=width, height=height)
        progress.message(f"{args.frames} frames over {args.degrees:g} degrees, {seconds:g} s; first camera: "
                         f"{camera_flags(cameras[0])}")
    width, height = cameras[0].width, cameras[0].height
    frames = plan.frames(cameras, **draw)
    write_video(frames, out, fps=args.frames / seconds)
    progress.message(f"wrote {args.frames} frames at {width}x{height} -> {out}")


def path_cameras(args) -> list | None:
    """``turntable --path FILE``: ``--frames`` cameras on a smooth path through the key views of FILE
    (:func:`~surfsplat.io.camera_formats.load_cameras`; :mod:`surfsplat.camera_path`), checked before
    the model is loaded; None without ``--path`` (an orbit)."""
    if not args.path:
        if args.loop or args.constant_speed:
            raise InputError("--loop and --constant-speed shape a camera path; give --path CAMERAS")
        return None
    if args.camera or args.eye is not None or args.target is not None or args.up is not None:
        raise InputError("give either --path FILE or --camera/--eye/--target/--up, not both")
    if args.elevation is not None or args.degrees != 360.0:
        raise InputError("--degrees and --elevation shape the orbit; a --path gives the cameras itself")
    keys = [camera for _, camera in load_cameras(args.path, width=args.width, height=args.height)]
    if len(keys) < 2:
        raise InputError(f"{args.path}: a camera path needs at least 2 key views, the file has {len(keys)}")
    cameras = interpolate_cameras(keys, max(args.frames, 2), closed=args.loop, constant_speed=args.constant_speed,
                                  width=args.width, height=args.height)
    progress.message(f"{len(cameras)} frames on a {'closed ' if args.loop else ''}path through {len(keys)} key "
                     f"views of {args.path}{' at constant speed' if args.constant_speed else ''}")
    return cameras


def render_mesh_and_save(args, inputs: tuple[Path, ...]) -> None:
    """``render --mesh``: the input's triangles with the same camera and lighting (ground truth)."""
    out, depth, camera_file = check_image_outputs(args, inputs)
    camera = opt.camera_spec(args)
    width, height = opt.image_size(args, camera)
    start = time.perf_counter()
    frame = api.render_mesh(args.input, camera, width=width, height=height, lights=opt.lights(args),
                            background=args.background, supersample=max(4, args.supersample))
    progress.message(f"camera: {camera_flags(frame.camera)}")
    frame.save(out, transparent=args.transparent, bit_depth=args.bit_depth)
    progress.message(f"rendered the mesh at {frame.camera.width}x{frame.camera.height} "
                     f"in {time.perf_counter() - start:.2f} s -> {out}")
    save_outputs(frame, camera_file, depth)
    save_maps(frame, args)


def cmd_demo(args) -> None:
    """``surfsplat demo``: a built-in procedural scene to an image."""
    render_and_save(DEMO_PREFIX + args.scene, args)


def cmd_info(args) -> None:
    """``surfsplat info``: counts, bounds, properties and spacing of a point file or a hierarchy."""
    if is_hierarchy_file(args.input):
        hierarchy_info(args.input)
        return
    cloud = load(args.input)
    lo, hi = cloud.bounds()
    print(f"file:       {args.input}")
    print(f"points:     {len(cloud):,}")
    print(f"bounds:     min {np.array2string(lo, precision=4)}  max {np.array2string(hi, precision=4)}")
    print(f"size:       {np.array2string(hi - lo, precision=4)} (diagonal {np.linalg.norm(hi - lo):.4g})")
    present = [name for name in ("normals", "colors", "u", "v", "normal_field", "clip_lines")
               if getattr(cloud, name) is not None]
    print(f"properties: positions{', ' + ', '.join(present) if present else ''}")
    for line in describe_attributes(cloud):
        print(f"attribute:  {line}")
    if cloud.u is not None:
        r = cloud.radii
        print(f"splat radius: min {r.min():.4g}  median {np.median(r):.4g}  max {r.max():.4g}")
    if len(cloud) > 1:
        stats = neighbour_spacing(cloud.positions)
        print("neighbour spacing: " + "  ".join(f"{key} {value:.4g}" for key, value in stats.items()))


def hierarchy_info(path) -> None:
    """Print what ``surfsplat info`` says of a hierarchy file."""
    hierarchy = load_hierarchy(path)
    d = hierarchy.describe()
    version = int(read_npz(path, ("format_version",))["format_version"])
    layout = ", compact: splats quantized to 19 bytes" if version == COMPACT_VERSION else ""
    print(f"file:       {path} (surfsplat LOD hierarchy, format {version}{layout}; "
          f"{Path(path).stat().st_size / d['points']:.0f} bytes a point)")
    print(f"points:     {d['points']:,}")
    print(f"nodes:      {d['nodes']:,} in {d['levels']} levels ({d['leaves']:,} leaves, capacity "
          f"{d['leaf_capacity']}, mean {d['mean_leaf_points']:.2f} points a leaf)")
    print(f"per level:  {', '.join(f'{n:,}' for n in d['nodes_per_level'])}")
    lo, hi = (np.array(b) for b in d["bounds"])
    print(f"bounds:     min {np.array2string(lo, precision=4)}  max {np.array2string(hi, precision=4)}")
    present = [name for name in ("colors", "normal_field", "clip_lines") if d[f"has_{name}"]]
    print(f"properties: positions, normals, u, v{', ' + ', '.join(present) if present else ''}")
    attributes = hierarchy.points.attributes or {}
    for line, values in zip(describe_attributes(hierarchy.points), attributes.values()):
        print(f"attribute:  {line}; nodes: {'majority vote' if is_majority_voted(values) else 'mean'}")
    print(f"memory:     {d['bytes'] / 2**20:.1f} MiB")


def surface_splats_of(args) -> SplatCloud:
    """The splats of ``args.input`` with no view known: a mesh's surface sampled with the model
    :data:`~surfsplat.cli.options.IMAGE_SIZE` pixels wide (or ``--samples``), raw points
    preprocessed (``--k``, ``--sharp-angle``, ``--shape``), splat files as they are."""
    options = opt.source_options(args)
    shape = getattr(args, "shape", "ellipse")
    if shape != "ellipse":
        cloud = load_cloud(args.input)
        return preprocess(cloud, k=options.k, shape=shape, sharp_angle=options.raw_sharp_angle,
                          outliers=options.outliers)
    model = View(args.input, source_options=options).model
    if model.is_tree:
        raise InputError(f"{args.input}: is a hierarchy already (surfsplat build writes them)")
    return model.surface(None, options, image_size=opt.IMAGE_SIZE).data


def cmd_build(args) -> None:
    """``surfsplat build``: the point-octree LOD hierarchy of a model, saved as one .npz file."""
    out = Path(args.output)
    if not is_hierarchy_file(out):
        raise InputError(f"{out}: a hierarchy is saved as .npz; name the output MODEL.npz")
    check_output(out, inputs_of(args))
    cloud = surface_splats_of(args)
    start = time.perf_counter()
    with progress.stage(f"building the point-octree of {len(cloud):,} splats"):
        hierarchy = build_hierarchy(cloud, args.leaf_capacity, source=args.input)
    seconds = time.perf_counter() - start
    save_hierarchy(hierarchy, out, compact=args.compact)
    progress.message(f"{len(hierarchy):,} nodes in {hierarchy.levels} levels, built in {seconds:.2f} s "
                     f"({len(cloud) / max(seconds, 1e-9):,.0f} points/s), {out.stat().st_size / len(cloud):.0f} "
                     f"bytes a splat{' (compact)' if args.compact else ''} -> {out}")


def cmd_phong(args) -> None:
    """``surfsplat phong``: Phong splats with linear normal fields (Botsch 2004) from dense samples."""
    out = Path(args.output)
    if (args.error is None) == (args.count is None):
        raise InputError("give exactly one of --error EPS (model units) and --count N")
    check_output(out, inputs_of(args))
    cloud = load_cloud(args.input, "samples")
    start = time.perf_counter()
    splats = phong_splats(cloud, args.error, count=args.count, sharp_angle=args.sharp_angle, relax=args.relax,
                          margin=args.margin, source=args.input)
    seconds = time.perf_counter() - start
    save_ply(splats, out)
    progress.message(f"{len(splats):,} Phong splats from {len(cloud):,} samples in {seconds:.1f} s "
                     f"({len(cloud) / max(seconds, 1e-9):,.0f} samples/s) -> {out}")


def cmd_preprocess(args) -> None:
    """``surfsplat preprocess``: splats of raw points (normals, ellipses) or of a mesh's surface, saved as a PLY."""
    out = Path(args.output)
    check_output(out, inputs_of(args))
    cloud = surface_splats_of(args)
    save_ply(cloud, out)
    progress.message(f"wrote {len(cloud):,} splats -> {out}")


def cmd_sample(args) -> None:
    """``surfsplat sample``: points uniformly by area on a triangle mesh."""
    out = Path(args.output)
    check_output(out, inputs_of(args))
    mesh = load_mesh(args.mesh)
    with progress.stage(f"sampling {args.n:,} points", count=args.n):
        cloud = sample_mesh(mesh, args.n, seed=args.seed, sharp_angle=args.sharp_angle,
                            smooth_normals=args.smooth_normals)
    save_ply(cloud, out)
    progress.message(f"wrote {len(cloud):,} samples -> {out}")


def cmd_export(args) -> None:
    """``surfsplat export``: a static web viewer of a model (:func:`surfsplat.web.export`)."""
    copc = args.format == "copc" or (args.format is None and str(args.output).lower().endswith(".copc.laz"))
    check_output(args.output, inputs_of(args),
                 directory=not copc and not str(args.output).lower().endswith((".html", ".htm")))
    result = export(args.input, args.output, technique=args.technique, background=tuple(args.background),
                    source_options=opt.source_options(args), lod=opt.lod_options(args),
                    point_budget=args.point_budget, browser_lod=args.browser_lod, force=args.force,
                    format="copc" if copc else "web", size=tuple(args.size), supersample=args.supersample,
                    position_bits=args.position_bits,
                    memory_budget=None if args.memory_budget is None else int(args.memory_budget * 2**20))
    if copc:
        progress.message(f"exported {result.splats:,} splats to COPC ({result.bytes / 1e6:.1f} MB, "
                         f"{result.bytes / max(result.splats, 1):.1f} bytes each) in {result.seconds:.2f} s -> "
                         f"{result.path}")
        return
    progress.message(f"exported {result.splats:,} splats ({result.bytes / 1e6:.1f} MB of splats, "
                     f"{result.bytes / max(result.splats, 1):.0f} bytes each) in {result.seconds:.2f} s -> "
                     f"{result.path}{'' if result.path.suffix else '/index.html'}")
