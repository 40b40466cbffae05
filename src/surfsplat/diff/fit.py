"""Fitting splats to images with known cameras: gradient descent through the differentiable renderer.

Views: a camera file that surfsplat reads (:func:`surfsplat.io.camera_formats.load_cameras`: COLMAP text
model, NeRF ``transforms.json``, OpenCV JSON, surfsplat's camera list) and one image per camera, found by
the camera's name (the image file's stem) under the camera file's folder (COLMAP: also ``../images``).
Images are taken as seen: the splats' colours are learned unlit (``Lights(enabled=False)``), and an RGBA
image's alpha is the mask the splats' coverage is fitted to (composited over a random background each
step, so colour cannot stand in for coverage).

The initial splats: a cloud given (``init``: a file, an array or a SplatCloud, made into splats by the
view plan: normals and radii from its neighbours) or a COLMAP model's ``points3D.txt``. Parameters:
positions, normals and log radii (circular splats), colour and opacity logits; Adam with the steps of
the geometry (positions, normals, radii) decaying tenfold over the run. Coarse to fine: the first
``coarse_fraction`` of the steps see the views at half the resolution (half the focal length, 2 x 2
means of the premultiplied colours and of alpha), four times fewer pixels while the splats move most.
The loss: the L1 distance of the colours, plus ``alpha_weight`` times that of the coverage where the
images have alpha, plus ``plane_weight`` times the plane term: the mean squared sine of the angle
between each splat's plane and the directions to its ``neighbours`` nearest splats (found again every
``densify_every`` steps), which ties the normals to the surface the centres describe and pulls centres
that stray off their neighbours' planes back (a local plane fit's residual, as in point-cloud normal
estimation; the photographs alone barely constrain an unlit splat's normal); neighbours whose normals
differ by more than ``crease_angle`` weigh little in it, so that at a sharp edge each face keeps its own
plane. After every step each radius is clamped to ``max_radius`` times the mean distance to the splat's
``neighbours`` nearest splats, so that no splat reaches across a silhouette or grows into a spike at a thin
part's rim. Over the last ``sharpen_fraction`` of the steps the renderer's soft rims and depth tests narrow to
those of ``sharpen_to`` (the renderer's defaults: the image the fitted splats are looked at with). Every
``densify_every`` steps until ``densify_until`` of the run, splats whose mean position gradient is in the
top ``densify_fraction`` are split in two (each with 0.7 of the radius, half a radius apart along a random
tangent direction) and splats of opacity below ``prune_opacity`` are dropped.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch
from PIL import Image
from scipy.spatial import cKDTree

from .. import progress
from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..io.camera_formats import COLMAP_FILES, COLMAP_POINTS, load_cameras, load_colmap_points
from ..lighting import Lights
from ..pipeline import View
from .render import DiffOptions, render_frame
from .scene import DiffCamera, Splats, tangent_axes

#: Image file suffixes searched for a camera's picture.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp")

UNLIT = Lights(enabled=False)
#: Adam's epsilon (the losses are means over pixels: gradients of 1e-6 and less are common).
ADAM_EPS = 1e-15


@dataclass(frozen=True)
class FitOptions:
    """Options of :func:`fit`.

    Attributes:
        iterations: optimizer steps (one view each, cycling through the views in a shuffled order).
        position_lr: Adam step of the positions as a fraction of the initial cloud's bounding-box diagonal
            (the steps of positions, normals and radii decay to a tenth over the run).
        normal_lr, radius_lr, color_lr, opacity_lr: Adam steps of the unnormalized normals, log radii,
            colour and opacity logits.
        alpha_weight: weight of the L1 loss on the coverage where the images have alpha.
        densify_every, densify_until, densify_fraction: split the splats with the largest mean position
            gradient every this many steps, until this fraction of the run, this fraction of them.
        prune_opacity: drop splats of lower opacity at each densification step.
        max_splats: never grow beyond this many splats.
        plane_weight: weight of the plane term (0: none); neighbours: how many nearest splats it uses.
        crease_angle: degrees; a neighbour whose normal differs from the splat's by more weighs little in the
            plane term (``exp(-(1 - |n_i . n_j|) / (1 - cos crease_angle))``; 0: all weigh alike).
        max_radius: after every step, each splat's radius is clamped to this many times the mean distance to
            its ``neighbours`` nearest splats (0: no limit).
        coarse_fraction: the fraction of the steps (the first ones) on the views at half the resolution
            (views of odd width or height: none).
        render: the renderer's options (soft rims and depth tests carry the gradients of the silhouettes;
            the papers' rims, without edge coverage, until the sharpening).
        sharpen_fraction, sharpen_to: over this fraction of the steps (the last), the renderer's
            ``edge_softness`` and ``depth_softness`` go geometrically from ``render``'s to ``sharpen_to``'s,
            drawn with ``sharpen_to``'s rim rule (edge coverage: the renderer's defaults, as ``surfsplat
            render`` draws the result). Measured on the bunny and the CAD part: held-out views 29.2 and 25.1 dB
            against 28.9-29.2 and 24.4-24.5 with edge coverage throughout (twice the time) and 27.5 and
            24.8-24.9 with the papers' rims throughout (``benchmarks/diff_fit.py --training-rims``).
        seed: random seed (view order, background colours, split directions).
    """

    iterations: int = 1000
    position_lr: float = 2e-4
    normal_lr: float = 0.005
    radius_lr: float = 0.02
    color_lr: float = 0.05
    opacity_lr: float = 0.05
    alpha_weight: float = 1.0
    densify_every: int = 100
    densify_until: float = 0.6
    densify_fraction: float = 0.05
    prune_opacity: float = 0.05
    max_splats: int = 500_000
    plane_weight: float = 0.2
    neighbours: int = 8
    crease_angle: float = 20.0
    max_radius: float = 0.7
    coarse_fraction: float = 0.5
    render: DiffOptions = field(default_factory=lambda: DiffOptions(edge_softness=0.5, depth_softness=0.3,
                                                                    edge_coverage=False))
    sharpen_fraction: float = 0.3
    sharpen_to: DiffOptions = field(default_factory=DiffOptions)
    seed: int = 0

    def __post_init__(self) -> None:
        if int(self.iterations) < 1:
            raise InputError(f"iterations must be >= 1, got {self.iterations!r}", argument="iterations")
        for name in ("position_lr", "normal_lr", "radius_lr", "color_lr", "opacity_lr", "alpha_weight",
                     "densify_until", "densify_fraction", "prune_opacity", "plane_weight", "coarse_fraction",
                     "sharpen_fraction", "crease_angle", "max_radius"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise InputError(f"{name} must be a finite number >= 0, got {value!r}", argument=name)
        if int(self.densify_every) < 1 or int(self.max_splats) < 1 or int(self.neighbours) < 1:
            raise InputError("densify_every, max_splats and neighbours must be >= 1")
        if self.crease_angle > 90:
            raise InputError(f"crease_angle must be <= 90 degrees, got {self.crease_angle!r}",
                             argument="crease_angle")
        if self.sharpen_fraction > 1:
            raise InputError(f"sharpen_fraction must be <= 1, got {self.sharpen_fraction!r}",
                             argument="sharpen_fraction")
        if self.coarse_fraction > 1:
            raise InputError(f"coarse_fraction must be <= 1, got {self.coarse_fraction!r}", argument="coarse_fraction")


@dataclass
class FitView:
    """One training image: its camera, (H, W, 3) colours in [0, 1] and (H, W) alpha or None (opaque)."""

    camera: Camera
    image: np.ndarray
    alpha: np.ndarray | None = None
    name: str = ""


@dataclass
class FitResult:
    """What :func:`fit` returns: the fitted splats, the loss of every step and the time taken (seconds)."""

    cloud: SplatCloud
    losses: list[float]
    seconds: float

    def save_loss_curve(self, path: str | Path) -> Path:
        """Write the loss curve as JSON (``{"loss": [...]}``, one value per step) and return the path."""
        path = Path(path)
        path.write_text(json.dumps({"loss": self.losses, "seconds": self.seconds}))
        return path


def read_image(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(H, W, 3) float colours in [0, 1] and the (H, W) alpha (None without an alpha channel) of an image file."""
    try:
        with Image.open(path) as picture:
            has_alpha = picture.mode in ("RGBA", "LA") or "transparency" in picture.info
            data = np.asarray(picture.convert("RGBA" if has_alpha else "RGB"), dtype=np.float64) / 255.0
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the image: {exc}", file=path) from None
    return (data[..., :3], data[..., 3]) if has_alpha else (data, None)


def _image_index(folders: list[Path]) -> dict[str, Path]:
    """Image files under ``folders`` (recursively) by their stem; the first folder wins."""
    found: dict[str, Path] = {}
    for folder in folders:
        if folder.is_dir():
            for path in sorted(folder.rglob("*")):
                if path.suffix.lower() in IMAGE_SUFFIXES:
                    found.setdefault(path.stem, path)
    return found


def load_views(cameras: str | Path, images: str | Path | None = None) -> list[FitView]:
    """The cameras of a camera file (see :func:`~surfsplat.io.camera_formats.load_cameras`) with their images.

    Each camera's image is the file whose stem is the camera's name, searched under ``images`` (if given),
    else the camera file's folder and, for a COLMAP model, its ``images`` sibling folder. The image must
    have the camera's size. InputError naming the camera and where it was looked for when one is missing.
    """
    cameras = Path(cameras)
    named = load_cameras(cameras)
    base = cameras if cameras.is_dir() else cameras.parent
    folders = [Path(images)] if images is not None else [base, base.parent / "images", base / "images"]
    index = _image_index(folders)
    views = []
    for name, camera in named:
        path = index.get(name)
        if path is None:
            raise InputError(f"{cameras}: no image named {name!r} ({'/'.join(IMAGE_SUFFIXES)}) under "
                             f"{', '.join(str(f) for f in folders)}", file=cameras)
        image, alpha = read_image(path)
        if image.shape[:2] != (camera.height, camera.width):
            raise InputError(f"{path}: the image is {image.shape[1]}x{image.shape[0]} pixels, its camera "
                             f"{name!r} {camera.width}x{camera.height}", file=path)
        views.append(FitView(camera, image, alpha, name))
    return views


def initial_cloud(init: Any, cameras: str | Path | None = None) -> SplatCloud:
    """The splats a fit starts from: ``init`` (a SplatCloud, an (N, 3) array or a point/splat file) or,
    without it, the ``points3D.txt`` of the COLMAP model at ``cameras``; made into splats (normals, radii)
    by the view plan."""
    if init is None:
        folder = None if cameras is None else (Path(cameras) if Path(cameras).is_dir() else Path(cameras).parent)
        if folder is None or not (folder / COLMAP_POINTS).is_file():
            raise InputError(f"no initial cloud: give one (--init CLOUD) or a COLMAP model with {COLMAP_POINTS} "
                             f"beside {' and '.join(COLMAP_FILES)}")
        init = load_colmap_points(folder)
    cloud = View(init).sample().points()
    if cloud.u is None or cloud.v is None or cloud.normals is None:
        raise InputError("the initial cloud has no splats (normals and radii could not be estimated)")
    return cloud


def _logit(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 1e-3, 1.0 - 1e-3)
    return np.log(x / (1.0 - x))


class _Params:
    """The optimized tensors (positions, raw normals, log radii, colour and opacity logits) and their Adam."""

    def __init__(self, tensors: dict[str, torch.Tensor], options: FitOptions, scale: float) -> None:
        self.options, self.scale = options, scale
        self.t = {k: v.detach().clone().requires_grad_(True) for k, v in tensors.items()}
        self.grad_sum = torch.zeros(len(self.t["positions"]), dtype=self.t["positions"].dtype)
        self.grad_count = torch.zeros_like(self.grad_sum)
        o = options
        lrs = {"positions": o.position_lr * scale, "normals": o.normal_lr, "log_radii": o.radius_lr,
               "colors": o.color_lr, "opacity": o.opacity_lr}
        self.geometry = {k: lrs[k] for k in ("positions", "normals", "log_radii")}
        self.optimizer = torch.optim.Adam([{"params": [self.t[k]], "lr": lr, "name": k} for k, lr in lrs.items()],
                                          eps=ADAM_EPS)
        self.find_neighbours()

    def find_neighbours(self) -> None:
        """The ``options.neighbours`` nearest other splats of every splat (the plane term's pairs) and the radius
        limits (``max_radius`` times their mean distance)."""
        p = self.t["positions"].detach().cpu().numpy()
        k = min(int(self.options.neighbours), len(p) - 1)
        self.pairs = self.max_log_radius = None
        if k < 1:
            return
        distance, index = cKDTree(p).query(p, k + 1)
        if self.options.max_radius > 0:
            spacing = np.maximum(distance[:, 1:].mean(axis=1), 1e-12)
            self.max_log_radius = torch.as_tensor(np.log(self.options.max_radius * spacing),
                                                  dtype=self.t["log_radii"].dtype,
                                                  device=self.t["log_radii"].device)
        if self.options.plane_weight > 0:
            self.pairs = torch.as_tensor(index[:, 1:], device=self.t["positions"].device)

    def limit_radii(self) -> None:
        """Clamp the radii to ``options.max_radius`` times the mean distance to the ``neighbours`` nearest
        splats (as of the last neighbour search): a splat cannot grow across a silhouette or into a spike."""
        if self.max_log_radius is not None:
            with torch.no_grad():
                r = self.t["log_radii"]
                r.copy_(torch.minimum(r, self.max_log_radius))

    def plane_loss(self) -> torch.Tensor | None:
        """Mean squared sine of the angle between each splat's plane and the directions to its neighbours."""
        if self.pairs is None:
            return None
        p, n = self.t["positions"], self.t["normals"]
        n = n / torch.linalg.vector_norm(n, dim=1, keepdim=True)
        d = p[self.pairs] - p[:, None, :]
        along = (d * n[:, None, :]).sum(-1)
        sine2 = along ** 2 / ((d * d).sum(-1) + 1e-20)
        if self.options.crease_angle <= 0:
            return sine2.mean()
        # neighbours across a crease (normals apart by the crease angle or more) weigh little: the term
        # then fits each side's plane apart instead of bending the normals at the edge into their mean
        with torch.no_grad():
            c = (n[self.pairs] * n[:, None, :]).sum(-1).abs()
            w = torch.exp(-(1.0 - c) / (1.0 - math.cos(math.radians(self.options.crease_angle))))
            w = w / w.sum(1, keepdim=True).clamp(min=1e-12)
        return (w * sine2).sum(1).mean()

    def splats(self) -> Splats:
        t = self.t
        u, v = tangent_axes(t["normals"], torch.exp(t["log_radii"]))
        return Splats(t["positions"], u, v, torch.sigmoid(t["colors"]), torch.sigmoid(t["opacity"]), t["normals"])

    def set_decay(self, factor: float) -> None:
        """Scale the steps of the geometry (positions, normals, radii) by ``factor`` of their initial size."""
        for group in self.optimizer.param_groups:
            if group["name"] in self.geometry:
                group["lr"] = self.geometry[group["name"]] * factor


def _densify(params: _Params, options: FitOptions, rng: np.random.Generator) -> _Params:
    """Split the splats of the largest mean position gradient and drop the transparent ones."""
    t = {k: v.detach() for k, v in params.t.items()}
    n = len(t["positions"])
    mean_grad = params.grad_sum / params.grad_count.clamp(min=1)
    keep = torch.sigmoid(t["opacity"]) >= options.prune_opacity
    room = max(0, options.max_splats - int(keep.sum()))
    count = min(int(options.densify_fraction * n), room)
    split = torch.zeros(n, dtype=torch.bool)
    if count > 0:
        candidates = torch.where(keep & (params.grad_count > 0), mean_grad, torch.full_like(mean_grad, -1.0))
        order = torch.argsort(candidates, descending=True)[:count]
        split[order[candidates[order] > 0]] = True
    radii = torch.exp(t["log_radii"])
    u, v = tangent_axes(t["normals"], radii)
    angle = torch.as_tensor(rng.uniform(0, 2 * np.pi, n), dtype=radii.dtype)
    offset = 0.5 * (torch.cos(angle)[:, None] * u + torch.sin(angle)[:, None] * v)
    shrink = torch.where(split, torch.log(torch.tensor(0.7, dtype=radii.dtype)), torch.zeros_like(radii))
    tensors = {k: v[keep] for k, v in t.items()}
    tensors["positions"] = (t["positions"] + torch.where(split[:, None], offset, 0.0))[keep]
    tensors["log_radii"] = (t["log_radii"] + shrink)[keep]
    new = {k: v[split] for k, v in t.items()}
    new["positions"] = (t["positions"] - offset)[split]
    new["log_radii"] = (t["log_radii"] + shrink)[split]
    merged = {k: torch.cat([tensors[k], new[k]]) for k in tensors}
    return _Params(merged, options, params.scale)


def _target(view: FitView, dtype: torch.dtype, device) -> tuple[DiffCamera, torch.Tensor, torch.Tensor | None]:
    """A view's camera, premultiplied colours (H, W, 3) and alpha (H, W) or None as tensors."""
    image = np.asarray(view.image, np.float64)
    alpha = None if view.alpha is None else np.asarray(view.alpha, np.float64)
    premultiplied = image if alpha is None else image * alpha[..., None]
    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(a, dtype=dtype, device=device)

    camera = DiffCamera.from_camera(view.camera, dtype, device)
    return camera, tensor(premultiplied), None if alpha is None else tensor(alpha)


def _halved(target: tuple[DiffCamera, torch.Tensor, torch.Tensor | None]
            ) -> tuple[DiffCamera, torch.Tensor, torch.Tensor | None]:
    """The view at half the resolution: half the focal length, 2 x 2 pixel means (of premultiplied colour)."""
    camera, premultiplied, alpha = target

    def pool(x: torch.Tensor) -> torch.Tensor:
        h, w = x.shape[:2]
        return x.reshape(h // 2, 2, w // 2, 2, *x.shape[2:]).mean(dim=(1, 3))

    small = replace(camera, focal=camera.focal / 2, width=camera.width // 2, height=camera.height // 2)
    return small, pool(premultiplied), None if alpha is None else pool(alpha)


def _render_options(options: FitOptions, step: int) -> DiffOptions:
    """The renderer's options at ``step``: ``options.render``, then over the last ``sharpen_fraction`` of the
    steps its rim and depth-test widths going geometrically to those of ``sharpen_to``, with its rim rule
    (``edge_coverage``)."""
    iterations = int(options.iterations)
    steps = int(round(options.sharpen_fraction * iterations))
    first = iterations - steps
    if steps == 0 or step < first:
        return options.render
    t = (step - first + 1) / steps
    a, b = options.render, options.sharpen_to

    def blend(x: float, y: float) -> float:
        return x ** (1.0 - t) * y ** t if x > 0 and y > 0 else (1.0 - t) * x + t * y

    return replace(a, edge_softness=blend(a.edge_softness, b.edge_softness),
                   depth_softness=blend(a.depth_softness, b.depth_softness), edge_coverage=b.edge_coverage)


def fit(views: list[FitView], init: SplatCloud, *, options: FitOptions | None = None,
        device: str | torch.device | None = None, on_step: Callable[[int, float, int], None] | None = None
        ) -> FitResult:
    """Fit splats, starting from ``init``, to the images of ``views`` (see the module docstring).

    ``views``: :class:`FitView` (camera, image, optional alpha); ``init``: preprocessed splats
    (:func:`initial_cloud`). ``device``: where PyTorch runs ("cpu", "cuda", "mps"; None: the CPU).
    ``on_step(step, loss, splats)``: called after every step (a log, a plot).
    Returns the fitted splats (colours unlit, the ``opacity`` attribute), the loss curve and the time.
    """
    options = options or FitOptions()
    if not views:
        raise InputError("no views to fit")
    if init.u is None or init.v is None or init.normals is None:
        raise InputError("the initial splats need normals and tangent axes (preprocess them)")
    start = time.perf_counter()
    rng = np.random.default_rng(options.seed)
    dtype = torch.float32
    world = np.asarray(init.positions, np.float64) + np.asarray(init.origin, np.float64)
    scale = float(np.linalg.norm(np.ptp(world, axis=0))) or 1.0
    radii = np.sqrt(np.linalg.norm(init.u, axis=1) * np.linalg.norm(init.v, axis=1))
    colors = init.colors if init.colors is not None else np.full((len(init), 3), 0.5)
    initial = {"positions": world, "normals": np.asarray(init.normals, np.float64),
               "log_radii": np.log(np.maximum(radii, 1e-12)), "colors": _logit(np.asarray(colors, np.float64)),
               "opacity": np.full(len(init), _logit(np.array(0.9)))}
    params = _Params({k: torch.as_tensor(np.asarray(v), dtype=dtype, device=device) for k, v in initial.items()},
                     options, scale)
    fine = [_target(v, dtype, device) for v in views]
    coarse = [_halved(t) for t in fine] if all(t[0].width % 2 == 0 and t[0].height % 2 == 0 for t in fine) else fine
    losses: list[float] = []
    order: list[int] = []
    iterations = int(options.iterations)
    coarse_steps = int(round(options.coarse_fraction * iterations)) if coarse is not fine else 0
    with progress.stage("fitting", total=iterations, unit="steps") as bar:
        for step in range(iterations):
            if not order:
                order = list(rng.permutation(len(fine)))
            camera, premultiplied, alpha = (coarse if step < coarse_steps else fine)[order.pop()]
            background = rng.uniform(0.0, 1.0, 3) if alpha is not None else np.ones(3)
            frame = render_frame(params.splats(), camera, lights=UNLIT, background=tuple(background),
                                 options=_render_options(options, step))
            if alpha is None:
                target = premultiplied
            else:
                bg = torch.as_tensor(background, dtype=dtype, device=premultiplied.device)
                target = premultiplied + (1.0 - alpha[..., None]) * bg
            loss = torch.abs(frame.color - target).mean()
            if alpha is not None:
                loss = loss + options.alpha_weight * torch.abs(frame.alpha - alpha).mean()
            plane = params.plane_loss()
            total = loss if plane is None else loss + options.plane_weight * plane
            params.optimizer.zero_grad(set_to_none=True)
            total.backward()
            grad = params.t["positions"].grad
            if grad is not None:
                g = torch.linalg.vector_norm(grad.detach(), dim=1).cpu()
                params.grad_sum += g
                params.grad_count += (g > 0).to(g.dtype)
            params.set_decay(0.1 ** (step / max(iterations - 1, 1)))
            params.optimizer.step()
            params.limit_radii()
            losses.append(float(loss.detach()))
            bar.update()
            if on_step is not None:
                on_step(step, losses[-1], len(params.t["positions"]))
            if (step + 1) % int(options.densify_every) == 0 and step + 1 < iterations:
                if step + 1 < options.densify_until * iterations:
                    params = _densify(params, options, rng)
                else:
                    params.find_neighbours()
    with torch.no_grad():
        cloud = params.splats().to_cloud()
    return FitResult(cloud, losses, time.perf_counter() - start)


def fit_files(cameras: str | Path, *, init: Any = None, images: str | Path | None = None,
              options: FitOptions | None = None, device: str | None = None) -> FitResult:
    """:func:`fit` to the images of a camera file (:func:`load_views`) from ``init`` or the COLMAP points."""
    views = load_views(cameras, images)
    return fit(views, initial_cloud(init, cameras), options=options, device=device)
