"""The free links evaluated at given parameters: by FEA through the sweep's cache, or as closed-form beams.

A :class:`LinkSample` is one evaluated link design: its 6x6 compliance (the link's spring frame,
mm/N, rad/(N mm) by block, order Fx..Mz), its mass (kg, one piece) and its FEA error bar.

FEA designs go through :func:`linkfea.sweep.run_sweep`: each free link has its own sweep folder
``DIR/links/<link>/`` (``results/<key>.json``, keyed by the script's bytes, the parameters and the
compute options, and the sweep table), so a rerun, a larger budget or a run after Ctrl-C or SIGKILL
finds every design already computed there and runs no FEA for it.  The designs of one round (of
every link) run at the same time on one Dask cluster, started only when a design is missing.
"""
from __future__ import annotations

import hashlib
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import VjmError
from .spec import FreeLink


@dataclass(frozen=True, eq=False)
class LinkSample:
    """One evaluated design of a free link; ``ok`` False for an FEA run that failed (``error_text``)."""

    link: str
    params: dict
    key: str
    ok: bool
    compliance: np.ndarray | None = None
    mass: float = float("nan")
    error: np.ndarray | None = None
    result: str | None = None
    error_text: str = ""


def beam_key(spec: dict) -> str:
    import json

    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def beam_sample(link: FreeLink, params: dict) -> LinkSample:
    """A closed-form beam (:func:`vjm.modelio.read.beam_compliance`, the model files' ``beam:``) and its mass."""
    from linkfea.beam.closed_form import cantilever_compliance
    from linkfea.mechanics.materials import get_material
    from linkfea.runtime.errors import LinkFeaError

    from ..modelio.read import beam_section

    spec = {**link.source, **params}  # type: ignore[dict-item]
    section, E, nu, length = beam_section(spec, f"links.{link.name}.beam")
    try:
        C = cantilever_compliance(length, section, E, nu, shear=bool(spec.get("shear", True)))
    except LinkFeaError as exc:
        raise VjmError(f"links.{link.name}.beam: {exc}") from None
    try:
        rho = get_material(spec["material"]).density
    except (KeyError, LinkFeaError):
        rho = None
    if rho is None:
        raise VjmError(f"links.{link.name}.beam: give a material with a density (the objective is the mass)")
    mass = rho * section.A * length * 1000.0  # t/mm^3 * mm^3 -> kg
    return LinkSample(link.name, dict(params), beam_key(spec), True, C, mass)


def check_beam(link: FreeLink) -> None:
    """Every corner of a beam's box gives a beam (an inner diameter below the outer one ...)."""
    import itertools

    for corner in itertools.product(*(p.corners() for p in link.free)):
        params = dict(zip((p.name for p in link.free), corner))
        try:
            beam_sample(link, params)
        except VjmError as exc:
            raise VjmError(f"links.{link.name}: at the corner {_show(params)} of the bounds: {exc}") from None


def _show(params: dict) -> str:
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in params.items())


def check_cad(link: FreeLink) -> None:
    """The script has every free and fixed parameter, and builds at every corner of the bounds (CAD only)."""
    import itertools

    from linkfea.cad import build_link, load_script
    from linkfea.runtime.errors import LinkFeaError
    from linkfea.sweep.designs import script_param_names

    src = Path(str(link.source))
    known = script_param_names(src)
    try:
        if known is None:
            known = set(load_script(src).PARAMS)
        for name in [p.name for p in link.free] + list(link.fixed):
            if name not in known:
                raise VjmError(f"links.{link.name}: {src.name} has no parameter {name!r}; its parameters: "
                               f"{', '.join(sorted(known))}")
        from linkfea.options import ComputeOptions

        ComputeOptions.from_mapping(link.compute)
        for corner in itertools.product(*(p.corners() for p in link.free)):
            params = {**link.fixed, **dict(zip((p.name for p in link.free), corner))}
            try:
                build_link(str(src), params)
            except LinkFeaError as exc:
                raise VjmError(f"links.{link.name}: {src.name} does not build at the corner {_show(params)} of the "
                               f"bounds: {' '.join(str(exc).split())}") from None
    except LinkFeaError as exc:
        raise VjmError(f"links.{link.name}: {' '.join(str(exc).split())}") from None


class LinkRunner:
    """Evaluates link designs: beams at once, FEA designs from the cache or on a Dask cluster."""

    def __init__(self, out: Path, workers: int | None = None, scheduler: str | None = None):
        self.out = Path(out)
        self.workers, self.scheduler = workers, scheduler
        self.client: Any = None
        self.cluster: Any = None
        self.computed = 0  # FEA designs this run computed (not found in the cache)
        self._sweeps: dict = {}  # link -> {key: Design}: every design of the link so far (the sweep table)
        self._lock = threading.Lock()

    def folder(self, link: FreeLink) -> Path:
        return self.out / "links" / link.name

    def _sweep(self, link: FreeLink, params_list: list):
        from linkfea.options import ComputeOptions
        from linkfea.sweep.designs import Design, Sweep, design_key

        src = Path(str(link.source))
        sha = hashlib.sha256(src.read_bytes()).hexdigest()
        options = ComputeOptions.from_mapping(link.compute).key_options()
        known = self._sweeps.setdefault(link.name, {})
        keys = []
        for p in params_list:
            k = design_key(sha, p, options)
            if k not in known:
                known[k] = Design(len(known), dict(p), k)
            keys.append(k)
        names = tuple(sorted({n for d in known.values() for n in d.params}))
        return Sweep(str(src), sha, options, names, tuple(known.values()), {"method": "vjm design"}), keys

    def _client(self):
        with self._lock:
            if self.client is None:
                from distributed import Client

                from linkfea.sweep import cluster

                if self.scheduler is not None:
                    self.client = cluster.connect(self.scheduler)
                else:
                    self.cluster = cluster.local_cluster(self.workers, "auto")
                    self.client = Client(self.cluster)
            return self.client

    def _fea(self, link: FreeLink, params_list: list) -> list[LinkSample]:
        from linkfea.sweep import pending, read_design_result, run_sweep

        sweep, keys = self._sweep(link, params_list)
        folder = self.folder(link)
        todo = {d.key for d in pending(sweep, folder)}
        if todo:
            rep = run_sweep(sweep, folder, client=self._client(), plot=["dx_Fx"])
            with self._lock:
                self.computed += len(rep.computed) + len(rep.failed)
            if rep.interrupted:
                raise KeyboardInterrupt
            if rep.unfinished:
                raise VjmError(f"links.{link.name}: {len(rep.unfinished)} FEA designs did not finish (a lost Dask "
                               "worker); run again: the finished ones are kept")
        out = []
        for p, k in zip(params_list, keys):
            doc = read_design_result(folder, k)
            out.append(_sample(link, p, k, doc, folder))
        return out

    def evaluate(self, batches: dict) -> dict:
        """``{link: (FreeLink, [params ...])}`` -> ``{link: [LinkSample ...]}``; the FEA links side by side."""
        res = {name: [beam_sample(link, p) for p in ps] for name, (link, ps) in batches.items() if link.kind == "beam"}
        fea = {name: b for name, b in batches.items() if b[0].kind == "cad" and b[1]}
        if len(fea) == 1:
            name, (link, ps) = next(iter(fea.items()))
            res[name] = self._fea(link, ps)
        elif fea:
            pool = ThreadPoolExecutor(len(fea))  # one Dask client: the links' designs share the workers
            try:
                futures = {name: pool.submit(self._fea, link, ps) for name, (link, ps) in fea.items()}
                for name, f in futures.items():
                    res[name] = f.result()
            except KeyboardInterrupt:
                # Ctrl-C reaches this thread only: closing the client cancels the FEA the other threads wait on
                self.close()
                raise
            finally:
                pool.shutdown(wait=False, cancel_futures=True)
        return {name: res.get(name, []) for name in batches}

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        self.client = self.cluster = None


def _sample(link: FreeLink, params: dict, key: str, doc, folder: Path) -> LinkSample:
    if doc is None or doc.get("sweep", {}).get("status") != "ok":
        err = (doc or {}).get("sweep", {}).get("error") or "no result"
        return LinkSample(link.name, dict(params), key, False, error_text=str(err))
    from linkfea.sweep.store import result_path

    from ..model.links import linkfea_spring

    path = str(result_path(folder, key))
    spring = linkfea_spring(path, f"links.{link.name}")
    mass = doc.get("mass_kg")
    if not isinstance(mass, (int, float)) or not mass > 0:
        raise VjmError(f"links.{link.name}: {path} has no mass (its material needs a density)")
    return LinkSample(link.name, dict(params), key, True, np.asarray(spring.compliance, dtype=float), float(mass),
                      spring.error, path)
