"""SplatCloud: the one splat representation every technique renders.

A structure of arrays, float32, one row per splat (DESIGN.md), with positions relative to
a float64 ``origin``: world coordinates are ``origin + positions``, so georeferenced data
(coordinates of 1e6..1e7 with millimetre spacing) keep float32's precision relative to
their own extent wherever they sit. A splat is an
ellipse in 3D: center ``positions[i]``, unit ``normals[i]`` and two scaled
tangent axes ``u[i]``, ``v[i]`` (orthogonal to the normal; a circular splat of
radius r has |u| = |v| = r). A point of the splat is
``positions + s * u + t * v`` with ``s**2 + t**2 <= 1``: ``(s, t)`` are the
splat's normalized coordinates, used by clip lines and normal fields.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InputError
from .frames import tangent_frame64

#: Albedo used where the input carries no colors (linear RGB in [0, 1]).
DEFAULT_ALBEDO = 0.8

#: A clip line that keeps everything: ``0 s + 0 t + 1 >= 0``.
NO_CLIP = np.array([0.0, 0.0, 1.0], dtype=np.float32)

#: Positions given without an origin are moved to one (their bounding-box centre) when the
#: centre lies farther from zero than this many times their extent: beyond it float32 would
#: keep less than 1/16 of its precision relative to the data's own size.
RECENTER_RATIO = 16.0

#: Largest magnitude of a coordinate relative to the origin (model units) that the float32 mesh
#: renderer draws: squares stay finite in float32 (3.4e38); beyond it a mesh comes out blank.
#: :meth:`Mesh.validated <surfsplat.io.mesh.Mesh.validated>` refuses such vertices. (Splats are
#: scaled to about unit size before they reach the GPU, which checks them against the same value,
#: ``surfsplat.rendering.gpu_splats.MAX_COORDINATE``.)
MAX_COORDINATE = 1e18


@dataclass
class SplatCloud:
    """Splats as a structure of float32 arrays.

    Attributes:
        positions: (N, 3) float32 splat centers relative to ``origin``, model units.
        normals: (N, 3) float32 unit vectors or None (estimated by preprocessing).
        colors: (N, 3) float32 linear RGB in [0, 1] or None (rendered 0.8 gray).
        u, v: (N, 3) float32 scaled tangent axes, model-space units, or None
            (set by preprocessing). Orthogonal to the normal.
        normal_field: (N, 2) float32 ``(alpha, beta)`` of the linear normal
            field ``n(s, t) = n + s * alpha * u_hat + t * beta * v_hat``
            (Botsch 2004, eq. 2, with ``normals`` as the center normal), or None.
        clip_lines: (N, 2, 3) float32 ``(a, b, c)`` in normalized ``(s, t)``
            coordinates; a point is kept where ``a s + b t + c >= 0``. Unused
            lines are ``(0, 0, 1)``. None when no splat is clipped.
        attributes: named per-point values, ``{name: (N,) array}`` of any numeric dtype
            (kept as read: LAS ``intensity`` uint16, ``classification`` uint8, PLY
            ``confidence`` float32, ...), or None. Rows follow the points through
            ``subset``, ``validated`` and preprocessing.
        origin: (3,) float64 world position of the local zero: a splat's world center is
            ``origin + positions[i]``. None: zeros, or, for positions given in another dtype
            than float32 (float64 world coordinates) that lie far from zero relative to their
            extent (:data:`RECENTER_RATIO`), their bounding-box centre (rounded to a multiple of
            a power of two below the extent), the positions being stored relative to it
            (:func:`split_origin`).
        up: the model's up axis as 3 floats (a unit vector, world), or None where unknown. Set by
            the loaders where the file says (LAS/LAZ/E57: +z; a PLY or hierarchy written by
            surfsplat stores it) and carried by :meth:`subset`, :meth:`replace` and
            :meth:`with_arrays`; :func:`surfsplat.orientation.model_up` decides where it is None.
    """

    positions: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    u: np.ndarray | None = None
    v: np.ndarray | None = None
    normal_field: np.ndarray | None = None
    clip_lines: np.ndarray | None = None
    attributes: dict[str, np.ndarray] | None = None
    origin: np.ndarray = None  # type: ignore[assignment]  # None given: zeros (__post_init__)
    up: tuple[float, float, float] | None = None

    _OPTIONAL = ("normals", "colors", "u", "v", "normal_field", "clip_lines")
    _SHAPES = {
        "positions": (3,),
        "normals": (3,),
        "colors": (3,),
        "u": (3,),
        "v": (3,),
        "normal_field": (2,),
        "clip_lines": (2, 3),
    }

    def __post_init__(self) -> None:
        if self.origin is None:
            if self.positions is not None:
                self.origin, self.positions = split_origin(self.positions)
            else:
                self.origin = np.zeros(3)
        else:
            origin = np.array(self.origin, dtype=np.float64).reshape(-1)
            if origin.shape != (3,) or not np.isfinite(origin).all():
                raise InputError(f"origin must be 3 finite numbers, got {self.origin!r}", argument="origin")
            self.origin = origin
        if self.up is not None:
            self.up = checked_up(self.up)
        for name, tail in self._SHAPES.items():
            value = getattr(self, name)
            if value is None:
                if name == "positions":
                    raise InputError("positions are required", argument="positions")
                continue
            with np.errstate(over="ignore"):   # beyond float32's range: inf, dropped and counted by validation
                arr = np.ascontiguousarray(value, dtype=np.float32)
            if name == "clip_lines" and arr.ndim == 2 and arr.shape[1] == 3:
                # one clip line per splat: pad the second with "keep all"
                arr = np.concatenate([arr[:, None, :], np.broadcast_to(NO_CLIP, arr.shape)[:, None, :]], axis=1)
            if arr.ndim != 1 + len(tail) or arr.shape[1:] != tail:
                raise InputError(f"{name} must have shape (N, {', '.join(map(str, tail))}), got {arr.shape}",
                                 argument=name, element=name)
            setattr(self, name, arr)
        n = len(self.positions)
        for name in self._OPTIONAL:
            value = getattr(self, name)
            if value is not None and len(value) != n:
                raise InputError(f"{name} has {len(value)} rows but positions has {n}", argument=name, element=name)
        if self.attributes is not None:
            self.attributes = checked_attributes(self.attributes, n)

    def __len__(self) -> int:
        return len(self.positions)

    def __repr__(self) -> str:
        present = [name for name in self._OPTIONAL if getattr(self, name) is not None]
        if self.attributes:
            present.append(f"attributes {', '.join(self.attributes)}")
        at = f", origin {np.array2string(self.origin, precision=10)}" if self.origin.any() else ""
        if self.up is not None:
            at += f", up {' '.join(f'{x:g}' for x in self.up)}"
        return f"SplatCloud({len(self)} splats, with {', '.join(present) or 'positions only'}{at})"

    # -- derived quantities -------------------------------------------------

    @property
    def has_splats(self) -> bool:
        """True when every splat has a normal and tangent axes (ready to render)."""
        return self.normals is not None and self.u is not None and self.v is not None

    @property
    def radii(self) -> np.ndarray:
        """(N,) float32 largest semi-axis of each splat, model units (needs u, v)."""
        if self.u is None or self.v is None:
            raise InputError("this SplatCloud has no splat axes yet; preprocess it first")
        # in float64: float32 squares overflow beyond 1.8e19 (a radius of 1e20 is not inf)
        lengths = np.maximum(np.linalg.norm(self.u.astype(np.float64), axis=1),
                             np.linalg.norm(self.v.astype(np.float64), axis=1))
        return lengths.astype(np.float32)

    @property
    def albedo(self) -> np.ndarray:
        """(N, 3) float32 colors, or the default 0.8 gray where none are stored."""
        if self.colors is not None:
            return self.colors
        return np.full((len(self), 3), DEFAULT_ALBEDO, dtype=np.float32)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned world bounds ``(min, max)`` of the splat centers, (3,) float64 each, model
        units (``origin`` + the local bounds)."""
        # per column: NumPy's min(axis=0) of an (N, 3) array runs strided, 30x slower (100 ms per million)
        columns = [self.positions[:, i] for i in range(3)]
        lo = np.array([c.min() for c in columns], dtype=self.positions.dtype)
        hi = np.array([c.max() for c in columns], dtype=self.positions.dtype)
        return lo + self.origin, hi + self.origin

    def world_positions(self) -> np.ndarray:
        """(N, 3) float64 world splat centers, ``origin + positions``, model units."""
        return self.positions.astype(np.float64) + self.origin

    def subset(self, index: np.ndarray) -> "SplatCloud":
        """A new SplatCloud with the rows selected by a boolean mask or index array (same origin)."""
        fields: dict[str, Any] = {name: (None if getattr(self, name) is None else getattr(self, name)[index])
                                  for name in ("positions",) + self._OPTIONAL}
        if self.attributes is not None:
            fields["attributes"] = {name: values[index] for name, values in self.attributes.items()}
        return SplatCloud(**fields, origin=self.origin, up=self.up)

    def replace(self, **changes) -> "SplatCloud":
        """A copy with some arrays replaced (validated like the constructor); ``origin`` and ``up``
        are kept unless changed."""
        return dataclasses.replace(self, **changes)

    def with_arrays(self, positions, **arrays) -> "SplatCloud":
        """A new SplatCloud of other rows with this one's metadata: ``positions`` (relative to this
        cloud's ``origin``) and any other arrays by name (``normals``, ``colors``, ``u``, ``v``,
        ``normal_field``, ``clip_lines``, ``attributes``; absent ones are None), with this cloud's
        ``origin`` and ``up``. Validated like the constructor."""
        return SplatCloud(positions=positions, **arrays, origin=self.origin, up=self.up)

    # -- conversions -------------------------------------------------------

    @classmethod
    def from_arrays(cls, positions, normals=None, colors=None, *, radius=None, u=None, v=None,
                    normal_field=None, clip_lines=None, origin=None) -> "SplatCloud":
        """A SplatCloud from plain arrays (anything ``numpy.asarray`` accepts), unvalidated.

        ``positions`` are world coordinates (kept in float64 until an origin is chosen, see
        :class:`SplatCloud`), or relative to ``origin`` when it is given.

        ``colors`` may be uint8 / uint16 (divided by 255 / 65535), other integers or floats
        (see :func:`unit_colors`: floats above 1 are read as 0..255). ``radius`` ((N,) model
        units) gives circular splats; it needs ``normals`` and is ignored when ``u``, ``v`` are
        given.
        """
        if colors is not None:
            colors = unit_colors(colors)
        if radius is not None and u is None and v is None:
            if normals is None:
                raise InputError("radius needs normals (a circular splat needs a normal to orient it)",
                                 argument="radius")
            u, v = circle_axes(normals, radius)
        return cls(positions=positions, normals=normals, colors=colors, u=u, v=v,
                   normal_field=normal_field, clip_lines=clip_lines, origin=origin)

    @classmethod
    def from_dict(cls, columns, *, extras: dict | None = None) -> "SplatCloud":
        """A SplatCloud from named columns: a mapping of name -> array, or a structured / record array.

        Names (case-insensitive; a leading ``//`` or ``#`` as CloudCompare writes is ignored):
        ``positions`` (N, 3) or ``x y z``; ``normals`` (N, 3) or ``nx ny nz`` (also
        ``normal_x ...``); ``colors`` (N, 3) or ``red green blue`` / ``r g b`` (uint8 or float,
        see :func:`unit_colors`); ``radius``; ``u``, ``v`` (N, 3) or ``ux uy uz vx vy vz``;
        ``normal_field`` (N, 2); ``clip_lines`` (N, 2, 3). Every other column is put in
        ``extras`` (when given) under its original name. Unvalidated.
        """
        if isinstance(columns, np.ndarray) and columns.dtype.names:
            columns = {name: columns[name] for name in columns.dtype.names}
        if not hasattr(columns, "items"):
            raise InputError(f"from_dict needs a mapping of column names to arrays, got {type(columns).__name__}")
        table = {}
        for name, value in columns.items():
            key = str(name).strip().lstrip("/#").strip().lower()
            table[key] = (name, value)
        used: set[str] = set()

        def take(*names):
            for key in names:
                if key in table:
                    used.add(key)
                    return np.asarray(table[key][1])
            return None

        def group(whole, *alternatives):
            value = take(whole) if whole else None
            if value is not None:
                return value
            for names in alternatives:
                present = [key for key in names if key in table]
                if present and len(present) < len(names):
                    missing = [key for key in names if key not in table]
                    raise InputError(f"columns {' '.join(present)} present but {' '.join(missing)} missing",
                                     element=table[present[0]][0])
                if present:
                    return np.column_stack([take(key).reshape(-1) for key in names])
            return None

        positions = group("positions", ("x", "y", "z"))
        if positions is None:
            positions = take("points", "xyz", "vertices")
        if positions is None:
            raise InputError(f"no positions: expected a 'positions' column or x, y, z columns "
                             f"(columns: {', '.join(str(table[k][0]) for k in table) or 'none'})", element="x")
        normals = group("normals", ("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"))
        colors = group("colors", ("red", "green", "blue"), ("r", "g", "b"))
        if colors is None:
            colors = take("rgb")
        u = group("u", ("ux", "uy", "uz"))
        v = group("v", ("vx", "vy", "vz"))
        radius = take("radius")
        normal_field = group("normal_field", ("alpha", "beta")) if ("beta" in table or "normal_field" in table) \
            else None
        clip_lines = take("clip_lines")
        if extras is not None:
            extras.update({table[key][0]: np.asarray(table[key][1]) for key in table if key not in used})
        if colors is not None and colors.ndim == 2 and colors.shape[1] == 4:
            colors = colors[:, :3]  # RGBA: alpha ignored
        return cls.from_arrays(positions, normals, colors, radius=radius, u=u, v=v,
                               normal_field=normal_field, clip_lines=clip_lines)

    def to_dict(self, *, columns: bool = False) -> dict[str, np.ndarray]:
        """The arrays present, by name: ``{"positions": (N, 3), "normals": ..., ...}`` (copies).

        With ``columns=True``: one (N,) array per scalar column (float32; x y z float64 with an origin),
        named as in PLY files
        (``x y z nx ny nz red green blue ux uy uz vx vy vz alpha beta clip0_a ... clip1_c``;
        colors in [0, 1]), ready for ``pandas.DataFrame``; :meth:`from_dict` reads both forms.
        Positions are world coordinates: float64 ``origin + positions`` when the origin is not zero.
        """
        arrays = {name: getattr(self, name).copy() for name in ("positions",) + self._OPTIONAL
                  if getattr(self, name) is not None}
        if self.origin.any():   # world coordinates, as from_dict reads them
            arrays["positions"] = self.world_positions()
        if not columns:
            return arrays
        names = {"positions": ("x", "y", "z"), "normals": ("nx", "ny", "nz"), "colors": ("red", "green", "blue"),
                 "u": ("ux", "uy", "uz"), "v": ("vx", "vy", "vz"), "normal_field": ("alpha", "beta"),
                 "clip_lines": tuple(f"clip{k}_{c}" for k in (0, 1) for c in "abc")}
        out = {}
        for name, value in arrays.items():
            flat = value.reshape(len(self), -1)
            out.update({column: flat[:, i].copy() for i, column in enumerate(names[name])})
        if "clip_lines" in arrays:  # from_dict reads clip lines as one (N, 2, 3) column
            out = {k: val for k, val in out.items() if not k.startswith("clip")}
            out["clip_lines"] = arrays["clip_lines"]
        return out

    # -- validation --------------------------------------------------------

    def validated(self, source: str = "input", *, file=None) -> "SplatCloud":
        """Drop invalid rows and report how many, raising if nothing is left.

        Dropped: non-finite positions (or other non-finite arrays; positions beyond float32's
        3.4e38 from the origin are infinite), zero-length or non-finite normals, and zero,
        negative, non-finite or degenerate splat axes.
        Normals are renormalized (in float64, scaled by their largest component first, so
        lengths far beyond float32's squares, 1e20, or below them, 1e-30, normalize exactly)
        and colors clipped to [0, 1]. ``source`` names the file or array in messages, ``file``
        (a path, or None) is set on the error and the warning.

        Raises:
            InputError (``file``, ``row`` 0, ``element`` the first row's fault): no rows, or none
                valid. A warning, :class:`InvalidPointsWarning`, counts dropped rows (its ``row``:
                the first of them, ``element``: why it was dropped, ``count``: how many).
        """
        n = len(self)
        if n == 0:
            raise InputError(f"{source}: contains no points", file=file)
        keep = np.isfinite(self.positions).all(axis=1)
        faults = [("positions", ~keep)]
        reasons = {"non-finite coordinates or ones beyond float32's 3.4e38 from the origin": int(n - keep.sum())}
        if self.normals is not None:
            scale = np.abs(self.normals).max(axis=1)
            bad = ~(np.isfinite(self.normals).all(axis=1) & (scale > 0))
            reasons["zero-length or non-finite normals"] = int((bad & keep).sum())
            faults.append(("normals", bad & keep))
            keep &= ~bad
        if self.u is not None and self.v is not None:
            u, v = self.u.astype(np.float64), self.v.astype(np.float64)   # float32 squares overflow beyond 1e19
            lu = np.linalg.norm(u, axis=1)
            lv = np.linalg.norm(v, axis=1)
            cross = np.linalg.norm(np.cross(u, v), axis=1)
            bad = ~(np.isfinite(lu) & np.isfinite(lv)) | (lu <= 0) | (lv <= 0) | (cross <= 1e-12 * lu * lv)
            reasons["zero, negative or degenerate splat radii"] = int((bad & keep).sum())
            faults.append(("u, v", bad & keep))
            keep &= ~bad
        for name in ("colors", "normal_field", "clip_lines"):
            value = getattr(self, name)
            if value is not None:
                bad = ~np.isfinite(value.reshape(n, -1)).all(axis=1)
                reasons[f"non-finite {name.replace('_', ' ')}"] = int((bad & keep).sum())
                faults.append((name, bad & keep))
                keep &= ~bad
        dropped = n - int(keep.sum())
        if dropped:
            row = int(np.argmin(keep))
            element = next(name for name, bad in faults if bad[row])
            detail = ", ".join(f"{count} with {why}" for why, count in reasons.items() if count)
        if dropped == n:
            raise InputError(f"{source}: no valid points left ({detail})", file=file, element=element, row=row)
        out = self.subset(keep) if dropped else self.replace()
        if dropped:
            warnings.warn(InvalidPointsWarning(f"{source}: dropped {dropped} of {n} points ({detail})", file=file,
                                               element=element, row=row, count=dropped), stacklevel=2)
        if out.normals is not None:
            out.normals = unit_normals(out.normals)
        if out.colors is not None:
            out.colors = np.clip(out.colors, 0.0, 1.0)
        return out


def unit_normals(normals: np.ndarray) -> np.ndarray:
    """(N, 3) float32 ``normals`` at unit length: rows off unit length by more than 1e-6 are
    divided by their length, computed in float64 after dividing by their largest component (no
    overflow of the squares however long, no underflow however short); the others are kept as
    they are (so validation is idempotent). Zero or non-finite rows become NaN (callers drop them
    first). The input is not modified."""
    with np.errstate(over="ignore", invalid="ignore"):
        length = np.linalg.norm(normals, axis=1)
    off = ~(np.abs(length - 1.0) <= 1e-6)
    if not off.any():
        return normals
    rows = normals[off].astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        rows /= np.abs(rows).max(axis=1, keepdims=True)
        rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    out = normals.copy()
    out[off] = rows
    return out


def split_origin(positions) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, local)`` of world ``positions``: (3,) float64 and the (N, 3) positions relative
    to it. float32 positions are taken as they are (local, origin zero: what library code passes);
    for others the origin is zero unless the bounding-box centre of the finite rows lies farther
    from zero than :data:`RECENTER_RATIO` times their extent; it is then that centre rounded to a
    multiple of the largest power of two not above the extent (so coordinates on a grid stay
    exact), and ``local`` is computed in float64. Shapes are checked by the caller."""
    arr = np.asarray(positions)
    if arr.dtype == np.float32 or arr.dtype.kind not in "uif" or arr.ndim != 2 or arr.shape[1:] != (3,) \
            or len(arr) == 0:
        return np.zeros(3), positions
    world = arr.astype(np.float64)
    finite = np.isfinite(world).all(axis=1)
    if not finite.any():
        return np.zeros(3), positions
    with np.errstate(over="ignore", invalid="ignore"):
        lo, hi = world[finite].min(axis=0), world[finite].max(axis=0)
        center = 0.5 * lo + 0.5 * hi
        extent = float(np.max(hi - lo))
        if not np.isfinite(extent) or not np.abs(center).max() > RECENTER_RATIO * extent:
            return np.zeros(3), positions
        if extent == 0:
            return np.zeros(3), positions   # coincident points: no spacing for float32 to lose
        step = 2.0 ** np.floor(np.log2(extent)) if extent > 0 else 0.0
        origin = np.round(center / step) * step if step > 0 and np.isfinite(center / step).all() else center
        return origin, world - origin


def checked_up(up) -> tuple[float, float, float]:
    """``up`` as a unit vector of 3 Python floats; an InputError unless it is 3 finite numbers, not
    all zero."""
    try:
        vec = np.array(up, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"up must be 3 finite numbers, got {up!r}") from None
    length = float(np.linalg.norm(vec)) if vec.shape == (3,) and np.isfinite(vec).all() else 0.0
    if not length > 0:
        raise InputError(f"up must be 3 finite numbers, not all zero, got {up!r}")
    x, y, z = (float(c) for c in vec / length)
    return (x, y, z)


def concatenate(clouds) -> SplatCloud:
    """One SplatCloud of the rows of ``clouds`` in order, positions relative to the first one's
    ``origin`` (others are moved there in float64), its ``up`` kept when every cloud that states
    one states the same (else None). An array present in some clouds only is dropped; attributes
    are kept where every cloud has them."""
    clouds = list(clouds)
    if not clouds or not all(isinstance(c, SplatCloud) for c in clouds):
        raise InputError("concatenate needs one or more SplatClouds")
    first = clouds[0]
    positions = np.concatenate([(c.positions.astype(np.float64) + (c.origin - first.origin)).astype(np.float32)
                                if (c.origin != first.origin).any() else c.positions for c in clouds])
    arrays: dict[str, Any] = {name: np.concatenate([getattr(c, name) for c in clouds])
                              for name in SplatCloud._OPTIONAL if all(getattr(c, name) is not None for c in clouds)}
    common = set.intersection(*(set(c.attributes or ()) for c in clouds))
    if common:
        arrays["attributes"] = {name: np.concatenate([c.attributes[name] for c in clouds])
                                for name in first.attributes if name in common}
    ups = [c.up for c in clouds if c.up is not None]
    up = ups[0] if ups and all(np.allclose(u, ups[0], atol=1e-6) for u in ups) else None
    return SplatCloud(positions=positions, **arrays, origin=first.origin, up=up)


def checked_attributes(attributes, n: int) -> dict[str, np.ndarray] | None:
    """``attributes`` as a new dict of contiguous 1-D numeric arrays of ``n`` rows (dtype kept;
    booleans become uint8), or None when empty; an InputError names a bad one."""
    if not hasattr(attributes, "items"):
        raise InputError(f"attributes must be a mapping of name -> (N,) array, got {type(attributes).__name__}",
                         argument="attributes")
    out = {}
    for name, value in attributes.items():
        arr = np.ascontiguousarray(value)
        if arr.dtype.kind == "b":
            arr = arr.astype(np.uint8)
        if arr.dtype.kind not in "uif":
            raise InputError(f"attribute {name!r} must be numeric, got dtype {arr.dtype}", element=str(name))
        if arr.ndim != 1 or len(arr) != n:
            raise InputError(f"attribute {name!r} must have shape ({n},), got {arr.shape}", element=str(name))
        out[str(name)] = arr
    return out or None


class InvalidPointsWarning(UserWarning):
    """Some input points were invalid and dropped; the message gives counts.

    Attributes (None where unknown): ``file`` (path, str), ``element`` (why the first dropped row
    was dropped: the array at fault, "positions", "normals", "u, v", "colors", ...), ``row`` (the
    first dropped row, index into the input), ``count`` (how many were dropped)."""

    def __init__(self, *args, file=None, element=None, row=None, count=None):
        super().__init__(*args)
        self.file = None if file is None else str(file)
        self.element = element
        self.row = None if row is None else int(row)
        self.count = None if count is None else int(count)


def unit_colors(values) -> np.ndarray:
    """(N, 3) float32 colors in [0, 1] from 8-bit, 16-bit or float colors.

    uint8 / int8-range integers: / 255; uint16: / 65535; other integers: / 255 when the largest
    value is <= 255, / 65535 when <= 65535; floats: as they are, unless the largest finite value
    is above 1 (0..255 floats): / 255.
    """
    arr = np.asarray(values)
    if arr.dtype.kind == "b" or arr.dtype.kind not in "uif":
        raise InputError(f"colors must be numbers, got dtype {arr.dtype}")
    if arr.dtype.kind in "ui":
        top = int(arr.max()) if arr.size else 0
        if arr.dtype == np.uint16 or top > 255:
            scale = 65535.0 if top <= 65535 else float(np.iinfo(arr.dtype).max)
        else:
            scale = 255.0
    else:
        finite = arr[np.isfinite(arr)]
        scale = 255.0 if finite.size and float(finite.max()) > 1.0 else 1.0
    return (arr.astype(np.float64) / scale).astype(np.float32)


def circle_axes(normals, radius) -> tuple[np.ndarray, np.ndarray]:
    """Tangent axes (u, v), (N, 3) float32, of circular splats of ``radius`` around ``normals``
    (right-handed: ``u x v`` along n). Zero or non-finite normals give NaN axes, bad radii zero
    axes: validation drops both."""
    n = np.asarray(normals, dtype=np.float64)
    r = np.asarray(radius, dtype=np.float64).reshape(-1)
    if n.ndim != 2 or n.shape[1] != 3 or len(r) != len(n):
        raise InputError(f"radius ({r.shape}) and normals ({n.shape}) must have N and (N, 3) entries")
    length = np.linalg.norm(n, axis=1)
    ok = np.isfinite(length) & (length > 0)
    t1 = np.full(n.shape, np.nan)
    t2 = np.full(n.shape, np.nan)
    if ok.any():
        t1[ok], t2[ok] = tangent_frame64(n[ok] / length[ok, None])
    r = np.where(np.isfinite(r) & (r > 0), r, 0.0)[:, None]
    return (t1 * r).astype(np.float32), (t2 * r).astype(np.float32)
