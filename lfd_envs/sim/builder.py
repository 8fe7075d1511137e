"""Scene description for the particle engine: cloth grids, ropes, static and rigid boxes.

A :class:`SceneBuilder` describes ONE world.  :class:`~lfd_envs.sim.ParticleSim` takes one
builder per world; all builders of a batch must share the same *topology* (particle count,
constraint graph, rigid-box particle ranges, pinned layout may differ), while geometry
(positions, rest lengths, static box poses, rigid box sizes) may differ per world.

Coordinates are z-up, metres; the ground plane ``z = 0`` always exists and needs no builder call.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .params import bend_span

__all__ = [
    "SceneBuilder",
    "ClothHandle",
    "RopeHandle",
    "RigidBoxHandle",
    "StaticBox",
    "STRETCH",
    "SHEAR",
    "BEND",
]

# constraint types
STRETCH = 0
SHEAR = 1
BEND = 2



def _vec3(value, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr


def _positive(value, name: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be a finite number > 0, got {value}")
    return v


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class ClothHandle:
    """A rectangular cloth grid inside one world.

    Attributes:
        start: Index of the first particle (world-local); particles are ``start .. start+nx*ny-1``.
        nx: Particles per row (along the cloth's local x axis).
        ny: Number of rows (along the cloth's local y axis).
        triangles: ``(2*(nx-1)*(ny-1), 3)`` int32 particle indices (world-local).  Winding is
            counter-clockwise seen from the cloth's *front* side, which faces +z when the cloth
            is created (``normal = cross(p1 - p0, p2 - p0)`` points to the front).
        corners: World-local indices of the corners in the order
            ``(row 0 col 0, row 0 col nx-1, row ny-1 col nx-1, row ny-1 col 0)``.
        spacing: Rest spacing ``(dx, dy)`` in metres.
    """

    start: int
    nx: int
    ny: int
    triangles: np.ndarray
    corners: tuple[int, int, int, int]
    spacing: tuple[float, float]

    @property
    def count(self) -> int:
        """Number of particles."""
        return self.nx * self.ny

    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape ``(ny, nx)``; ``positions[..., h.indices, :]`` reshapes to ``(ny, nx, 3)``."""
        return (self.ny, self.nx)

    @property
    def indices(self) -> np.ndarray:
        """World-local particle indices in row-major ``(ny, nx)`` order."""
        return np.arange(self.start, self.start + self.count)

    def index(self, row: int, col: int) -> int:
        """World-local index of grid particle ``(row, col)``."""
        if not (0 <= row < self.ny and 0 <= col < self.nx):
            raise IndexError(f"cloth grid index ({row}, {col}) outside ({self.ny}, {self.nx})")
        return self.start + row * self.nx + col


@dataclass(frozen=True)
class RopeHandle:
    """A particle chain inside one world (particles ``start .. start+n-1`` from start to end)."""

    start: int
    n: int
    segment_length: float

    @property
    def count(self) -> int:
        """Number of particles."""
        return self.n

    @property
    def indices(self) -> np.ndarray:
        """World-local particle indices from the first to the last rope particle."""
        return np.arange(self.start, self.start + self.n)

    @property
    def ends(self) -> tuple[int, int]:
        """Indices of the two end particles."""
        return (self.start, self.start + self.n - 1)


@dataclass(frozen=True)
class RigidBoxHandle:
    """A rigid box made of surface particles held together by shape matching.

    Attributes:
        box: Index of the box among the world's rigid boxes (order of ``add_rigid_box`` calls).
        start: First particle index (world-local); the box owns ``start .. start+count-1``.
        count: Number of particles of the box.
        half_extents: Half extents (m) of the box in its local frame.
    """

    box: int
    start: int
    count: int
    half_extents: tuple[float, float, float]

    @property
    def indices(self) -> np.ndarray:
        """World-local particle indices of the box."""
        return np.arange(self.start, self.start + self.count)


@dataclass(frozen=True)
class StaticBox:
    """A static oriented box (table plank, block): centre (m), half extents (m), yaw (rad about z)."""

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    yaw: float = 0.0

    def rotation(self) -> np.ndarray:
        """3x3 rotation matrix (local -> world)."""
        return _rot_z(self.yaw)


@dataclass
class _Particles:
    pos: list = field(default_factory=list)
    inv_mass: list = field(default_factory=list)
    radius: list = field(default_factory=list)      # contact radius (nan = params default)
    sc_dist: list = field(default_factory=list)     # self-collision distance (nan = auto, 0 = off)
    sc_spacing: list = field(default_factory=list)  # rest spacing for the automatic distance
    obj: list = field(default_factory=list)
    rest: list = field(default_factory=list)
    box: list = field(default_factory=list)


class SceneBuilder:
    """Describes the content of ONE world (see module docstring).

    Example::

        b = SceneBuilder()
        cloth = b.add_cloth(40, 40, 0.75, 0.75, center=(0, 0, 0.1))
        b.add_static_box(center=(0.5, 0, 0.15), half_extents=(0.01, 0.6, 0.15))
        b.pin([cloth.corners[0]])
    """

    def __init__(self) -> None:
        self._p = _Particles()
        # constraint chunks: (i, j, rest, type, colour) arrays; no two constraints of one colour
        # share a particle (graph colouring for the Gauss-Seidel solver)
        self._cons: list[tuple[np.ndarray, ...]] = []
        # cloths that take bend constraints: (cloth index, particle grid, dx, dy); their span depends
        # on the engine's ``bend_reference_resolution``, so they are made at export
        self._cloth_bends: list[tuple] = []
        self._cache: dict | None = None
        self._static_boxes: list[StaticBox] = []
        self._rigid: list[dict] = []
        self._num_objects = 0
        self.cloths: list[ClothHandle] = []
        self.ropes: list[RopeHandle] = []
        self.rigid_boxes: list[RigidBoxHandle] = []

    # ------------------------------------------------------------------ queries
    @property
    def num_particles(self) -> int:
        """Number of particles in this world."""
        return len(self._p.pos)

    @property
    def static_boxes(self) -> list[StaticBox]:
        """Static boxes of this world (copy of the list)."""
        return list(self._static_boxes)

    # ------------------------------------------------------------------ helpers
    def _add_particles(self, pos: np.ndarray, inv_mass: float, radius: float | None,
                       sc_dist: float | None, sc_spacing: float, obj: int, rest: np.ndarray,
                       box: int, self_collide: bool) -> int:
        self._cache = None
        start = self.num_particles
        n = pos.shape[0]
        p = self._p
        p.pos.extend(pos.tolist())
        p.inv_mass.extend([inv_mass] * n)
        p.radius.extend([math.nan if radius is None else radius] * n)
        if not self_collide:
            sc = 0.0
        else:
            sc = math.nan if sc_dist is None else sc_dist
        p.sc_dist.extend([sc] * n)
        p.sc_spacing.extend([sc_spacing] * n)
        p.obj.extend([obj] * n)
        p.rest.extend(rest.tolist())
        p.box.extend([box] * n)
        return start

    def _add_constraints(self, ci: np.ndarray, cj: np.ndarray, rest: float, typ: int,
                         color: np.ndarray) -> None:
        ci = np.asarray(ci, np.int32)
        self._cons.append((ci, np.asarray(cj, np.int32), np.full(ci.shape, float(rest)),
                           np.full(ci.shape, typ, np.int32), np.asarray(color, np.int32)))
        self._cache = None

    def _bend_chunks(self, reference_resolution: int | None) -> list[tuple[np.ndarray, ...]]:
        """Bend constraint chunks of every cloth, spanning :func:`bend_span` particles (colours
        8-11: constraint ``i -> i + k`` gets parity ``(i // k) % 2``, so no two of one colour
        share a particle)."""
        chunks = []
        for _, grid, dx, dy in self._cloth_bends:
            k = bend_span(max(grid.shape), reference_resolution)
            rows, cols = np.indices(grid.shape)
            for f, (gi, gj, rest, par) in enumerate((
                    (grid[:, :-k], grid[:, k:], k * dx, (cols[:, :-k] // k) % 2),
                    (grid[:-k, :], grid[k:, :], k * dy, (rows[:-k, :] // k) % 2))):
                ci = gi.ravel().astype(np.int32)
                chunks.append((ci, gj.ravel().astype(np.int32), np.full(ci.shape, float(rest)),
                               np.full(ci.shape, BEND, np.int32), (8 + 2 * f + par.ravel()).astype(np.int32)))
        return chunks

    def bend_spans(self, reference_resolution: int | None = None) -> tuple[int, ...]:
        """Span (particles) of each cloth's bend constraints under ``reference_resolution``
        (``SimParams.bend_reference_resolution``); 0 for a cloth without bend constraints."""
        spans = {c[0]: bend_span(max(c[1].shape), reference_resolution) for c in self._cloth_bends}
        return tuple(spans.get(k, 0) for k in range(len(self.cloths)))

    def _new_object(self) -> int:
        self._num_objects += 1
        return self._num_objects - 1

    # ------------------------------------------------------------------ cloth
    def add_cloth(self, nx: int, ny: int, size_x: float, size_y: float,
                  center: Sequence[float] = (0.0, 0.0, 0.05), yaw: float = 0.0,
                  mass: float = 0.5, radius: float | None = None,
                  collision_distance: float | None = None, self_collision: bool = True,
                  bend: bool = True) -> ClothHandle:
        """Add a flat rectangular cloth grid parallel to the ground.

        Args:
            nx: Particles per row (local x), >= 2.
            ny: Rows (local y), >= 2.
            size_x: Side length along local x in metres (spacing ``size_x/(nx-1)``).
            size_y: Side length along local y in metres.
            center: Centre of the cloth in world coordinates (m).
            yaw: Rotation about +z in radians (local x axis -> world).
            mass: Total mass in kg, split evenly over the particles.
            radius: Contact radius against ground/boxes (m); ``None`` = ``SimParams.particle_radius``.
            collision_distance: Self-collision distance (m); ``None`` = from ``SimParams``.
            self_collision: Whether this cloth takes part in particle-particle collisions.
            bend: Add bend constraints: distance-2 ones, or for cloth finer than the engine's
                ``SimParams.bend_reference_resolution`` ones of the same length in metres.

        Returns:
            :class:`ClothHandle` with world-local indices.
        """
        if isinstance(nx, bool) or isinstance(ny, bool) or int(nx) != nx or int(ny) != ny:
            raise TypeError("nx and ny must be ints")
        nx, ny = int(nx), int(ny)
        if nx < 2 or ny < 2:
            raise ValueError(f"cloth needs at least 2x2 particles, got nx={nx}, ny={ny}")
        size_x = _positive(size_x, "size_x")
        size_y = _positive(size_y, "size_y")
        mass = _positive(mass, "mass")
        center = _vec3(center, "center")
        if not math.isfinite(float(yaw)):
            raise ValueError("yaw must be finite")
        dx, dy = size_x / (nx - 1), size_y / (ny - 1)
        jj, ii = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
        local = np.stack([ii.ravel() * dx - 0.5 * size_x, jj.ravel() * dy - 0.5 * size_y,
                          np.zeros(nx * ny)], axis=1)
        pos = local @ _rot_z(float(yaw)).T + center
        obj = self._new_object()
        start = self._add_particles(pos, nx * ny / mass, radius, collision_distance,
                                    min(dx, dy), obj, local, -1, self_collision)

        def idx(j, i):
            return start + j * nx + i

        grid = np.arange(nx * ny).reshape(ny, nx) + start
        rows = np.broadcast_to(np.arange(ny)[:, None], (ny, nx))
        cols = np.broadcast_to(np.arange(nx)[None, :], (ny, nx))
        diag = math.hypot(dx, dy)
        fams = [
            # (i-side, j-side, rest, type, parity) ; colour = 2*family + parity
            (grid[:, :-1], grid[:, 1:], dx, STRETCH, cols[:, :-1] % 2),
            (grid[:-1, :], grid[1:, :], dy, STRETCH, rows[:-1, :] % 2),
            (grid[:-1, :-1], grid[1:, 1:], diag, SHEAR, rows[:-1, :-1] % 2),
            (grid[:-1, 1:], grid[1:, :-1], diag, SHEAR, rows[:-1, 1:] % 2),
        ]
        for f, (gi, gj, rest, typ, par) in enumerate(fams):
            # colours 0-3 stretch, 4-7 shear, 8-11 bend (one constraint type per colour)
            self._add_constraints(gi.ravel(), gj.ravel(), rest, typ, 2 * f + par.ravel())
        if bend:
            self._cloth_bends.append((len(self.cloths), grid, dx, dy))
        a = (jj[:-1, :-1] * nx + ii[:-1, :-1]).ravel() + start
        b = a + 1
        c = a + nx + 1
        d = a + nx
        tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
        # interleave so that the two triangles of a cell are adjacent
        tris = tris.reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)
        h = ClothHandle(start=start, nx=nx, ny=ny, triangles=tris,
                        corners=(idx(0, 0), idx(0, nx - 1), idx(ny - 1, nx - 1), idx(ny - 1, 0)),
                        spacing=(dx, dy))
        self.cloths.append(h)
        return h

    # ------------------------------------------------------------------ rope
    def add_rope(self, n: int, length: float, start: Sequence[float] = (0.0, 0.0, 0.05),
                 direction: Sequence[float] = (1.0, 0.0, 0.0), mass: float = 0.25,
                 radius: float | None = None, collision_distance: float | None = None,
                 self_collision: bool = True, give: float = 0.0) -> RopeHandle:
        """Add a straight rope (particle chain) with stretch and bend constraints.

        Args:
            n: Number of particles (SoftGym: 41), >= 2.
            length: Rope length in metres (SoftGym: 0.5).
            start: Position of the first particle (m).
            direction: Direction of the chain (normalised internally).
            mass: Total mass in kg (SoftGym: inverse mass 2 per particle).
            radius: Contact radius (m); ``None`` = ``SimParams.particle_radius``.
            collision_distance: Self-collision distance (m); ``None`` = from ``SimParams``.
            self_collision: Whether the rope takes part in particle-particle collisions.
            give: Rest lengths are multiplied by ``1 + give`` (SoftGym: 0.075), i.e. a slack rope.
        """
        if isinstance(n, bool) or int(n) != n or int(n) < 2:
            raise ValueError(f"rope needs n >= 2 particles, got {n}")
        n = int(n)
        length = _positive(length, "length")
        mass = _positive(mass, "mass")
        start_v = _vec3(start, "start")
        d = _vec3(direction, "direction")
        norm = float(np.linalg.norm(d))
        if norm < 1e-12:
            raise ValueError("direction must be non-zero")
        d = d / norm
        if not math.isfinite(float(give)) or give <= -1.0:
            raise ValueError("give must be > -1")
        seg = length / (n - 1)
        s = np.arange(n) * seg
        pos = start_v[None, :] + s[:, None] * d[None, :]
        local = np.stack([s, np.zeros(n), np.zeros(n)], 1)
        obj = self._new_object()
        first = self._add_particles(pos, n / mass, radius, collision_distance, seg, obj, local,
                                    -1, self_collision)
        rest = seg * (1.0 + give)
        k = np.arange(n)
        self._add_constraints(first + k[:-1], first + k[1:], rest, STRETCH, k[:-1] % 2)
        self._add_constraints(first + k[:-2], first + k[2:], 2 * rest, BEND, 8 + (k[:-2] // 2) % 2)
        h = RopeHandle(start=first, n=n, segment_length=seg)
        self.ropes.append(h)
        return h

    # ------------------------------------------------------------------ boxes
    def add_static_box(self, center: Sequence[float], half_extents: Sequence[float],
                       yaw: float = 0.0) -> int:
        """Add a static oriented box (plank, block) rotated by ``yaw`` about +z.

        Returns:
            Index of the static box in this world.
        """
        c = _vec3(center, "center")
        he = _vec3(half_extents, "half_extents")
        if np.any(he <= 0):
            raise ValueError(f"half_extents must be > 0, got {he}")
        if not math.isfinite(float(yaw)):
            raise ValueError("yaw must be finite")
        self._cache = None
        self._static_boxes.append(StaticBox(tuple(map(float, c)), tuple(map(float, he)), float(yaw)))
        return len(self._static_boxes) - 1

    def add_rigid_box(self, center: Sequence[float], half_extents: Sequence[float],
                      yaw: float = 0.0, mass: float = 0.1, spacing: float = 0.03,
                      radius: float | None = None) -> RigidBoxHandle:
        """Add a dynamic rigid box made of surface particles kept rigid by shape matching.

        Its particles sit on a surface lattice (at most 6 per axis), inset by their contact
        radius so that the visible box of ``half_extents`` touches ground/other boxes.  Pickers
        grasp these particles like cloth particles; boxes collide with the ground, static
        boxes and each other; cloth/rope particles are pushed out of them (one-way).

        Args:
            center: Box centre (m).
            half_extents: Half extents (m), each > 0.
            yaw: Rotation about +z (rad).
            mass: Total mass in kg.
            spacing: Target lattice spacing (m) of the surface particles.
            radius: Particle contact radius (m); default ``min(0.005, 0.25*min(half_extents))``.
        """
        c = _vec3(center, "center")
        he = _vec3(half_extents, "half_extents")
        if np.any(he <= 0):
            raise ValueError(f"half_extents must be > 0, got {he}")
        mass = _positive(mass, "mass")
        spacing = _positive(spacing, "spacing")
        r = min(0.005, 0.25 * float(he.min())) if radius is None else _positive(radius, "radius")
        if r >= float(he.min()):
            raise ValueError("rigid box particle radius must be smaller than its half extents")
        inner = he - r
        counts = [int(min(6, max(2, math.ceil(2 * inner[a] / spacing) + 1))) for a in range(3)]
        axes = [np.linspace(-inner[a], inner[a], counts[a]) for a in range(3)]
        gx, gy, gz = np.meshgrid(*axes, indexing="ij")
        pts = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], 1)
        on_surface = np.zeros(len(pts), bool)
        for a in range(3):
            on_surface |= np.isclose(np.abs(pts[:, a]), inner[a])
        local = pts[on_surface]
        local = local - local.mean(axis=0)  # exact zero rest centroid
        pos = local @ _rot_z(float(yaw)).T + c
        box_index = len(self._rigid)
        obj = self._new_object()
        start = self._add_particles(pos, len(local) / mass, r, None, 1.0, obj, local, box_index,
                                    False)
        self._rigid.append(dict(start=start, count=len(local), center=c, half_extents=he,
                                yaw=float(yaw), mass=mass))
        h = RigidBoxHandle(box=box_index, start=start, count=len(local),
                           half_extents=tuple(map(float, he)))
        self.rigid_boxes.append(h)
        return h

    # ------------------------------------------------------------------ pins
    def pin(self, particle_indices: Sequence[int] | np.ndarray | int) -> None:
        """Pin particles (world-local indices): inverse mass 0, they never move."""
        idx = np.atleast_1d(np.asarray(particle_indices))
        if idx.size and not np.issubdtype(idx.dtype, np.integer):
            raise TypeError("particle indices must be integers")
        n = self.num_particles
        for i in idx.tolist():
            if not 0 <= i < n:
                raise IndexError(f"particle index {i} out of range [0, {n})")
            self._p.inv_mass[i] = 0.0
        self._cache = None

    # ------------------------------------------------------------------ export
    def _export(self, bend_reference_resolution: int | None = None) -> dict:
        """Flattened numpy description used by :class:`ParticleSim` (internal); the bend
        constraints follow ``bend_reference_resolution`` (``SimParams``)."""
        n = self.num_particles
        if n == 0:
            raise ValueError("SceneBuilder has no particles; add a cloth, rope or rigid box")
        p = self._p
        if self._cache is not None and bend_reference_resolution in self._cache:
            return self._cache[bend_reference_resolution]
        cons = self._cons + self._bend_chunks(bend_reference_resolution)
        if cons:
            ci, cj, cr, ct, ccol = (np.concatenate([c[k] for c in cons]) for k in range(5))
        else:
            ci = cj = ct = ccol = np.zeros(0, np.int32)
            cr = np.zeros(0, np.float64)
        order = np.argsort(ccol, kind="stable")
        ci, cj, cr, ct, ccol = ci[order], cj[order], cr[order], ct[order], ccol[order]
        if len(ci):
            # validity of the colouring: a particle appears at most once per colour
            key = np.concatenate([ccol.astype(np.int64) * n + ci, ccol.astype(np.int64) * n + cj])
            if np.unique(key).size != key.size:
                raise RuntimeError("internal error: constraint colouring is invalid")
            for c in np.unique(ccol):
                if np.unique(ct[ccol == c]).size != 1:
                    raise RuntimeError("internal error: mixed constraint types in one colour")
        boxes = self._rigid
        rot = [_rot_z(b["yaw"]) for b in boxes]
        sb = self._static_boxes
        out = dict(
            positions=np.asarray(p.pos, np.float64).reshape(n, 3),
            inv_mass=np.asarray(p.inv_mass, np.float64),
            radius=np.asarray(p.radius, np.float64),
            sc_dist=np.asarray(p.sc_dist, np.float64),
            sc_spacing=np.asarray(p.sc_spacing, np.float64),
            obj=np.asarray(p.obj, np.int32),
            rest=np.asarray(p.rest, np.float64).reshape(n, 3),
            box=np.asarray(p.box, np.int32),
            con_i=ci,
            con_j=cj,
            con_type=ct,
            con_color=ccol.astype(np.int32),
            con_rest=cr,
            rigid_start=np.array([b["start"] for b in boxes], np.int32),
            rigid_count=np.array([b["count"] for b in boxes], np.int32),
            rigid_center=np.array([b["center"] for b in boxes], np.float64).reshape(-1, 3),
            rigid_rot=np.array(rot, np.float64).reshape(-1, 3, 3),
            rigid_half_extents=np.array([b["half_extents"] for b in boxes], np.float64).reshape(-1, 3),
            static_center=np.array([s.center for s in sb], np.float64).reshape(-1, 3),
            static_half_extents=np.array([s.half_extents for s in sb], np.float64).reshape(-1, 3),
            static_rot=np.array([s.rotation() for s in sb], np.float64).reshape(-1, 3, 3),
        )
        self._cache = {**(self._cache or {}), bend_reference_resolution: out}
        return out

    def topology_key(self, bend_reference_resolution: int | None = None) -> str:
        """Hash of everything that must match across the worlds of one batch (with the bend
        constraints ``bend_reference_resolution`` gives, see :meth:`bend_spans`)."""
        e = self._export(bend_reference_resolution)
        h = hashlib.sha1()
        for k in ("obj", "box", "con_i", "con_j", "con_type", "con_color", "rigid_start",
                  "rigid_count"):
            h.update(k.encode())
            h.update(np.ascontiguousarray(e[k]).tobytes())
        h.update(str(self.num_particles).encode())
        h.update(np.isnan(e["sc_dist"]).tobytes())
        h.update((e["sc_dist"] == 0).tobytes())
        return h.hexdigest()
