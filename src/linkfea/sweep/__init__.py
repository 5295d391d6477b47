"""Design sweeps: many parameter sets of one link, each through the whole pipeline, on Dask.

A sweep is a list of :class:`Design` (a full grid over several ``--param`` or a
Latin hypercube sample), each identified by a key: a hash of the CAD source's
content, the design's parameters and the compute options.  Each design is one
Dask task running :func:`linkfea.pipeline.compute`; the client writes its
result to ``DIR/results/<key>.json`` (atomically) as soon as it completes, so:

* a rerun skips every design whose result is already there (resumable);
* a design that fails is recorded with its one-line error and the others go on;
* a worker that dies loses only the design it was running (Dask reruns it
  elsewhere, or a rerun of the sweep does);
* the table (``sweep.parquet``, ``sweep.csv``) and the plot (``sweep.png``)
  are rebuilt from ``results/`` at the end of every run, also after Ctrl-C,
  in the designs' enumeration order: the same whatever the number of workers.

The package's modules: :mod:`~linkfea.sweep.grammar` (``--param`` specs),
:mod:`~linkfea.sweep.designs` (designs and keys), :mod:`~linkfea.sweep.task` (one design on a
worker), :mod:`~linkfea.sweep.cluster` (the local Dask cluster), :mod:`~linkfea.sweep.store`
(``results/``), :mod:`~linkfea.sweep.runner` (a run), :mod:`~linkfea.sweep.table` and
:mod:`~linkfea.sweep.plot` (the table set); size planning and progress are in
:mod:`linkfea.sweep.budget`.  A rerun whose designs are all done starts no cluster and, when the
table set is current, rewrites nothing.

Units: compliance t = C w (mm/N, rad/(N mm), 1/N, rad/N by block) in each
link's reference frame (origin and axes in the design's JSON); stiffness N/mm
and N mm/rad; volume mm^3; mass kg; times s.
"""
from .cluster import LEAN_CLUSTER_CONFIG, local_cluster, worker_env
from .designs import KEY_VERSION, OPTION_NAMES, Design, Sweep, design_key, make_sweep, resolve_source
from .grammar import ParamSpec, parse_param_spec
from .plot import C_COLUMNS, DIAGONAL, plot_sweep
from .runner import SWEEP_FILES, SweepReport, run_sweep
from .store import pending, read_design_result, result_path
from .table import K_COLUMNS, UNITS, design_row, table_is_current, write_table
from .task import RESULT_SCHEMA_FAILED, run_design

__all__ = ["C_COLUMNS", "DIAGONAL", "K_COLUMNS", "KEY_VERSION", "LEAN_CLUSTER_CONFIG", "OPTION_NAMES",
           "RESULT_SCHEMA_FAILED", "SWEEP_FILES", "UNITS", "Design", "ParamSpec", "Sweep", "SweepReport",
           "design_key", "design_row", "local_cluster", "make_sweep", "parse_param_spec", "pending", "plot_sweep",
           "read_design_result", "resolve_source", "result_path", "run_design", "run_sweep", "table_is_current",
           "worker_env", "write_table"]
