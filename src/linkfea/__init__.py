"""linkfea: a link CAD to its 6x6 compliance by finite elements.

>>> import linkfea
>>> r = linkfea.compute("bar", linkfea.ComputeOptions(mesh_size=5.0))  # doctest: +SKIP
>>> r.compliance, r.stiffness, r.frame               # doctest: +SKIP
>>> r.save("bar.json"); linkfea.load("bar.json")     # doctest: +SKIP
>>> linkfea.compare("bar", "1,2,4").errors           # doctest: +SKIP
"""
# The heavy dependencies (cadquery, pytetwild, scipy.sparse, pyvista) are imported inside
# the functions that need them, so ``import linkfea`` (and ``vjm``) stays fast.
# ``linkfea.compare`` is the function; its module is ``linkfea.beam.compare``.
from .beam.compare import Comparison, compare
from .mechanics.compliance import Compliance
from .options import ComputeOptions
from .pipeline import compute
from .result.linkresult import LinkResult, load
from .runtime import checks
from .runtime.errors import LinkFeaError, SolverError

__all__ = ["Comparison", "Compliance", "ComputeOptions", "LinkFeaError", "LinkResult", "SolverError", "checks", "compare", "compute",
           "load"]


def __dir__() -> list[str]:
    # submodules imported on the way (linkfea.options, linkfea.pipeline ...) stay importable, but the
    # package's listing is its public API
    return sorted(__all__)
