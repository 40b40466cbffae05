"""Phong splat generation (Botsch, Spernat & Kobbelt 2004, section 3).

From dense samples with normals to far fewer elliptical splats with linear
normal fields that cover every sample within an error tolerance ``eps``: a
sample ``p_i`` is covered by splat ``S_j`` when it lies in the elliptical
cylinder of the splat offset by ``+-eps`` along its plane normal (Botsch 2004,
sec. 3, after eq. 1), i.e. its projection into the plane is inside the
ellipse and its distance from the plane is at most ``eps``.

Stages (each reported through :func:`surfsplat.progress.stage`), in the
spirit of Wu & Kobbelt 2004 ([WK04], the generator Botsch 2004 uses):

1. samples (:mod:`.samples`): validation, spatial (Morton) order, a k-d tree; PCA normals
   oriented by the MST (Hoppe 1992) when the cloud has none; with
   ``sharp_angle``, the half-spaces of the faces across sharp edges (from the
   samples' own clip lines, or :func:`~surfsplat.geometry.sharp.detect_sharp_features`).
2. candidates (:mod:`.candidates`): a splat per seed sample, grown over its nearest neighbours in
   rings of increasing size (x 1.25 each) while the least-squares plane of the
   grown set keeps every member within ``eps`` (the splat's covered set
   ``P_j``). The neighbours are ranked by an anisotropic distance that follows
   the local principal curvatures ([WK04]: ellipses aligned to the principal
   directions): from the covariance of the neighbours' normals, so that
   candidates stretch along the flat direction, up to ``MAX_ANISOTROPY``.
   Seeds: a random subset of about ``SEED_FACTOR`` candidates per splat (a
   pilot of ``PILOT_SEEDS`` seeds measures the typical splat size and the
   neighbourhood sizes needed: candidates that outgrow the one enough for
   half of them grow again over a larger one), then every sample no
   candidate covered.
3. greedy cover (:mod:`.cover`): candidates that cover the most not-yet-covered samples
   are picked, vectorized in rounds: each round takes every candidate whose
   gain (with a random tie-break) is the largest among all candidates sharing
   an uncovered sample with it, exactly like the sequential greedy locally.
4. fit (:mod:`.fit`, :mod:`.normal_field`; vectorized over splats): least-squares plane (centroid and smallest
   eigenvector of the covariance of ``P_j``), tangent axes along the principal
   directions (Botsch 2004, sec. 3: eigenvectors of the two smaller
   eigenvalues of ``sum n_i n_i^T``, projected into the plane; the point
   covariance's axes where that is isotropic, e.g. on a plane), the
   smallest enclosing ellipse with these axes (a 1-D convex minimisation
   over the axis ratio, bounded by ``MAX_ANISOTROPY``), grown by a surface
   margin (``SURFACE_MARGIN``: the enclosing ellipses cover the samples but
   not the surface between them), the splat's orientation from the sum of
   its samples' normals, and the linear normal field of eq. 3-4.
5. relaxation (:mod:`.relax`; ``relax`` iterations, after [WK04]'s global relaxation):
   redundant splats (all their samples covered by others) are dropped, every
   sample goes to the covering splat it is most central in (smallest
   ``s^2 + t^2``), and each splat is re-fitted to its samples (re-centred;
   its old plane is kept where the new one breaks the tolerance or fits no
   surface). Every step keeps every sample covered.
6. with ``sharp_angle`` (:mod:`.clip`, :mod:`.sharp_edges`): clip lines where a splat reaches over a sharp edge
   (Botsch 2004, sec. 4, ``(a, b, c)`` in ``(s, t)``) from the half-spaces of
   the edge samples on the splat's side; splats that still claim samples of
   another face (a hole in the face, a third edge) are replaced by splats
   grown to at most two, then no, other faces (``REPAIR_FACES``); last, the
   surface margin of any splat that still does is reduced.

:mod:`.pipeline` runs stages 2-6 for one tolerance; :mod:`.count` searches
the tolerance for a splat count (``count=``); :mod:`.splatting` is the entry
(:func:`phong_splats`, :func:`phong_fit`) and :mod:`.coverage` checks a
cover (:func:`phong_coverage`). :mod:`.csr` holds the member lists (CSR) and
per-splat sums shared by the stages.

Normal field convention (:mod:`surfsplat.cloud`): ``n(s, t) = normals + s
alpha u_hat + t beta v_hat`` with ``(s, t)`` the splat's normalized
coordinates. ``u x v`` is the splat's plane normal, ``normals`` the fitted
center normal (which generally differs from it, Botsch 2004 sec. 3).
"""

from .coverage import phong_coverage
from .normal_field import solve_least_norm
from .samples import SURFACE_MARGIN
from .splatting import MAX_COUNT_NEIGHBOURS, MAX_NEIGHBOURS, PhongResult, phong_fit, phong_splats

#: Former name (tests and scripts import it from here).
_solve_least_norm = solve_least_norm

__all__ = ["phong_splats", "phong_fit", "phong_coverage", "PhongResult", "MAX_NEIGHBOURS", "MAX_COUNT_NEIGHBOURS",
           "SURFACE_MARGIN"]
