"""Normal estimation (PCA of kNN neighbourhoods) and consistent orientation.

Orientation follows Hoppe, DeRose, Duchamp, McDonald & Stuetzle 1992,
"Surface reconstruction from unorganized points", section 3.3: the
Riemannian graph over the points (here: the symmetric k-nearest-neighbour
graph) with edge cost ``1 - |n_i . n_j|``, its minimum spanning tree, and
sign propagation from a seed along the tree: ``sign(child) = sign(parent) *
sign(n_child . n_parent)``. One tree per connected component, each seeded at
its highest point (largest z) whose normal is turned to +z.

Everything is vectorized. The default MST is a NumPy Boruvka that propagates
the signs while it merges components (``method="boruvka"``); the reference
path uses ``scipy.sparse.csgraph.minimum_spanning_tree`` + a breadth-first
order + pointer jumping (``method="scipy"``). Both compute the same unique
tree: edges are ranked by (weight, position in the row-major kNN array),
which is exactly SciPy's stable-sort Kruskal order.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree

from ..errors import InputError
from .common import (block_covariance, block_offsets, check_indices, check_oriented_points, check_vectors, columns,
                     for_blocks)

#: Added to every edge cost ``1 - |n_i . n_j|`` so that parallel normals
#: (cost 0) are not taken for "no edge" by scipy.sparse.
EDGE_EPSILON = 1e-6

#: A seed normal with ``|n_z|`` below this is "nearly horizontal" (within
#: ~5.7 degrees of the horizontal plane): it is then turned away from the
#: centroid of its component instead of towards +z.
HORIZONTAL_NZ = 0.1


# -- normal estimation ------------------------------------------------------


def neighbourhood_covariance(positions, indices) -> tuple[np.ndarray, ...]:
    """Covariance of each point's neighbourhood (the point itself included).

    Args:
        positions: (N, 3) float array, model units.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).

    Returns:
        Six (N,) float64 arrays ``(cxx, cxy, cxz, cyy, cyz, czz)``: the
        entries of the 3x3 covariance ``1/(k+1) sum (p - mean)(p - mean)^T``
        over the point and its k neighbours, model units squared. Computed in
        float32 from coordinates relative to the point (no loss from large
        coordinate offsets).
    """
    pts = check_vectors(positions, "positions")
    idx = check_indices(indices, len(pts))
    cols = columns(pts)
    out = [np.empty(len(pts)) for _ in range(6)]

    def block(sl):
        for o, c in zip(out, block_covariance(block_offsets(cols, idx, sl))):
            o[sl] = c

    for_blocks(block, len(pts))
    return tuple(out)


def neighbourhood_pca(positions, indices) -> tuple[np.ndarray, np.ndarray]:
    """PCA of each neighbourhood: unit normals and the covariance eigenvalues.

    Args:
        positions: (N, 3) float array, model units.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).

    Returns:
        ``(normals, eigenvalues)``: (N, 3) float32 unit normals as :func:`estimate_normals`
        (not oriented) and (N, 3) float64 eigenvalues of :func:`neighbourhood_covariance`,
        descending, model units squared (closed form of :func:`smallest_eigenvectors`).
    """
    pts = check_vectors(positions, "positions")
    idx = check_indices(indices, len(pts))
    cols = columns(pts)
    nrm = np.empty((len(pts), 3), dtype=np.float32)
    lam = np.empty((len(pts), 3), dtype=np.float64)

    def block(sl):
        nrm[sl], lam[sl] = smallest_eigenvectors(*block_covariance(block_offsets(cols, idx, sl)),
                                                 with_eigenvalues=True)

    for_blocks(block, len(pts))
    return nrm, lam


def smallest_eigenvectors(cxx, cxy, cxz, cyy, cyz, czz, *, with_eigenvalues: bool = False):
    """Unit eigenvector of the smallest eigenvalue of many symmetric 3x3 matrices.

    Closed form, vectorized (about 10x faster than ``np.linalg.eigh`` on
    (N, 3, 3)): eigenvalues by the trigonometric method (Smith 1961, "Eigenvalues
    of a symmetric 3x3 matrix", CACM 4(4)), then the eigenvector as the largest
    cross product of two rows of ``A - lambda_min I``. Where that matrix has
    rank < 2 (the two smallest eigenvalues coincide: collinear or coincident
    points, isotropic blobs) any unit vector orthogonal to its largest row is
    returned, and (0, 0, 1) where the whole matrix vanishes.

    Args:
        cxx ... czz: (N,) float arrays, the six distinct matrix entries.
        with_eigenvalues: also return the three eigenvalues.

    Returns:
        (N, 3) float32 unit vectors (sign arbitrary); with ``with_eigenvalues``,
        ``(vectors, eigenvalues)`` with (N, 3) float64 eigenvalues in descending
        order (the matrix entries' units; for a covariance, model units squared).
    """
    a00, a01, a02, a11, a12, a22 = (np.asarray(a, dtype=np.float64) for a in (cxx, cxy, cxz, cyy, cyz, czz))
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    p = np.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1) / 6.0)
    det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(p > 0, det / (2.0 * p * p * p), 0.0)
    phi = np.arccos(np.clip(r, -1.0, 1.0)) / 3.0
    lam_min = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    m00, m11, m22 = a00 - lam_min, a11 - lam_min, a22 - lam_min
    rows = ((m00, a01, a02), (a01, m11, a12), (a02, a12, m22))

    def cross(r, s):
        return (r[1] * s[2] - r[2] * s[1], r[2] * s[0] - r[0] * s[2], r[0] * s[1] - r[1] * s[0])

    crosses = [cross(rows[0], rows[1]), cross(rows[0], rows[2]), cross(rows[1], rows[2])]
    norms2 = np.stack([c[0] ** 2 + c[1] ** 2 + c[2] ** 2 for c in crosses])
    pick = np.argmax(norms2, axis=0)
    best2 = np.take_along_axis(norms2, pick[None], axis=0)[0]
    vec = np.stack([np.choose(pick, [c[j] for c in crosses]) for j in range(3)], axis=1)

    scale2 = m00 * m00 + m11 * m11 + m22 * m22 + 2.0 * p1  # |A - lam I|_F^2
    degenerate = ~(best2 > 1e-10 * scale2 * scale2)
    if degenerate.any():
        # rank <= 1: normal = anything orthogonal to the dominant row (the
        # direction of a line of points); zero matrix: +z.
        dsel = np.flatnonzero(degenerate)
        rn2 = np.stack([r[0][dsel] ** 2 + r[1][dsel] ** 2 + r[2][dsel] ** 2 for r in rows])
        top = np.argmax(rn2, axis=0)
        line = np.stack([np.choose(top, [r[j][dsel] for r in rows]) for j in range(3)], axis=1)
        lnorm = np.linalg.norm(line, axis=1)
        fallback = np.zeros((len(dsel), 3))
        fallback[:, 2] = 1.0
        has_line = lnorm > 0
        if has_line.any():
            line = line[has_line] / lnorm[has_line, None]
            # cross with the coordinate axis least aligned with the line
            axis = np.zeros_like(line)
            axis[np.arange(len(line)), np.argmin(np.abs(line), axis=1)] = 1.0
            fallback[has_line] = np.cross(line, axis)
        vec[dsel] = fallback
    vec /= np.linalg.norm(vec, axis=1, keepdims=True)
    if not with_eigenvalues:
        return vec.astype(np.float32)
    lam_max = q + 2.0 * p * np.cos(phi)  # Smith 1961: the other two roots of the same cubic
    lam = np.stack([lam_max, 3.0 * q - lam_max - lam_min, lam_min], axis=1)
    return vec.astype(np.float32), np.maximum(lam, 0.0)


def estimate_normals(positions, indices) -> np.ndarray:
    """Unit normals by PCA of each k-neighbourhood (the point itself included).

    The normal is the eigenvector of the smallest eigenvalue of the
    neighbourhood covariance (Hoppe et al. 1992, section 3.2; the least-squares
    tangent plane). Its sign is arbitrary: see :func:`orient_normals`.

    Args:
        positions: (N, 3) float array, model units.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).

    Returns:
        (N, 3) float32 unit normals. Degenerate neighbourhoods (collinear or
        coincident points) get some unit vector orthogonal to the line, or +z.
    """
    pts = check_vectors(positions, "positions")
    idx = check_indices(indices, len(pts))
    cols = columns(pts)
    out = np.empty((len(pts), 3), dtype=np.float32)

    def block(sl):
        out[sl] = smallest_eigenvectors(*block_covariance(block_offsets(cols, idx, sl)))

    for_blocks(block, len(pts))
    return out


# -- orientation --------------------------------------------------------------


def _edge_costs(normals: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 costs ``1 - |n_i . n_j| + eps`` and int8 signs of ``n_i . n_j`` per kNN edge."""
    dot = None
    for col in columns(normals):
        term = col[idx]
        term *= col[:, None]
        dot = term if dot is None else np.add(dot, term, out=dot)
    cost = np.abs(dot)
    np.subtract(np.float32(1.0 + EDGE_EPSILON), cost, out=cost)
    np.maximum(cost, np.float32(EDGE_EPSILON), out=cost)  # |dot| may exceed 1 by rounding
    sign = np.where(dot < 0, np.int8(-1), np.int8(1))
    return cost, sign


def _pointer_jump(parent: np.ndarray, value: np.ndarray, nodes: np.ndarray | None = None) -> None:
    """In place: make ``parent[i]`` the root of ``i`` and ``value[i]`` the sign product up to it.

    ``parent`` (N,) int: a forest, roots have ``parent[r] == r``.
    ``value`` (N,) int8: ``value[i]`` is the sign of ``i`` relative to ``parent[i]``
    (roots: left unchanged). After the call, ``value[i]`` is the sign of ``i``
    relative to its root (the product along the path, root excluded).
    Takes ceil(log2(depth)) vectorized steps. ``nodes``: restrict to these
    (a set closed under ``parent``).
    """
    todo = np.flatnonzero(parent != np.arange(len(parent))) if nodes is None else nodes
    todo = todo[parent[todo] != todo]
    while len(todo):
        up = parent[todo]
        upup = parent[up]
        jump = up != upup               # parent is not a root yet
        todo, up, upup = todo[jump], up[jump], upup[jump]
        if not len(todo):
            break
        newval = value[todo] * value[up]  # old values: segments [i, up) + [up, upup)
        value[todo] = newval
        parent[todo] = upup


#: Light-edge phase of the filtered Boruvka: about this many edges per point
#: (the cheapest ones) are processed first; the rest only where they join
#: different components afterwards.
LIGHT_EDGES_PER_POINT = 2.0


def _edge_keys(pts: np.ndarray, nrm: np.ndarray, idx: np.ndarray, dist: np.ndarray | None = None,
               irregular: np.ndarray | None = None):
    """Edges of the Riemannian graph as sortable uint64 keys, split into light and heavy ones.

    One blocked, threaded pass over the kNN entries ``(i, j = idx[i, s])``,
    edge id ``i*k + s``:

    * cost ``1 - |n_i . n_j| + EDGE_EPSILON`` (Hoppe 1992, sec. 3.3) as
      float32 bits in the high 32 bits of the key, the edge id in the low ones
      (unique keys; ties broken by position, like SciPy's stable-sort Kruskal);
    * the second copy of a mutual pair is skipped: entry (i, j) with j < i
      when i is certainly among the neighbours of j, i.e.
      ``|p_i - p_j| < |p_j - p_(k-th neighbour of j)|``. With ``dist`` (the
      float32 distances from :func:`knn`, rounded monotonically from the
      exact ones) the strict comparison is exact; without, squared float32
      distances are recomputed and compared with a relative margin of 1e-5 so
      that rounding never drops an edge whose twin is missing. The twin has the
      same cost and a smaller position, so the graph and its MST are unchanged;
    * keys with a cost at most the ``LIGHT_EDGES_PER_POINT / k``-quantile
      (estimated on a sample of rows) go to ``light``, the others to ``heavy``.

    ``irregular``: (N,) bool, rows that are not the k *nearest* neighbours
    (e.g. the rows :mod:`~surfsplat.geometry.cells` chose): no entry into
    such a row is skipped as a twin.

    Returns ``(light, heavy, sign)``: two uint64 key arrays and the (N, k)
    int8 ``sign(n_i . n_j)`` of every entry.
    """
    n, k = idx.shape
    if n * k >= 2**32:
        raise InputError(f"orient_normals: too many edges ({n * k:,}) for 32-bit edge ids")
    ncols = columns(nrm)
    pcols = columns(pts)
    sign = np.empty((n, k), dtype=np.int8)

    def squared_lengths(rows):
        d2 = None
        for col in pcols:
            d = col[idx[rows]]
            d -= col[rows, None]
            d *= d
            d2 = d if d2 is None else np.add(d2, d, out=d2)
        return d2

    # distance of every point to its k-th neighbour (squared without dist)
    far = np.empty(n, dtype=np.float32)

    def far_block(sl):
        d = dist[sl] if dist is not None else squared_lengths(sl)
        far[sl] = d.max(axis=1)

    for_blocks(far_block, n)
    if irregular is not None:
        far[irregular] = -1.0  # never "certainly among its neighbours"
    margin = np.float32(1.0) if dist is not None else np.float32(1.0 - 1e-5)

    def entries(rows, first):
        """Costs and ids of the kept entries of these rows (slice or index array)."""
        it = idx[rows]
        dot = None
        for col in ncols:
            term = col[it]
            term *= col[rows, None]
            dot = term if dot is None else np.add(dot, term, out=dot)
        if isinstance(rows, slice):
            sign[rows] = np.where(dot < 0, np.int8(-1), np.int8(1))
        cost = np.abs(dot)
        np.subtract(np.float32(1.0 + EDGE_EPSILON), cost, out=cost)
        np.maximum(cost, np.float32(EDGE_EPSILON), out=cost)  # |dot| may exceed 1 by rounding
        length = dist[rows] if dist is not None else squared_lengths(rows)
        dup = length < far[it] * margin
        row_ids = np.arange(n)[rows] if not isinstance(rows, slice) else np.arange(rows.start, rows.stop)
        dup &= it < row_ids[:, None]
        keep = np.flatnonzero(~dup.ravel())
        if isinstance(rows, slice):
            eid = keep + first * k
        else:
            eid = row_ids[keep // k] * k + keep % k
        return cost.ravel()[keep], eid

    # light/heavy threshold from ~16 k sampled rows: any threshold gives the same tree
    sample_rows = np.arange(0, n, max(1, n // 16384))
    sample_cost, _ = entries(sample_rows, 0)
    kept_per_point = max(len(sample_cost) / len(sample_rows), 1e-9)
    fraction = min(1.0, LIGHT_EDGES_PER_POINT / kept_per_point)
    limit = np.float32(np.quantile(sample_cost, fraction)) if len(sample_cost) else np.float32(np.inf)

    parts = {}

    def key_block(sl):
        cost, eid = entries(sl, sl.start)
        key = cost.view(np.uint32).astype(np.uint64)
        key <<= np.uint64(32)
        key |= eid.view(np.uint64)
        light = cost <= limit
        parts[sl.start] = (key[light], key[~light])

    for_blocks(key_block, n)
    order = sorted(parts)
    light = np.concatenate([parts[s][0] for s in order])
    heavy = np.concatenate([parts[s][1] for s in order])
    return light, heavy, sign


def _boruvka(n: int, idx: np.ndarray, sign: np.ndarray, light: np.ndarray, heavy: np.ndarray | None = None):
    """Minimum spanning forest of a kNN graph by Boruvka, with sign propagation.

    ``light`` and ``heavy`` hold the unique uint64 keys ``(cost bits << 32) |
    edge id`` of the edges, edge id ``i*k + s`` for the entry ``(i,
    idx[i, s])``, every light key smaller than every heavy one (see
    :func:`_edge_keys`). Each round every component takes its cheapest
    outgoing edge, components merge along them (pointer jumping over the
    component labels), and each merged component's sign relative to its new
    root is ``rel[i] * rel[j] * sign(n_i . n_j)`` for the connecting edge (i, j).

    Filtered like Filter-Kruskal (Osipov, Sanders & Singler 2009): the light
    edges go first; the forest they give is exactly Kruskal's state after
    them, so the heavy edges are then only needed where they join two
    different components. Same tree as Kruskal over all edges, about half the
    work and memory.

    Returns ``(comp, rel, tree_edges)``: (N,) intp component label per point
    (a member point), (N,) int8 sign of each point relative to its label (so
    that ``rel[a] * rel[b] == sign(n_a . n_b)`` along every tree edge), and
    the intp ids of the N - #components tree edges.
    """
    forest = _Forest(n, idx, sign)
    forest.run(light)
    if heavy is not None:
        forest.run(heavy, prefilter=True)
    tree_edges = np.concatenate(forest.tree) if forest.tree else np.zeros(0, dtype=np.intp)
    return forest.comp, forest.rel, tree_edges


class _Forest:
    """State of the Boruvka merges: component label and relative sign of every point."""

    NONE = np.uint64(np.iinfo(np.uint64).max)
    LOW = np.uint64(0xFFFFFFFF)

    def __init__(self, n: int, idx: np.ndarray, sign: np.ndarray):
        self.k = np.int64(idx.shape[1])
        self.dst_all = idx.ravel()
        self.sgn_all = sign.ravel()
        self.comp = np.arange(n, dtype=np.intp)     # component label (a member point) of each point
        self.rel = np.ones(n, dtype=np.int8)        # sign of each point relative to its label
        self.parent = np.arange(n, dtype=np.intp)   # per label, during a round
        self.flip = np.ones(n, dtype=np.int8)
        self.best = np.empty(n, dtype=np.uint64)
        self.tree = []
        self._bufs = None

    def _buffers(self, m: int) -> dict:
        """Work buffers for m edges, reused by every round (and phase) through
        out= arguments: fresh temporaries of this size per round cost as much
        in page faults as the arithmetic itself."""
        if self._bufs is None or len(self._bufs["eid"]) < m:
            self._bufs = {"eid": np.empty(m, dtype=np.int64), "tmp": np.empty(m, dtype=np.intp),
                          "ca": np.empty(m, dtype=np.intp), "cb": np.empty(m, dtype=np.intp),
                          "ext": np.empty(m, dtype=bool), "mkey": np.empty(m, dtype=np.uint64),
                          "spare0": np.empty(m, dtype=np.uint64), "spare1": np.empty(m, dtype=np.uint64)}
        return self._bufs

    def _labels(self, keys, bufs):
        """Component labels of both endpoints of the edges with these keys."""
        size = len(keys)
        eid = np.bitwise_and(keys, self.LOW, out=bufs["eid"][:size].view(np.uint64)).view(np.int64)
        tmp = bufs["tmp"][:size]
        # mode="clip": indices are valid; the default "raise" buffers out= (2-3x slower)
        ca = np.take(self.comp, np.floor_divide(eid, self.k, out=tmp), out=bufs["ca"][:size], mode="clip")
        cb = np.take(self.comp, np.take(self.dst_all, eid, out=tmp, mode="clip"), out=bufs["cb"][:size], mode="clip")
        return ca, cb

    def _external(self, ekey: np.ndarray, chunk: int = 1 << 16) -> np.ndarray:
        """The keys of edges between different components (chunked: small temporaries)."""
        kept = []
        for start in range(0, len(ekey), chunk):
            keys = ekey[start:start + chunk]
            eid = (keys & self.LOW).view(np.int64)
            ca = self.comp[eid // self.k]
            cb = self.comp[self.dst_all[eid]]
            kept.append(keys[ca != cb])
        return np.concatenate(kept) if kept else ekey[:0]

    def run(self, ekey: np.ndarray, prefilter: bool = False) -> None:
        """Merge along the edges with keys ``ekey`` until none joins two components.

        ``prefilter``: first drop the edges inside the current components
        (otherwise all edges must join different components, as at the start).
        """
        if prefilter:
            ekey = self._external(ekey)
        if not len(ekey):
            return
        bufs = self._buffers(len(ekey))
        spares = (bufs["spare0"], bufs["spare1"])  # compaction targets, used in turn
        turn = 0
        ca, cb = self._labels(ekey, bufs)
        mkey = ekey
        while True:
            if not self._round(ca, cb, mkey):
                return
            ca, cb = self._labels(ekey, bufs)
            # keep the edges between different components
            external = np.not_equal(ca, cb, out=bufs["ext"][:len(ekey)])
            alive = int(np.count_nonzero(external))
            if alive == 0:
                return
            if alive < 0.6 * len(ekey):
                ekey = np.compress(external, ekey, out=spares[turn][:alive])
                turn = 1 - turn
                ca, cb = self._labels(ekey, bufs)
                mkey = ekey
            else:
                mkey = bufs["mkey"][:len(ekey)]
                np.copyto(mkey, ekey)
                np.copyto(mkey, self.NONE, where=~external)  # cheaper than compacting

    def _round(self, ca, cb, mkey) -> bool:
        """One Boruvka round over edges with endpoint labels ca, cb and keys mkey (NONE = skip)."""
        comp, parent, flip, rel, best = self.comp, self.parent, self.flip, self.rel, self.best
        # each component's cheapest outgoing edge
        best.fill(self.NONE)
        np.minimum.at(best, ca, mkey)
        np.minimum.at(best, cb, mkey)
        act = np.flatnonzero(best != self.NONE)
        if not len(act):
            return False
        e = (best[act] & self.LOW).astype(np.intp)
        ea, eb = e // self.k, self.dst_all[e]
        a_inside = comp[ea] == act
        inside = np.where(a_inside, ea, eb)
        outside = np.where(a_inside, eb, ea)
        other = comp[outside]
        parent[act] = other
        # sign of this component's label relative to the other's, so that
        # sign(inside) * sign(outside) == sign(n_inside . n_outside)
        flip[act] = rel[inside] * rel[outside] * self.sgn_all[e]
        # two components that chose each other (the same edge): the smaller label is the root
        root = (parent[other] == act) & (act < other)
        parent[act[root]] = act[root]
        flip[act[root]] = 1
        self.tree.append(e[~root])
        _pointer_jump(parent, flip, act)
        rel *= flip[comp]
        self.comp = parent[comp]
        parent[act] = act
        flip[act] = 1
        return True


def _scipy_forest(n: int, cost: np.ndarray, sign: np.ndarray, idx: np.ndarray):
    """Same ``(comp, rel, tree)`` as :func:`_boruvka` via scipy.sparse.csgraph (reference path); tree is the COO MST."""
    k = idx.shape[1]
    graph = csr_matrix((cost.ravel().astype(np.float64), idx.ravel(), np.arange(0, n * k + 1, k)), shape=(n, n))
    mst = minimum_spanning_tree(graph).tocoo()  # undirected reading of the kNN graph = symmetric kNN graph
    ncomp, labels = connected_components(mst, directed=False)
    # root of each component: its smallest point index; tie a virtual node n to
    # every root so one breadth-first traversal covers the whole forest
    roots = np.full(ncomp, n, dtype=np.intp)
    np.minimum.at(roots, labels, np.arange(n))
    rows = np.concatenate([mst.row, np.full(ncomp, n)])
    cols = np.concatenate([mst.col, roots])
    forest = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1))
    _, pred = breadth_first_order(forest, n, directed=False, return_predecessors=True)
    parent = pred[:n].astype(np.intp)
    parent[roots] = roots
    # sign of each point relative to its tree parent: sign(n_child . n_parent),
    # looked up from the kNN edge that the tree used (either direction)
    ids = np.flatnonzero(parent != np.arange(n))
    rel = np.ones(n, dtype=np.int8)
    if len(ids):
        dot_sign = _pair_sign(sign, idx, ids, parent[ids])
        rel[ids] = dot_sign
    _pointer_jump(parent, rel)
    return parent, rel, mst


def _pair_sign(sign: np.ndarray, idx: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """int8 sign(n_a . n_b) for pairs that are kNN edges in at least one direction."""
    hit_ab = idx[a] == b[:, None]
    hit_ba = idx[b] == a[:, None]
    from_ab = hit_ab.any(axis=1)
    out = np.empty(len(a), dtype=np.int8)
    out[from_ab] = sign[a[from_ab], np.argmax(hit_ab[from_ab], axis=1)]
    rest = ~from_ab
    out[rest] = sign[b[rest], np.argmax(hit_ba[rest], axis=1)]
    return out


def orient_normals(positions, normals, indices, distances=None, *, method: str = "boruvka") -> np.ndarray:
    """Flip normals to a consistent orientation over the neighbour graph (Hoppe et al. 1992).

    The Riemannian graph is the symmetric kNN graph (edge i-j when j is among
    the neighbours of i or i among those of j) with cost
    ``1 - |n_i . n_j| + EDGE_EPSILON``. Along its minimum spanning tree (one
    per connected component) signs propagate as
    ``sign(child) = sign(parent) * sign(n_child . n_parent)``. Each component
    is seeded at its point of largest z, whose normal is turned to +z; where
    that normal is nearly horizontal (``|n_z| < HORIZONTAL_NZ``) it is turned
    away from the component's centroid instead. On a closed surface this gives
    outward normals; on open surfaces, normals on the +z side.

    Args:
        positions: (N, 3) float array, model units.
        normals: (N, 3) float array of (not necessarily unit) normals, any signs.
        indices: (N, k) integer neighbour indices (e.g. from :func:`knn`).
        distances: optional (N, k) float32 distances returned by :func:`knn`
            together with ``indices``; only used to skip duplicate edges
            faster (same result without them).
        method: ``"boruvka"`` (default, vectorized NumPy Boruvka) or
            ``"scipy"`` (``scipy.sparse.csgraph.minimum_spanning_tree``,
            breadth-first order, pointer jumping). Both give the same result.

    Returns:
        (N, 3) float32: ``normals`` (renormalized to unit length) times +-1.
    """
    pts, nrm, idx = check_oriented_points(positions, normals, indices)
    if method not in ("boruvka", "scipy"):
        raise InputError(f"orient_normals: method must be 'boruvka' or 'scipy', got {method!r}")
    if distances is not None:
        distances = np.asarray(distances, dtype=np.float32)
        if distances.shape != idx.shape:
            raise InputError(f"distances {distances.shape} and indices {idx.shape} must have the same shape")
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
    sigma = orientation_signs(pts, nrm, idx, distances, method)
    nrm *= sigma[:, None]
    return nrm


def orientation_signs(pts: np.ndarray, nrm: np.ndarray, idx: np.ndarray, dist: np.ndarray | None = None,
                      method: str = "boruvka", irregular: np.ndarray | None = None) -> np.ndarray:
    """(N,) int8 signs that orient unit normals ``nrm`` consistently (see :func:`orient_normals`).

    Arguments already validated: float32 (N, 3) ``pts`` and unit ``nrm``,
    intp (N, k) ``idx``, optional float32 (N, k) ``dist`` from :func:`knn`
    (the distances of the entries of ``idx``); ``irregular`` (N,) bool marks
    rows of ``idx`` that are not the k nearest neighbours (see :func:`_edge_keys`).
    """
    n = len(pts)
    if method == "boruvka":
        light, heavy, sign = _edge_keys(pts, nrm, idx, dist, irregular)
        comp, rel, _ = _boruvka(n, idx, sign, light, heavy)
        del light, heavy, sign
    else:
        cost, sign = _edge_costs(nrm, idx)
        comp, rel, _ = _scipy_forest(n, cost, sign, idx)
        del cost, sign
    desired, seeds = _seed_signs(pts, nrm, comp)
    root_sign = np.ones(n, dtype=np.int8)
    root_sign[comp[seeds]] = rel[seeds] * desired
    rel *= root_sign[comp]
    return rel


def _seed_signs(pts: np.ndarray, nrm: np.ndarray, comp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per component (label = a member point): the seed (its highest point) and the sign its normal needs."""
    n = len(pts)
    z = np.ascontiguousarray(pts[:, 2])
    zmax = np.full(n, -np.inf, dtype=np.float32)
    np.maximum.at(zmax, comp, z)
    cand = np.flatnonzero(z == zmax[comp])
    seed_of = np.empty(n, dtype=np.intp)
    seed_of[comp[cand]] = cand
    labels = np.flatnonzero(comp == np.arange(n))
    seeds = seed_of[labels]
    nz = nrm[seeds, 2]
    desired = np.where(nz < 0, -1, 1).astype(np.int8)  # seed normal towards +z
    horizontal = np.flatnonzero(np.abs(nz) < HORIZONTAL_NZ)
    if len(horizontal):
        # nearly horizontal seed normal: turn it away from the component's centroid
        lab = labels[horizontal]
        slot = np.full(n, -1, dtype=np.intp)
        slot[lab] = np.arange(len(lab))
        member = np.flatnonzero(slot[comp] >= 0)
        group = slot[comp[member]]
        count = np.bincount(group, minlength=len(lab)).astype(np.float64)
        centroid = np.stack([np.bincount(group, weights=pts[member, c], minlength=len(lab)) / count
                             for c in range(3)], axis=1)
        sd = seeds[horizontal]
        away = np.einsum("ij,ij->i", nrm[sd].astype(np.float64), pts[sd] - centroid)
        desired[horizontal] = np.where(away < 0, -1, 1)
    return desired, seeds


def orient_towards(normals, positions, viewpoint) -> np.ndarray:
    """Flip each normal to face a viewpoint (e.g. the scanner position).

    Args:
        normals: (N, 3) float array.
        positions: (N, 3) float array, model units.
        viewpoint: (3,) or (N, 3) float array, model units.

    Returns:
        (N, 3) float32 normals with ``n . (viewpoint - p) >= 0``.
    """
    nrm = check_vectors(normals, "normals")
    pts = check_vectors(positions, "positions", len(nrm))
    view = np.asarray(viewpoint, dtype=np.float32)
    facing = np.einsum("ij,ij->i", nrm, np.broadcast_to(view, pts.shape) - pts)
    return np.where((facing < 0)[:, None], -nrm, nrm).astype(np.float32)
