"""The data kinds of a diagnosis, one registry: each :class:`Kind` recognises its file, reads it, names its
output files, checks the options, and runs to a :class:`~vjm.discrepancy.diagnosis.Diagnosis`.

``vjm diagnose`` and :func:`vjm.diagnose` ask :func:`find` which kind a file (or a data set in memory) is, for
a model; the kinds are asked in :data:`KINDS` order, the first that claims the file takes it.  Built in:

- :class:`RobotPoseData`: a serial or tree robot's data (``model.kind == "serial"``), always;
- :class:`PlatformPoseData`: a parallel machine's absolute poses (``<frame>.x`` columns, no wrench);
- :class:`StiffnessData`: ``x,y,z,quantity,value`` (or wide ``k_tran``/``k_rot`` columns);
- :class:`DeflectionData`: ``x,y,z,Fx..Mz,dx..rz``, the others' fallback (its reader says what a file lacks).

A new kind is a subclass of :class:`Kind` passed to :func:`register` (asked before the built-in ones);
:func:`unregister` removes it.  A kind on the stages' diagnosis only reads its file into
:class:`~vjm.discrepancy.data.Deflections` or :class:`~vjm.discrepancy.data.StiffnessObs` and names the
stages' strategy (:mod:`vjm.discrepancy.stages.kinds`) in ``stages``.
"""
from __future__ import annotations

import csv
import os
import re
import warnings

from linkfea.mechanics.compliance import WRENCH
from linkfea.runtime.checks import Bounds, integer

from ..calibration import diagnosis as absolute
from ..calibration import parallel_diagnosis as platform
from ..calibration.poses import AbsolutePoses, read_column_map
from ..effects.context import unique_postures
from ..errors import ArgumentError, VjmError
from ..modelio.read import file_kind
from ..resources import data_file
from ..stats.fit import MAX_FOLDS, check_fold_count
from .data import QUANTITIES, StiffnessObs, read_csv
from .pipeline import diagnose_stages
from .report import REPORT_FILES
from .stages.kinds import DeflectionKind, StiffnessKind
from .stages.thresholds import DEFAULT_ALPHA

#: the options only absolute poses read
POSE_OPTIONS = ("columns", "validate", "frame", "same_setup", "min_gain")
#: the options only the stages' kinds read
STAGE_OPTIONS = ("suggest", "forces_only", "noise", "max_effects")


class Kind:
    """A data kind: ``name``, the output set ``files`` (``vjm diagnose --out``), whether it writes
    ``commands.csv`` for ``--targets`` (``commands``), and the five steps below.  The stages' kinds set
    ``stages`` (their strategy) and inherit :meth:`read`, :meth:`check` and :meth:`run`."""

    name = ""
    files: tuple = REPORT_FILES
    commands = False
    stages: DeflectionKind | StiffnessKind | None = None

    def sniff(self, data, model, columns=None) -> bool:
        """Whether ``data`` (a path, or a data set read) is of this kind for ``model`` (a loaded model or a
        model file: :func:`model_kind` says which kind it is)."""
        raise NotImplementedError

    def read(self, path, model, columns=None):
        """The data set of the file ``path``."""
        return read_csv(path)

    def check(self, options: dict) -> None:
        """Refuse, before any reading, the options that mean nothing for this kind."""
        if options.get("columns") is not None or options.get("validate"):
            raise VjmError("--columns and --validate read absolute poses, the data of a serial or tree robot (a "
                           "model file with urdf: or dh:)")
        if options.get("frame"):
            raise VjmError("--frame picks measured points of absolute poses, the data of a serial or tree robot")
        if options.get("min_gain") is not None:
            raise VjmError("--min-gain is the practical threshold of an effect on absolute poses (a robot's or a "
                           "parallel machine's)")
        if options.get("folds") is not None:
            integer(options["folds"], "folds", Bounds(2, MAX_FOLDS), ArgumentError)

    def output_files(self, targets: bool = False) -> tuple:
        """The output set's files (``targets``: commands.csv too)."""
        return self.files + (("commands.csv",) if targets else ())

    def run(self, model, data, *, alpha=None, folds=None, **options):
        """The diagnosis of ``data`` (read) on ``model`` (loaded)."""
        for k in POSE_OPTIONS + ("register",):
            options.pop(k, None)
        if folds is not None:   # a fold holds out whole postures (the default 5 is cut to what the data have)
            check_fold_count(folds, len(unique_postures(data.P)[0]), "posture")
        return diagnose_stages(model, data, self.stages, DEFAULT_ALPHA if alpha is None else alpha,
                               folds=5 if folds is None else folds, name=self.name, **options)


class DeflectionData(Kind):
    """Twists measured under applied wrenches (:class:`~vjm.discrepancy.data.Deflections`)."""

    name = "deflection"
    stages = DeflectionKind()

    def sniff(self, data, model, columns=None) -> bool:
        return True   # the fallback: read_csv names the columns a file lacks


class StiffnessData(Kind):
    """k_tran / k_rot observed per posture (:class:`~vjm.discrepancy.data.StiffnessObs`)."""

    name = "stiffness"
    stages = StiffnessKind()

    def sniff(self, data, model, columns=None) -> bool:
        if isinstance(data, StiffnessObs):
            return True
        names = header(data)
        # read_csv's rule: a quantity column, or wide k_tran/k_rot columns without a wrench
        return "quantity" in names or (any(h.startswith(QUANTITIES) for h in names)
                                       and not any(c in names for c in WRENCH))


class _Poses(Kind):
    """What the two kinds of absolute poses share: the options of the stages refused, their own run."""

    module = absolute   # its check_options

    def check(self, options: dict) -> None:
        self.module.check_options(options.get("effects"), options.get("suggest", 0), options.get("forces_only", False),
                                  options.get("noise"))
        self.module.check_min_gain(options.get("min_gain"))
        if options.get("folds") is not None:
            integer(options["folds"], "folds", Bounds(0), ArgumentError)

    def run(self, model, data, *, folds=None, validate=(), **options):
        for k in STAGE_OPTIONS:
            options.pop(k, None)
        # 5 folds unless asked: the held-out gain names an effect, beside --validate files too
        return self._diagnose(model, data, folds=5 if folds is None else folds, validate=validate, **options)

    def _diagnose(self, model, data, **options):
        raise NotImplementedError


class RobotPoseData(_Poses):
    """A serial or tree robot's measured points (:class:`~vjm.calibration.poses.AbsolutePoses`), diagnosed by
    the calibration engine (:func:`vjm.calibration.diagnosis.diagnose_poses`)."""

    name = "absolute"
    files = absolute.POSE_FILES
    commands = True

    def sniff(self, data, model, columns=None) -> bool:
        return model_kind(model) == "serial"

    def read(self, path, model, columns=None):
        return absolute.read(path, model, columns)

    def _diagnose(self, model, data, **options):
        return absolute.diagnose_poses(model, data, **options)


class PlatformPoseData(_Poses):
    """A parallel machine's platform point measured at commanded actuator values
    (:func:`vjm.calibration.parallel_diagnosis.diagnose_platform_poses`)."""

    name = "platform_absolute"
    files = absolute.PLATFORM_FILES
    module = platform

    def sniff(self, data, model, columns=None) -> bool:
        if model_kind(model) != "parallel":
            return False
        if isinstance(data, AbsolutePoses):
            return True
        if columns is not None and isinstance(data, (str, os.PathLike)):
            try:
                return any(re.fullmatch(r".+\.x", k) for k in read_column_map(columns).columns)
            except VjmError:
                return False
        names = header(data)
        return any(re.fullmatch(r".+\.x", h) for h in names) and "Fx" not in names and "quantity" not in names

    def read(self, path, model, columns=None):
        return platform.read(path, model, columns)

    def _diagnose(self, model, data, frame=None, validate=(), **options):
        if frame:
            raise VjmError("--frame: a parallel machine's absolute poses measure one point, the platform's")
        return platform.diagnose_platform_poses(model, data, validate_files=validate, **options)


def model_kind(model) -> str:
    """The kind of ``model``: a loaded model's :attr:`~vjm.Model.kind`, or that of a model file, read without
    loading it (so that ``vjm diagnose`` checks its output folder before any work)."""
    return file_kind(model) if isinstance(model, (str, os.PathLike)) else model.kind


def header(data) -> set:
    """The column names of a CSV file's header (the first row not a comment, at most 64 kB read; a bundled
    name resolved as the readers resolve it, :func:`vjm.resources.data_file`); empty when ``data`` is no
    readable file (its reader then says why; a device such as /dev/zero is never read)."""
    if not isinstance(data, (str, os.PathLike)):
        return set()
    with warnings.catch_warnings():   # the reader warns once, when it reads
        warnings.simplefilter("ignore")
        try:
            data = data_file(data)   # a bundled name ("seed_table1.csv") as the reader resolves it
        except VjmError:
            return set()
    if not os.path.isfile(data):
        return set()
    try:
        with open(data, newline="", encoding="utf-8-sig") as f:
            head = f.read(1 << 16)
    except (OSError, UnicodeDecodeError):
        return set()
    row = next((r for r in csv.reader(head.splitlines()) if r and not r[0].startswith("#")), [])
    return {h.strip() for h in row}


#: the data kinds, asked in this order (the first whose sniff claims a file takes it)
KINDS: list[Kind] = [RobotPoseData(), PlatformPoseData(), StiffnessData(), DeflectionData()]


def register(kind: Kind) -> Kind:
    """Add a data kind, asked before those already registered (a name already taken is refused)."""
    if any(k.name == kind.name for k in KINDS):
        raise VjmError(f"data kind {kind.name!r} is registered already")
    KINDS.insert(0, kind)
    return kind


def unregister(name: str) -> None:
    """Remove the data kind ``name``."""
    KINDS[:] = [k for k in KINDS if k.name != name]


def get(name: str) -> Kind:
    """The registered data kind ``name``."""
    for k in KINDS:
        if k.name == name:
            return k
    raise VjmError(f"no data kind {name!r}; kinds: {', '.join(k.name for k in KINDS)}")


def find(data, model, columns=None) -> Kind:
    """The kind of ``data`` (a path, or a data set read) for ``model``: the first of :data:`KINDS` to claim it."""
    for k in KINDS:
        if k.sniff(data, model, columns):
            return k
    raise VjmError(f"{data}: no data kind reads this file")
