"""A link result on disk: ``X.json`` with ``X.vtu`` and ``X.png`` beside it, written as one set.

The three files come from one run or are the old ones, untouched (see
:mod:`linkfea.files.outputs`).  The JSON records the name and sha256 of its
companions under ``files``, so a ``.vtu`` that is not the JSON's own (copied
over, or left by a different run) is detected when it is read
(:func:`companion_mismatch`).  An existing ``X.json`` that is not a linkfea
result, and an ``X.vtu``/``X.png`` whose sha256 the JSON beside it does not
record (the user's own, or edited since), are never overwritten or removed.
"""
from __future__ import annotations

import json
from pathlib import Path

from ..files.outputs import OutputSet, check_file, file_set_name, is_result_json, own_companions, sha256
from ..runtime.errors import LinkFeaError

SUFFIXES = {"vtu": ".vtu", "png": ".png"}


def is_result(path) -> bool:
    """Is ``path`` a result JSON written by linkfea (schema ``linkfea.result/...``)?"""
    return is_result_json(path)


def companions(path) -> dict[str, Path]:
    path = Path(path)
    return {k: path.with_suffix(s) for k, s in SUFFIXES.items()}


def check_result_out(path, vtu: bool = True, png: bool = True, option: str = "--out") -> Path:
    """Check ``--out`` of a result before any work (see :func:`linkfea.files.outputs.check_file`)."""
    if not Path(path).name:  # ".", "" (which Path reads as ".") or "/": no name to put .vtu and .png beside
        raise LinkFeaError(f"{option} {str(path)!r} is a folder, not a file: give a file name such as "
                           "out/result.json")
    comp = companions(path)
    want = [comp[k] for k, on in (("vtu", vtu), ("png", png)) if on]
    return check_file(path, is_result, "a linkfea result", companions=want, option=option,
                      own_companions=own_companions)


def write_result_set(path, res, vtu: bool = True, png: bool = True) -> list[Path]:
    """Write result ``res`` as ``path`` (JSON) with ``.vtu`` and ``.png`` beside it, as one set.

    The pictures need the FEA solution at hand; without it only the JSON is written.  Companions
    of an earlier result at ``path`` that this one does not have are removed with the commit (those
    whose bytes it recorded only), so a JSON never sits beside another run's mesh.
    """
    from ..files.atomic import plain

    path = Path(path)
    has = res.solution is not None
    vtu, png = vtu and has, png and has
    check_result_out(path, vtu, png)
    comp = companions(path)
    mine = own_companions(path) if is_result(path) else set()
    old = [c.name for k, c in comp.items() if c.name in mine and not {"vtu": vtu, "png": png}[k]]
    doc = res.to_dict()
    with OutputSet(path.parent, file_set_name(path), manifest=False, remove=old) as s:
        files = {}
        if vtu:
            from .post import write_vtu

            write_vtu(s.path(comp["vtu"].name), res)
        if png:
            from .post import write_png

            write_png(s.path(comp["png"].name), res)
        for k, c in comp.items():
            if c.name in s.tmps:
                files[k] = {"name": c.name, "sha256": sha256(s.tmps[c.name])}
        if files:
            doc["files"] = files
        with open(s.path(path.name), "w", encoding="utf-8") as fh:
            fh.write(json.dumps(plain(doc), indent=2) + "\n")
    return [path, *(comp[k] for k in files)]


def companion_mismatch(path, kind: str = "vtu") -> str | None:
    """Why the ``kind`` companion beside result ``path`` is not the JSON's own, or None if it is
    (or if the JSON records no companion: results of earlier versions)."""
    try:
        rec = json.loads(Path(path).read_text(encoding="utf-8")).get("files", {}).get(kind)
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(rec, dict) or "sha256" not in rec:
        return None
    c = Path(path).with_name(str(rec.get("name")))
    if not c.is_file():
        return f"{c} is missing"
    if sha256(c) != rec["sha256"]:
        return f"{c} is not the file written with {Path(path).name} (its sha256 differs)"
    return None


def check_companion(path, kind: str = "vtu") -> None:
    """Raise LinkFeaError if the ``kind`` companion of result ``path`` is not its own."""
    why = companion_mismatch(path, kind)
    if why is not None:
        raise LinkFeaError(f"{why}: rerun linkfea compute to write the set again")
