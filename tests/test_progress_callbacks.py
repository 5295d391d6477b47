"""Progress callbacks have one name, ``progress``, across the public API of linkfea and vjm."""
import importlib
import inspect
import pkgutil

import pytest

import linkfea
import vjm
from linkfea.sweep.budget import LineProgress

#: the public functions that run long enough to report progress, by module and attribute
ENTRY_POINTS = [
    ("linkfea", "compute"), ("linkfea", "compare"), ("linkfea.beam.compare", "fea_compliance"),
    ("linkfea.mesh", "mesh_link"), ("linkfea.fem.problem", "solve_link"), ("linkfea.sweep", "run_sweep"),
    ("linkfea.solvers.factorizers", "auto_factorizer"),
    ("vjm.toolpath.run", "path"), ("vjm.maps.compute", "grid_map"), ("vjm.maps.compute", "compute_map"),
    ("vjm.sweep.combine", "sweep"), ("vjm.sweep.combine", "trade_offs"), ("vjm.model.machine", "ParallelModel.map"),
    ("vjm.discrepancy.workflow", "diagnose"), ("vjm.discrepancy.simulate", "simulate"),
    ("vjm.discrepancy.simulate", "run"), ("vjm.stats.selection", "forward_select"),
]
#: names the same callback had before it was called ``progress`` everywhere
OLD_NAMES = ("say", "log", "report", "echo", "callback", "on_progress")


def _get(module, attr):
    obj = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


@pytest.mark.parametrize("module,attr", ENTRY_POINTS, ids=[f"{m}.{a}" for m, a in ENTRY_POINTS])
def test_entry_point_takes_progress(module, attr):
    params = inspect.signature(_get(module, attr)).parameters
    assert "progress" in params
    assert params["progress"].default in (None, False)
    assert not set(params) & set(OLD_NAMES)


def _public_functions():
    """Every public function and method defined in linkfea and vjm (modules imported one by one)."""
    for pkg in (linkfea, vjm):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if info.name.endswith("__main__"):
                continue
            mod = importlib.import_module(info.name)
            for name, obj in vars(mod).items():
                if name.startswith("_") or getattr(obj, "__module__", None) != mod.__name__:
                    continue
                if inspect.isfunction(obj):
                    yield f"{mod.__name__}.{name}", obj
                elif inspect.isclass(obj):
                    for mname, meth in vars(obj).items():
                        if inspect.isfunction(meth) and (not mname.startswith("_") or mname == "__init__"):
                            yield f"{mod.__name__}.{name}.{mname}", meth


def test_no_public_function_takes_an_old_name_for_the_callback():
    """No public function of either package has a parameter ``say``, ``log``, ``report`` ... that
    defaults to None (the shape of an optional callback; ``log: bool`` of a plot axis is no callback)."""
    found, n = [], 0
    for qual, f in _public_functions():
        n += 1
        for p in inspect.signature(f).parameters.values():
            if p.name in OLD_NAMES and p.default is None:
                found.append(f"{qual}({p.name}=None)")
    assert n > 300  # the walk saw the packages
    assert not found, found


def test_sweep_progress_as_lines():
    """A callable ``progress`` of a sweep gets one line per finished design, with the failures counted."""
    lines = []
    p = LineProgress(3, lines.append)
    p.advance()
    p.advance(ok=False)
    p.advance()
    p.stop()
    assert lines == ["designs 1/3", "designs 2/3, 1 failed", "designs 3/3, 1 failed"]


def test_path_reports_its_stages(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("x,y,z,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,10,0,0,0,0,0\n10,0,0,10,0,0,0,0,0\n")
    lines = []
    res = vjm.path("data/orthoglide/puu.yaml", f, compensate=True, progress=lines.append)
    assert lines == ["nonlinear deflection at 2 points and compensation"]  # together, pass by pass
    assert res.deflection.shape == (2, 6)
