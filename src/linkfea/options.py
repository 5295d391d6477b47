"""The options of one link computation, as one frozen value checked once.

:class:`ComputeOptions` is what :func:`linkfea.compute`, ``linkfea compute``, ``linkfea sweep``
(and its design keys) take.  Every option is checked when the value is made, against the
ranges stated here, before any CAD or mesh work: the solver and mesh stages trust it.

The block ratio ``E_block / E`` must be > 1: the pseudo-rigid block is stiffer than the link
(1 would be the link's own material, below 1 a soft pad).  :func:`linkfea.fem.problem.solve_link`
checks the same :data:`BLOCK_RATIO`.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

from .runtime import checks
from .runtime.errors import LinkFeaError

#: valid ranges of the numeric options
MESH_SIZE = checks.Bounds(0, lo_open=True, unit="mm")
BLOCK_RATIO = checks.Bounds(1, lo_open=True)
ENVELOPE = checks.Bounds(0, 0.1, lo_open=True, hi_open=True)
TOLERANCE = checks.Bounds(0, 1, lo_open=True, hi_open=True, unit="(a fraction: 0.01 = 1%)")
MAX_DOFS_BOUNDS = checks.Bounds(1)

MODES = ("rigid", "block")
ASSEMBLERS = ("kernel", "skfem")
MESHERS = ("gmsh", "pytetwild")
SOLVERS = ("auto", "direct", "iterative")

MAX_DOFS = 1_000_000
"""Default DOF budget of ``tolerance``: the refinement stops before a mesh would pass it."""

#: the options ``linkfea sweep`` takes
SWEEP_OPTIONS = ("mesh_size", "mode", "block_ratio", "material", "base", "tip", "envelope", "convergence", "mesher")


def _one_of(value, name: str, known) -> str:
    if value not in known:
        raise LinkFeaError(f"unknown {name} {value!r}; use {', '.join(known[:-1])} or {known[-1]}")
    return value


@dataclass(frozen=True)
class ComputeOptions:
    """How a link is computed (see :func:`linkfea.compute` for each option's meaning).

    ``envelope`` None is the mesher's default (:data:`linkfea.mesh.DEFAULT_EPSILON`), ``mesher``
    None the default of the input (gmsh for scripts and STEP, pytetwild for surfaces).
    Made with bad values, it raises :class:`linkfea.runtime.errors.LinkFeaError` naming the option.
    """

    mesh_size: float | None = None
    mode: str = "rigid"
    block_ratio: float = 1000.0
    material: str | None = None
    base: object = None
    tip: object = None
    envelope: float | None = None
    convergence: bool = False
    mesher: str | None = None
    assembler: str = "kernel"
    solver: str = "auto"
    tolerance: float | None = None
    max_dofs: int = MAX_DOFS

    def __post_init__(self):
        def put(name, value):
            object.__setattr__(self, name, value)

        put("mesh_size", checks.optional_number(self.mesh_size, "mesh_size", MESH_SIZE))
        put("block_ratio", checks.number(self.block_ratio, "block_ratio", BLOCK_RATIO))
        put("envelope", checks.optional_number(self.envelope, "envelope", ENVELOPE))
        _one_of(self.mode, "mode", MODES)
        _one_of(self.assembler, "assembler", ASSEMBLERS)
        _one_of(self.solver, "solver", SOLVERS)
        if self.mesher is not None:
            _one_of(self.mesher, "mesher", MESHERS)
        put("convergence", bool(self.convergence))
        put("max_dofs", checks.integer(self.max_dofs, "max_dofs", MAX_DOFS_BOUNDS))
        put("tolerance", checks.optional_number(self.tolerance, "tolerance", TOLERANCE))
        if self.tolerance is not None:
            if self.convergence:
                raise LinkFeaError("--tolerance and --convergence do not go together: choose one")
            if self.mesher not in (None, "gmsh"):
                raise LinkFeaError("--tolerance refines with gmsh's local sizes: use --mesher gmsh")

    @classmethod
    def from_mapping(cls, options: dict | None) -> "ComputeOptions":
        """From a dict of options; None entries take the defaults, an unknown name is an error."""
        given = {k: v for k, v in (options or {}).items() if v is not None}
        known = {f.name for f in fields(cls)}
        bad = sorted(set(given) - known)
        if bad:
            raise LinkFeaError(f"unknown compute options {bad}")
        return cls(**given)

    def for_input(self, spec) -> "ComputeOptions":
        """With ``mesher`` resolved for ``spec`` (pytetwild for STL/OBJ/PLY surfaces, else gmsh)."""
        from dataclasses import replace

        if self.mesher is not None:
            return self
        from .cad.surface import is_surface

        return replace(self, mesher="pytetwild" if is_surface(spec) else "gmsh")

    def key_options(self) -> dict:
        """The options that name a sweep design, as its key spells them.

        The mode always, the block ratio in block mode only, every other option when it differs
        from its default: the keys of designs made before this value existed stay the same.
        """
        out: dict = {"mode": self.mode}
        if self.mode == "block":
            out["block_ratio"] = self.block_ratio
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name not in ("mode", "block_ratio") and v != f.default:
                out[f.name] = v
        return out
