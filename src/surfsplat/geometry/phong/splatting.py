"""Phong splats from dense samples: the public entry (Botsch, Spernat & Kobbelt 2004, sec. 3).

:func:`phong_splats` / :func:`phong_fit` check the arguments, prepare the
samples (:mod:`.samples`), run the stages for the tolerance
(:mod:`.pipeline`) or search the tolerance for a splat count (:mod:`.count`),
and return float32 splats.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from ... import progress as report
from ...cloud import SplatCloud
from ...errors import InputError
from ..sharp import check_sharp_angle
from .count import search_count
from .fit import Splats
from .pipeline import generate
from .samples import SURFACE_MARGIN, Samples, prepare_samples

#: Default cap of the neighbourhood a candidate splat grows over (the most
#: samples one splat can cover). The neighbourhood actually queried is sized
#: by the pilot, usually far smaller.
MAX_NEIGHBOURS = 1024

#: Count mode: the largest default neighbourhood (few splats for many samples).
MAX_COUNT_NEIGHBOURS = 4096


@dataclass
class PhongResult:
    """Phong splats and how they were made (:func:`phong_fit`).

    Attributes:
        splats: the :class:`SplatCloud` of Phong splats (see :func:`phong_splats`).
        error: the tolerance used, model units (found by the search in count mode).
        samples: number of (valid) input samples.
        member_ptr, member_idx: CSR of the samples each splat was fitted to
            (its covered set ``P_j``): splat ``j`` covers the samples
            ``member_idx[member_ptr[j]:member_ptr[j + 1]]``, row indices of
            the validated input (``cloud.validated()``; the input's own rows
            when none was dropped). Every sample appears at least once.
    """

    splats: SplatCloud
    error: float
    samples: int
    member_ptr: np.ndarray
    member_idx: np.ndarray


def phong_splats(cloud: SplatCloud, error: float | None = None, *, count: int | None = None,
                 k: int | None = None, sharp_angle: float | None = None, relax: int = 2,
                 margin: float = SURFACE_MARGIN, progress: bool | None = None,
                 source: str = "input") -> SplatCloud:
    """Phong splats (Botsch, Spernat & Kobbelt 2004, sec. 3) that cover every sample within ``error``.

    Args:
        cloud: dense samples: a :class:`SplatCloud` (or an (N, 3) array of
            positions), with normals (oriented consistently) or without
            (then estimated by PCA over 8 neighbours and oriented by the MST,
            as :func:`~surfsplat.geometry.preprocess.preprocess` does). Colors
            are averaged per splat. Invalid rows are dropped with a warning.
        error: the tolerance ``eps`` in model units, > 0: every sample lies in
            some splat's ellipse (projected into its plane) within ``eps`` of
            its plane (the elliptical cylinder offset by ``+-eps``).
        count: instead of ``error``: the number of splats wanted, 1 to N.
            The tolerance is searched (secant/bisection on ``log eps`` over the
            whole pipeline) until the count is within ``COUNT_TOLERANCE`` (3 %);
            if no tolerance gets within 5 % (e.g. flat regions whose splats are
            capped by ``k``), the closest result is returned with a warning.
        k: the most neighbours (samples) a candidate splat grows over, >= 1:
            caps the samples per splat, and time and memory. Default (None):
            ``MAX_NEIGHBOURS`` (1024); in count mode up to
            ``MAX_COUNT_NEIGHBOURS`` (4096) where few splats need more.
        sharp_angle: None, or a dihedral angle in degrees in (0, 180): splats
            do not grow across edges sharper than this (a sample joins a splat
            only if its normal is within the angle of the seed's), and splats
            reaching over such an edge get clip lines ``(a, b, c)`` (Botsch
            2004, sec. 4). The edges come from the samples' own clip lines
            when the cloud has them (e.g. ``sample_mesh(..., sharp_angle=)``),
            else from :func:`~surfsplat.geometry.sharp.detect_sharp_features`.
            Splats that two lines cannot keep off other faces (a hole in the
            face, a third edge) are replaced by smaller ones, and their
            surface margin is reduced.
        relax: relaxation iterations (>= 0, default 2): redundant splats
            dropped, samples re-assigned to the covering splat they are most
            central in, splats re-fitted to them (coverage kept).
        margin: factor (>= 0, default 0.75) on the mean distance of a splat's
            samples to their 8th nearest sample, added to both semi-axes so
            that the surface between the samples is covered too, not only the
            samples (see ``SURFACE_MARGIN``); 0 gives the paper's bare smallest
            enclosing ellipses.
        progress: None (default) reports stages on stderr when
            :func:`surfsplat.progress.enable` is on; True or False forces it
            on or off for this call.
        source: name of the input in messages and warnings.

    Returns:
        A :class:`SplatCloud` (float32) with one row per splat: ``positions``
        the ellipse centers (the covered samples' centroid, on their
        least-squares plane); ``u``, ``v`` the scaled semi-axes spanning that
        plane (``u x v`` along the plane normal; ``u`` along the direction of
        largest normal variation); ``normals`` the unit center normal of the
        fitted linear normal field and ``normal_field`` ``(alpha, beta)`` so
        that ``normals + s alpha u_hat + t beta v_hat`` is the fitted normal at
        ``(s, t)`` (Botsch 2004, eq. 2-4, up to scale); ``colors`` the mean of
        the covered samples' colors (None without input colors); with
        ``sharp_angle``, ``clip_lines`` (N, 2, 3).

    Raises:
        InputError: neither or both of ``error`` and ``count``, a tolerance
            that is not a positive finite number, a count outside 1..N,
            bad ``k``, ``relax``, ``margin`` or ``sharp_angle``, or no valid
            samples.
    """
    return phong_fit(cloud, error, count=count, k=k, sharp_angle=sharp_angle, relax=relax, margin=margin,
                     progress=progress, source=source).splats


def phong_fit(cloud: SplatCloud, error: float | None = None, *, count: int | None = None,
              k: int | None = None, sharp_angle: float | None = None, relax: int = 2,
              margin: float = SURFACE_MARGIN, progress: bool | None = None,
              source: str = "input") -> PhongResult:
    """:func:`phong_splats` with the tolerance used and the samples each splat covers.

    Same arguments as :func:`phong_splats`; returns a :class:`PhongResult`.
    """
    if not isinstance(cloud, SplatCloud):
        cloud = SplatCloud(positions=cloud)
    error, count, k, relax, sharp_angle, margin = _check_arguments(error, count, k, relax, sharp_angle, margin)
    with report.enabled(progress):
        samples = prepare_samples(cloud, sharp_angle, source)
        samples.margin = margin
        n = len(samples.pts)
        if count is not None and count > n:
            raise InputError(f"{source}: count must be at most the number of samples ({n:,}), got {count:,}")
        if count is None:
            splats = generate(samples, error, MAX_NEIGHBOURS if k is None else k, relax, np.random.default_rng(0))
        else:
            if k is None:
                # a cover overlaps ~2x, and anisotropic candidates use ~1/4 of their neighbourhood
                k = int(np.clip(8 * n // count, MAX_NEIGHBOURS, MAX_COUNT_NEIGHBOURS))
            error, splats = search_count(samples, count, k, relax, source)
        out = _to_cloud(samples, splats, cloud.origin)
        out.up = cloud.up
        report.message(f"  {len(out):,} Phong splats for {n:,} samples (error {error:.4g}, "
                       f"{n / len(out):.1f} samples per splat)")
    # members in the order of the validated input
    member_idx = samples.perm[splats.idx]
    return PhongResult(out, float(error), n, splats.ptr.copy(), member_idx)


def _check_arguments(error, count, k, relax, sharp_angle, margin):
    """The arguments of :func:`phong_splats`, checked and normalized; InputError naming the bad one."""
    if (error is None) == (count is None):
        raise InputError("phong_splats: give exactly one of error (the tolerance eps, model units) "
                         "and count (the number of splats wanted)")
    if error is not None:
        if isinstance(error, bool) or not isinstance(error, numbers.Real) or not math.isfinite(error) or error <= 0:
            raise InputError(f"phong_splats: error must be a positive finite distance in model units, got {error!r}")
        error = float(error)
    if count is not None:
        if isinstance(count, bool) or not isinstance(count, numbers.Integral) or count < 1:
            raise InputError(f"phong_splats: count must be a positive integer, got {count!r}")
        count = int(count)
    if k is not None and (isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 1):
        raise InputError(f"phong_splats: k must be a positive integer (neighbours per splat), got {k!r}")
    if isinstance(relax, bool) or not isinstance(relax, numbers.Integral) or relax < 0:
        raise InputError(f"phong_splats: relax must be a non-negative integer (iterations), got {relax!r}")
    if sharp_angle is not None:
        sharp_angle = check_sharp_angle(sharp_angle, "phong_splats: sharp_angle")
    if isinstance(margin, bool) or not isinstance(margin, numbers.Real) or not (0 <= margin < math.inf):
        raise InputError(f"phong_splats: margin must be a non-negative finite factor, got {margin!r}")
    return error, count, None if k is None else int(k), int(relax), sharp_angle, float(margin)


def _to_cloud(samples: Samples, splats: Splats, origin: np.ndarray) -> SplatCloud:
    """The float32 :class:`SplatCloud` of the fitted splats (axes scaled to model units), positions
    relative to ``origin`` (the input cloud's, (3,) float64)."""
    u = splats.u_hat * splats.a[:, None]
    v = splats.v_hat * splats.b[:, None]
    return SplatCloud(positions=splats.center.astype(np.float32), normals=splats.center_normal.astype(np.float32),
                      colors=None if splats.colors is None else splats.colors.astype(np.float32),
                      u=u.astype(np.float32), v=v.astype(np.float32), normal_field=splats.field.astype(np.float32),
                      clip_lines=splats.lines, origin=origin)
