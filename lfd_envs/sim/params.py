"""Simulation parameters of the particle engine.

All quantities are SI (metres, seconds, kilograms); the world is z-up with the
table top / ground plane at ``z = 0``.

The constraint solver is position based (PBD, the FleX convention): every
constraint type has a *stiffness* in ``[0, 1]``, the fraction of the constraint
error removed each time the constraint is projected (once per solver iteration
from each of its two particles).  ``1.0`` is as stiff as the iteration count
allows; the FleX/SoftGym cloth used ``(stretch, bend, shear) = (0.8, 1.0, 0.9)``
with 4 substeps x 30 iterations.  Because our defaults use far fewer iterations
per frame than FleX did, the default stretch stiffness is 1.0 so that a hanging
cloth stretches less than 10 % (the SoftGym cloth was criticised as too
stretchy).  The equivalent XPBD compliance of a PBD stiffness ``k`` with ``n``
iterations per substep of length ``h`` is roughly ``alpha = h**2 (1/k_n - 1)``
with ``k_n = 1 - (1 - k)**n``; we keep the PBD form because it is what the
reference parameters are expressed in.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

__all__ = ["SimParams", "GRASP_MODES", "GRASP_TRIGGERS", "bend_span", "effective_substeps"]


def effective_substeps(substeps: int, reference_resolution: int | None, resolution: int) -> int:
    """Substeps for a cloth of ``resolution`` particles per side when ``substeps`` suit one of
    ``reference_resolution`` (``None``: no scaling); never fewer than ``substeps``."""
    if reference_resolution is None or resolution <= reference_resolution:
        return substeps
    return max(substeps, math.ceil(substeps * (resolution / reference_resolution) ** 1.5 - 1e-9))


def bend_span(resolution: int, reference_resolution: int | None) -> int:
    """Grid distance (particles) spanned by the bend constraints of a cloth with ``resolution``
    particles along its longer side: 2, or for a cloth finer than ``reference_resolution`` the
    span of the same length in metres as the reference's two spacings (4 at 80 per side
    against 40)."""
    if reference_resolution is None or resolution <= reference_resolution:
        return 2
    return max(2, round(2 * resolution / reference_resolution))

#: upper bounds of the count parameters (each is linear in a step's time or the engine's memory;
#: the tasks use at most 57 substeps, 5 iterations and 16 neighbours)
MAX_COUNTS = {"substeps": 1000, "iterations": 1000, "max_neighbors": 256, "collision_passes": 100,
              "release_relaxation": 10_000}
#: upper bound (m) of the radii (a picker or particle larger than the scene has no meaning)
MAX_LENGTH = 1.0

GRASP_MODES = ("closest", "radius")
GRASP_TRIGGERS = ("level", "edge")


@dataclass(frozen=True)
class SimParams:
    """Parameters of :class:`~lfd_envs.sim.ParticleSim` (immutable; use ``dataclasses.replace``).

    Attributes:
        frame_dt: Duration of one :meth:`ParticleSim.step` call in seconds (FleX: 0.01 s).
        substeps: Substeps per frame; each substep has ``frame_dt / substeps`` seconds.
        iterations: Gauss-Seidel solver iterations per substep.
        substeps_reference_resolution: Resolution-aware substeps.  ``None`` (default) runs
            ``substeps`` whatever the cloth.  Given ``n_ref``, ``substeps`` are those of a cloth of
            ``n_ref`` particles per side, and a scene whose finest cloth has ``n > n_ref``
            particles along a side runs ``ceil(substeps x (n / n_ref) ** 1.5)`` substeps
            (:func:`effective_substeps`): a solver of a few iterations per substep leaves a
            stretch error that grows with the length of the particle chains it carries
            (hung from two corners for 2.5 s at 20 substeps, a 0.6 m cloth stretches 5.3 % at
            its worst edge with 40 particles per side and 38 % with 80;
            ``python -m tools.cloth_stretch``), and the ``1.5`` power keeps that error at
            the reference cloth's.  :class:`~lfd_envs.sim.ParticleSim` applies it
            (:meth:`for_resolution`); ``sim.substeps`` gives the substeps it runs.
        gravity: Gravitational acceleration along +z in m/s^2 (negative: downwards).
        particle_radius: Default contact radius (m) of cloth/rope particles against the
            ground and static/rigid boxes; a resting cloth lies at ``z = particle_radius``
            above the surface.  Also the default picker-threshold particle radius.
        self_collision: Enable particle-particle collisions (cloth/rope self and mutual
            collisions; rigid box particles use box-box contacts instead).
        self_collision_distance: Minimum distance (m) between two colliding particles.
            ``None`` (default) picks ``self_collision_spacing_factor`` x the rest spacing of
            each cloth/rope, which keeps particles of one layer from slipping through the
            grid cells of another.
        self_collision_spacing_factor: See ``self_collision_distance`` (dimensionless).
        self_collision_margin: Extra search radius for the neighbour lists, as a fraction
            of the collision distance (dimensionless).
        self_collision_interval: Rebuild the self-collision neighbour lists every this many
            substeps (1 = every substep, most robust).
        max_neighbors: Maximum self-collision neighbours kept per particle (closest first).
        self_collision_relaxation: Over-relaxation of the Jacobi self-collision response
            (1 = each particle of a pair removes its mass share of the overlap; in [1, 2)).
        collision_passes: Extra contact/self-collision passes after the last solver iteration
            of every substep (keeps layers of folded cloth apart; 0 disables).
        stretch_stiffness: PBD stiffness in [0, 1] of the stretch constraints (grid
            neighbours / rope segments).
        shear_stiffness: PBD stiffness in [0, 1] of the cloth diagonal constraints.
        bend_stiffness: PBD stiffness in [0, 1] of the distance-2 bend constraints (at particle
            spacings up to ``bend_reference_spacing``).
        stretch_compliance, shear_compliance, bend_compliance: XPBD compliance (Macklin et
            al. 2016) of each constraint type, in m/N (the inverse stiffness of one distance
            constraint; 0 = rigid).  ``None`` (default) projects that type with its PBD
            ``*_stiffness`` instead.  Unlike a PBD stiffness, a compliance gives the same
            material whatever ``substeps`` and ``iterations`` are, so "small steps" settings
            (many substeps of one iteration, which converge far better per unit of work) keep
            the cloth's bending; the resolution-aware factor of the bend constraints divides it.
        bend_reference_spacing: Resolution-aware bending.  A distance-2 bend constraint spans two
            particle spacings, so on a coarse grid it resists a fold over a long stretch of cloth
            (at 15 particles per 0.75 m side it spans 11 cm and a fold springs back open).  Bend
            constraints of a grid with spacing ``dx`` larger than this reference (m) get the
            stiffness ``bend_stiffness x (bend_reference_spacing / dx) ** bend_spacing_exponent``,
            so the cloth bends about as easily per metre as at the reference resolution
            (default 0.02 m: a 0.75 m cloth of 40 x 40 particles, unchanged).  ``None`` disables.
        bend_spacing_exponent: Exponent of the bend stiffness scaling (dimensionless, >= 0).
        bend_reference_resolution: Resolution-aware bending.  ``None`` (default) leaves the
            bend and shear constraints as above.  Given ``n_ref``, the bend constraints of a
            cloth with ``n < n_ref`` particles along its longer side get their stiffness
            multiplied by ``(n / n_ref) ** bend_resolution_exponent`` (on top of the spacing
            rule) and its shear constraints by ``(n / n_ref) ** shear_resolution_exponent``.  A solver of one iteration per substep converges further on the short
            particle chains of a coarse grid, so the same PBD stiffness bends less: at 20
            particles per side a folded cloth springs back open after the release (ClothFold's
            two-picker fold on eval variant 1: p-hat 0.43 after the fold, -0.09 two idle steps
            later), while the same particle spacing folds flat at 40 per side on a cloth twice
            the size.  The shear constraints (cell diagonals) span every crease that runs along
            a cell diagonal: at 20 per side the diagonal fold's top layer ended 8.3 cm above the
            table on average (2.0 cm at 40).  A cloth with ``n > n_ref`` gets bend constraints
            of the same length in metres as the reference's instead of distance-2 ones
            (spanning :func:`bend_span` particles: 4 at 80 against 40), with their stiffness
            multiplied by the substeps at the reference over the substeps that run (20 / 57 at
            80 with ``substeps_reference_resolution``), so each frame projects them about as
            much as at the reference.  Distance-2 constraints on fine cloth resist only bends
            over a few millimetres: hung over DryCloth's plank by one edge, an 80 x 80 cloth
            bunched along the plank (spread error 0.242 m against 0.003 with the rule).  The
            span is part of the scene's constraint layout, so it is fixed when the simulator is
            built.
        bend_resolution_exponent: Exponent of that scaling of the bend constraints
            (dimensionless, >= 0).
        shear_resolution_exponent: Exponent of that scaling of the shear constraints
            (dimensionless, >= 0).  Softer shear lets a coarse cloth crease along a diagonal,
            but also lets it narrow where it hangs and relax further when a grasp lets go: 2
            (default) keeps a released 20 x 20 cloth under 5 mm per frame (3: 9.8 mm; see
            ``docs/particle_tasks.md``).
        tethers: Long-range attachments (Kim et al. 2012): each free cloth/rope particle may
            not get farther from the nearest (in rest space) pinned or grasped particle of its
            object than their rest distance x (1 + ``tether_slack``).  Removes the "stretchy
            cloth" artefact of few-iteration PBD at no visible cost.
        tether_slack: Allowed relative over-length of the tethers (dimensionless, >= 0).
        static_friction: Coulomb static friction coefficient against ground and boxes.
        dynamic_friction: Coulomb dynamic friction coefficient against ground and boxes
            (FleX cloth: 0.75).
        damping: Viscous velocity damping in 1/s (FleX cloth: 1.0); ``v *= 1 - damping*h``.
        max_speed: Particle speed clamp in m/s (the maximum picker speed is 8 m/s).
        picker_radius: Radius (m) of a picker sphere (rendering, and contact with
            ``picker_collision``; SoftGym cloth: 0.05).
        picker_collision: Pickers are sphere colliders of ``picker_radius`` that push free
            particles (cloth, rope, the particles of rigid boxes, so boxes too) out of them, as
            FleX's picker shapes do; what a picker holds is not pushed.  These contacts are
            inelastic: along the push, what a picker pushes is carried at the picker's speed
            instead of gaining push / substep (a particle squeezed against the table or left
            inside a picker by a release is not shot away).  Off by default: the scripted
            experts and the committed ``-v0`` results are tuned and measured without it, and
            pick-and-place moves empty pickers up to 2 m per frame, which would sweep the
            cloth.  Delta actions move pickers at most 1 cm per frame, far less than a
            picker's diameter per substep, so the sphere cannot pass through a particle.
        grasp_mode: ``"closest"`` attaches the single closest free particle within
            ``grasp_radius`` (SoftGym); ``"radius"`` attaches all free particles within it.
        grasp_trigger: When a picker tries to grasp.  ``"level"`` (SoftGym/FleX): in every
            frame in which its grasp flag is on and it holds nothing, so a picker lowered onto
            the cloth with the flag already on grasps once it is close enough.  ``"edge"``: only
            in the frame where the flag turns on (a grasp that misses stays empty until the flag
            is switched off and on again).
        grasp_radius: Grasp distance from the picker centre in metres (SoftGym cloth:
            picker_threshold + picker_radius + particle_radius = 0.06125).
        rigid_weight_kinematic: Shape-matching weight of a grasped/pinned rigid-box particle
            relative to a free one (dimensionless, >= 1).
        particle_static_friction: Coulomb static friction coefficient of particle-particle
            (self-collision) contacts, e.g. cloth on cloth.  Position based (Macklin et al.
            2014): in every self-collision projection the tangential displacement of the pair
            relative to each other during the substep is removed entirely while it is below
            ``particle_static_friction x penetration`` (the layers stick), else reduced by
            ``particle_dynamic_friction x penetration`` (they slide).  0 disables.
        particle_dynamic_friction: Coulomb dynamic friction coefficient of particle-particle
            contacts (see ``particle_static_friction``).
        release_relaxation: Position-only solver iterations run on the worlds where a picker
            releases (at the start of that frame, after the release).  A held particle is
            kinematic, so the constraint error around it (stretch of the cloth it carries, a
            particle pressed into a lower layer) is not resolved while it is held; projected
            in the next substep it would become a velocity ``error / substep_dt`` (a kick of
            1-2 m/s).  The relaxation moves the particles (constraints, collisions, friction)
            without changing their velocities.  0 disables.
    """

    frame_dt: float = 0.01
    substeps: int = 2
    iterations: int = 5
    substeps_reference_resolution: int | None = None
    gravity: float = -9.81
    particle_radius: float = 0.00625
    self_collision: bool = True
    self_collision_distance: float | None = None
    self_collision_spacing_factor: float = 0.75
    self_collision_margin: float = 0.25
    self_collision_interval: int = 1
    max_neighbors: int = 16
    self_collision_relaxation: float = 1.0
    collision_passes: int = 1
    stretch_stiffness: float = 1.0
    shear_stiffness: float = 0.9
    bend_stiffness: float = 1.0
    stretch_compliance: float | None = None
    shear_compliance: float | None = None
    bend_compliance: float | None = None
    tethers: bool = True
    tether_slack: float = 0.02
    static_friction: float = 0.8
    dynamic_friction: float = 0.75
    damping: float = 1.0
    max_speed: float = 10.0
    picker_radius: float = 0.05
    picker_collision: bool = False
    grasp_mode: str = "closest"
    grasp_trigger: str = "level"
    grasp_radius: float = 0.06125
    rigid_weight_kinematic: float = 1000.0
    particle_static_friction: float = 0.5
    particle_dynamic_friction: float = 0.4
    release_relaxation: int = 50
    bend_reference_spacing: float | None = 0.02
    bend_spacing_exponent: float = 2.0
    bend_reference_resolution: int | None = None
    bend_resolution_exponent: float = 4.0
    shear_resolution_exponent: float = 2.0

    def __post_init__(self) -> None:
        def _finite(name: str) -> float:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"SimParams.{name} must be a number, got {type(value).__name__}")
            if not math.isfinite(value):
                raise ValueError(f"SimParams.{name} must be finite, got {value}")
            return float(value)

        def _int(name: str, low: int) -> None:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"SimParams.{name} must be an int, got {type(value).__name__}")
            if value < low:
                raise ValueError(f"SimParams.{name} must be >= {low}, got {value}")
            high = MAX_COUNTS.get(name)
            if high is not None and value > high:
                raise ValueError(f"SimParams.{name} must be <= {high} (larger values make a step take "
                                 f"minutes or exhaust memory), got {value}")

        for name in ("frame_dt", "particle_radius", "max_speed", "grasp_radius"):
            if _finite(name) <= 0.0:
                raise ValueError(f"SimParams.{name} must be > 0, got {getattr(self, name)}")
        for name in ("self_collision_spacing_factor",):
            if _finite(name) <= 0.0:
                raise ValueError(f"SimParams.{name} must be > 0, got {getattr(self, name)}")
        for name in ("picker_radius", "damping", "static_friction", "dynamic_friction",
                     "self_collision_margin", "tether_slack", "particle_static_friction",
                     "particle_dynamic_friction"):
            if _finite(name) < 0.0:
                raise ValueError(f"SimParams.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("particle_radius", "picker_radius", "grasp_radius"):
            if getattr(self, name) > MAX_LENGTH:
                raise ValueError(f"SimParams.{name} must be <= {MAX_LENGTH} m (the scenes are about 1 m "
                                 f"across), got {getattr(self, name)}")
        _finite("gravity")
        for name in ("stretch_stiffness", "shear_stiffness", "bend_stiffness"):
            v = _finite(name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"SimParams.{name} is a PBD stiffness and must lie in [0, 1], got {v}")
        if _finite("rigid_weight_kinematic") < 1.0:
            raise ValueError("SimParams.rigid_weight_kinematic must be >= 1")
        _int("substeps", 1)
        _int("iterations", 1)
        _int("self_collision_interval", 1)
        _int("max_neighbors", 1)
        if self.substeps_reference_resolution is not None:
            _int("substeps_reference_resolution", 2)
        _int("collision_passes", 0)
        _int("release_relaxation", 0)
        if not 1.0 <= _finite("self_collision_relaxation") < 2.0:
            raise ValueError("SimParams.self_collision_relaxation must lie in [1, 2)")
        for name in ("self_collision", "tethers", "picker_collision"):
            if not isinstance(getattr(self, name), bool):
                raise TypeError(f"SimParams.{name} must be a bool")
        if self.self_collision_distance is not None:
            if _finite("self_collision_distance") <= 0.0:
                raise ValueError("SimParams.self_collision_distance must be > 0 or None")
        for name in ("stretch_compliance", "shear_compliance", "bend_compliance"):
            if getattr(self, name) is not None and _finite(name) < 0.0:
                raise ValueError(f"SimParams.{name} must be >= 0 or None, got {getattr(self, name)}")
        if self.bend_reference_spacing is not None and _finite("bend_reference_spacing") <= 0.0:
            raise ValueError("SimParams.bend_reference_spacing must be > 0 or None")
        if _finite("bend_spacing_exponent") < 0.0:
            raise ValueError("SimParams.bend_spacing_exponent must be >= 0")
        if self.bend_reference_resolution is not None:
            _int("bend_reference_resolution", 2)
        if _finite("bend_resolution_exponent") < 0.0:
            raise ValueError("SimParams.bend_resolution_exponent must be >= 0")
        if _finite("shear_resolution_exponent") < 0.0:
            raise ValueError("SimParams.shear_resolution_exponent must be >= 0")
        if self.grasp_trigger not in GRASP_TRIGGERS:
            raise ValueError(f"SimParams.grasp_trigger must be one of {GRASP_TRIGGERS}, got {self.grasp_trigger!r}")
        if self.grasp_mode not in GRASP_MODES:
            raise ValueError(f"SimParams.grasp_mode must be one of {GRASP_MODES}, got {self.grasp_mode!r}")

    def for_resolution(self, resolution: int) -> "SimParams":
        """These params for a scene whose finest cloth has ``resolution`` particles along a side:
        ``substeps`` raised as ``substeps_reference_resolution`` says (see there) and the
        reference cleared, so applying it again changes nothing; unchanged without a reference."""
        if self.substeps_reference_resolution is None:
            return self
        substeps = effective_substeps(self.substeps, self.substeps_reference_resolution, resolution)
        return replace(self, substeps=substeps, substeps_reference_resolution=None)

    @property
    def substep_dt(self) -> float:
        """Duration of one substep in seconds."""
        return self.frame_dt / self.substeps

    def to_dict(self) -> dict:
        """Plain-dict view (for logging / configs)."""
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """Names of all parameters."""
        return tuple(f.name for f in fields(cls))
