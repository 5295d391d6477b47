"""Robot model files: the YAML beside a URDF (``urdf: robot.urdf``) or with a DH table (``dh:``), or in another
format of the registry :mod:`vjm.modelio.robotformats`, whose reader gives the kinematic tree.

Units N, mm, kg, rad (the URDF's metres are converted where it is read)::

    name: UR10
    urdf: ur10.urdf                 # relative to this file; or dh: {...} (vjm.modelio.dh)
    tools: [tool0]                  # optional: the tool frames (default: tool0, else the deepest childless link)
    gravity: [0, 0, -9.80665]       # optional, m/s^2 in the base frame (a wall or ceiling mount turns it)
    strict_limits: false            # optional: a q outside a joint's limits is an error, not a warning
    home: [0, -1.2, 1.5, -1.87, -1.57, 0]   # optional: the working configuration (rad, mm), vjm path's seed
    joints:                         # optional: a joint not named here is rigid
      shoulder_pan_joint: {stiffness: 2.0e9}                 # N mm/rad (N/mm for a prismatic joint)
      lift: {stiffness: "2e4 * (1 - q / 2000)"}              # an expression of the joint's value q
      elbow_joint: {stiffness: {table: [[-3, 1.5e9], [3, 1.1e9]]}}   # (q, stiffness) rows, interpolated
      wrist_1_joint: {stiffness: 4.0e8, spring6: {compliance: [[...], ...]}}  # + a 6x6 spring (a <link>)
    links:                          # optional link springs: <link> entries of vjm's model files, placed
      upper_arm:                    # at a frame of the tree (a URDF link or fixed joint, a DH linkN)
        at: upper_arm_link
        xyz: [0, 0, 612]            # optional offset in that frame, mm, and rpy (rad)
        beam: {section: tube, diameter: 120, inner_diameter: 100, length: 612, material: aluminium}
    masses:                         # optional point masses (kg, centre of mass mm in the frame)
      upper_arm_link: {mass: 1.5, com: [0, 0, 300]}
      forearm_link: {linkfea: forearm.json, com: [0, 0, 280]}   # the mass a linkfea result states
    payload: {frame: tool0, mass: 5.0, com: [0, 0, 50]}    # optional
    payload_limit: 10.0             # optional: the rated load (kg), the bound of a calibrated payload mass

A URDF alone (no ``joints:``) is a valid, rigid model: kinematics and gravity work, its stiffness
is infinite (C = 0).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import VjmError
from ..robot.model import GRAVITY, MAX_MASS, MIN_STIFFNESS, JointSpring, Payload, PlacedSpring, RobotModel
from ..robot.tree import Body, Tree, origin_transform
from . import robotformats

#: a robot's plausible size (mm): its frames at zero joint values within this of the base (100 m), and
#: reaching at least this far if they reach at all (5 mm); beyond, its lengths are in other units
MAX_SIZE_MM = 1e5
MIN_SIZE_MM = 5.0
#: the keys of a robot file besides its format's (``urdf:``, ``dh:`` ...: :mod:`vjm.modelio.robotformats`)
COMMON_KEYS = ("tools", "gravity", "strict_limits", "home", "joints", "links", "masses", "payload",
               "payload_limit")


def robot_keys() -> tuple[str, ...]:
    """The top-level keys a robot model file may have."""
    return ("name",) + robotformats.format_keys() + COMMON_KEYS


def _num(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise VjmError(f"{where} must be a finite number, got {v!r}")
    return float(v)


def _vec3(v, where: str) -> np.ndarray:
    if not isinstance(v, list) or len(v) != 3:
        raise VjmError(f"{where} must be 3 numbers, got {v!r}")
    return np.array([_num(x, where) for x in v])


def _joint_spring(spec, where: str) -> JointSpring:
    if isinstance(spec, str):
        from .description import evaluate

        k0 = evaluate(spec, {"q": 0.0}, where)  # read once now: a typo fails at load, not in a map
        _at_least(k0, f"{where} at q = 0")
        return JointSpring(expression=spec)
    if isinstance(spec, dict):
        if set(spec) != {"table"}:
            raise VjmError(f"{where} must be a number, an expression of q or {{table: [[q, stiffness], ...]}}")
        rows = spec["table"]
        if not isinstance(rows, list) or len(rows) < 2 or not all(isinstance(r, list) and len(r) == 2 for r in rows):
            raise VjmError(f"{where}.table must be at least two [q, stiffness] rows")
        t = np.array([[_num(a, f"{where}.table"), _num(b, f"{where}.table")] for a, b in rows])
        if np.any(np.diff(t[:, 0]) <= 0):
            raise VjmError(f"{where}.table: the q values must increase")
        for k in t[:, 1]:
            _at_least(k, f"{where}.table")
        return JointSpring(table=(t[:, 0].copy(), t[:, 1].copy()))
    k = _num(spec, where)
    _at_least(k, where)
    return JointSpring(stiffness=k)


def _at_least(k: float, where: str) -> None:
    if not k >= MIN_STIFFNESS:
        raise VjmError(f"{where} must be at least {MIN_STIFFNESS:g} N mm/rad (N/mm for a prismatic joint), got {k:g}")


def _mass(v, where: str) -> float:
    m = _num(v, where)
    if not 0 <= m <= MAX_MASS:
        raise VjmError(f"{where} must be in [0, {MAX_MASS:g}] kg, got {m:g}")
    return m


def check_size(tree: Tree, where: str) -> None:
    """Refuse a robot larger than :data:`MAX_SIZE_MM` or smaller than :data:`MIN_SIZE_MM` (a URDF written in
    millimetres, a DH table in metres): its size the longest path of offsets from the base to a frame."""
    reach = np.zeros(len(tree.joints))  # the length of the path of offsets from the base: a bound of the reach
    for i, j in enumerate(tree.joints):  # a joint's parent comes before it
        reach[i] = (reach[j.parent] if j.parent >= 0 else 0.0) + float(np.linalg.norm(j.placement[:3, 3]))
    far = [(reach[f.joint] if f.joint >= 0 else 0.0) + float(np.linalg.norm(f.placement[:3, 3])) for f in tree.frames]
    size = max(far + list(reach) + [0.0])
    heavy = [b for b in tree.bodies if not b.mass <= MAX_MASS]
    if heavy:
        raise VjmError(f"{where}: body {heavy[0].name!r} has a mass of {heavy[0].mass:g} kg, above {MAX_MASS:g} kg (100 t)")
    if size > MAX_SIZE_MM:
        raise VjmError(f"{where}: the robot's links add up to {size / 1000:.4g} m from its base to a frame, "
                       f"beyond {MAX_SIZE_MM / 1000:g} m: lengths in millimetres where metres are meant (a URDF is in m)?")
    if 0 < size < MIN_SIZE_MM:
        raise VjmError(f"{where}: the robot's links add up to {size:.3g} mm from its base to its farthest frame, below "
                       f"{MIN_SIZE_MM:g} mm: "
                       f"lengths in metres where millimetres are meant (a DH table is in mm)?")


def _joints(d, base_dir: str, tree: Tree, parse_link):
    if not isinstance(d, dict):
        raise VjmError("joints must be a mapping joint name -> {stiffness: ..., spring6: <link>}")
    names = [j.name for j in tree.joints]
    springs, six = {}, {}
    for name, spec in d.items():
        where = f"joints.{name}"
        if name not in names:
            raise VjmError(f"{where}: {tree.source} has no joint {name!r}; its joints: {', '.join(names)}")
        if not isinstance(spec, dict) or not spec or set(spec) - {"stiffness", "spring6"}:
            raise VjmError(f"{where} must be a mapping with stiffness and/or spring6")
        if "stiffness" in spec:
            springs[name] = _joint_spring(spec["stiffness"], f"{where}.stiffness")
        if "spring6" in spec:
            six[name] = parse_link(spec["spring6"], f"{where}.spring6", base_dir).checked(f"{where}.spring6")
    return springs, six


def _links(d, base_dir: str, tree: Tree, parse_link) -> dict:
    if not isinstance(d, dict):
        raise VjmError("links must be a mapping name -> {at: frame, <link>}")
    out = {}
    for name, spec in d.items():
        where = f"links.{name}"
        if not isinstance(spec, dict) or "at" not in spec:
            raise VjmError(f"{where} must be a mapping with at: (the frame the spring sits in) and one link entry")
        tree.frame(str(spec["at"]))
        rest = {k: v for k, v in spec.items() if k not in ("at", "xyz", "rpy")}
        off = origin_transform(_vec3(spec.get("xyz", [0, 0, 0]), f"{where}.xyz"),
                               _vec3(spec.get("rpy", [0, 0, 0]), f"{where}.rpy"))
        sp = parse_link(rest, where, base_dir).checked(where)
        out[str(name)] = PlacedSpring(sp, str(spec["at"]), off)
    return out


def _linkfea_mass(path: str, where: str) -> float:
    """The CAD mass (kg) a ``linkfea compute`` result states (``mass_kg``: volume times density)."""
    from linkfea.result.schema import read_result
    from linkfea.runtime.errors import LinkFeaError

    if not os.path.isfile(path):
        raise VjmError(f"{where}: file not found: {path}")
    try:
        m = read_result(path).get("mass_kg")
    except LinkFeaError as exc:
        raise VjmError(f"{where}: {exc}") from None
    if isinstance(m, bool) or not isinstance(m, (int, float)) or not np.isfinite(m) or m < 0:
        raise VjmError(f"{where}: {path} states no mass (mass_kg {m!r}; its material needs a density)")
    return float(m)


def _masses(d, tree: Tree, base_dir: str) -> tuple:
    if not isinstance(d, dict):
        raise VjmError("masses must be a mapping frame -> {mass: kg, com: [x, y, z] mm}")
    out = []
    for name, spec in d.items():
        where = f"masses.{name}"
        f = tree.frame(str(name))
        if not isinstance(spec, dict) or set(spec) - {"mass", "com", "linkfea"} or ("mass" in spec and "linkfea" in spec):
            raise VjmError(f"{where} must be a mapping {{mass: kg, com: [x, y, z] mm}} or "
                           f"{{linkfea: result.json, com: [x, y, z] mm}} (the result's CAD mass)")
        if "linkfea" in spec:
            if not isinstance(spec["linkfea"], str):
                raise VjmError(f"{where}.linkfea must be a file path")
            m = _linkfea_mass(os.path.normpath(os.path.join(base_dir, spec["linkfea"])), f"{where}.linkfea")
        elif "mass" in spec:
            m = _mass(spec["mass"], f"{where}.mass")
        else:
            raise VjmError(f"{where}: a centre of mass without a mass")
        if not 0 <= m <= MAX_MASS:
            raise VjmError(f"{where}.mass must be in [0, {MAX_MASS:g}] kg, got {m:g}")
        if "com" not in spec:
            raise VjmError(f"{where}: a mass of {m:g} kg without a centre of mass (com: [x, y, z] mm)")
        c = _vec3(spec["com"], f"{where}.com")
        out.append(Body(str(name), f.joint, m, f.placement[:3, :3] @ c + f.placement[:3, 3]))
    return tuple(out)


def _payload(d, tree: Tree) -> Payload:
    if not isinstance(d, dict) or set(d) - {"frame", "mass", "com"} or "frame" not in d or "mass" not in d:
        raise VjmError("payload must be a mapping {frame: name, mass: kg, com: [x, y, z] mm}")
    tree.frame(str(d["frame"]))
    m = _mass(d["mass"], "payload.mass")
    return Payload(str(d["frame"]), m, _vec3(d.get("com", [0, 0, 0]), "payload.com"))


def robot_from_dict(d: dict, base_dir: str, path: str | None, parse_link) -> RobotModel:
    """A validated :class:`RobotModel` from the mapping of a robot model file (read through
    :func:`vjm.modelio.read.model_from_dict`, which passes its ``<link>`` reader ``parse_link``)."""
    known = robot_keys()
    extra = set(d) - set(known)
    if extra:
        raise VjmError(f"unknown top-level keys {sorted(extra)} for a robot; known: {list(known)}")
    formats = robotformats.recognised(d)
    if len(formats) != 1:
        raise VjmError(f"a robot model file has exactly one of {robotformats.one_of()}")
    tools = d.get("tools")
    if tools is not None and (not isinstance(tools, list) or not all(isinstance(t, str) for t in tools) or not tools):
        raise VjmError("tools must be a list of frame names")
    tree = robotformats.READERS[formats[0]].read(d, base_dir)
    check_size(tree, str(tree.source or path or "the robot"))
    if tools and tree.tools != tuple(tools):
        tree = Tree(tree.name, tree.joints, tree.frames, tree.bodies, tuple(tools), tree.source, tree.declared)
    for t in tree.tools:
        if tree.frame(t).joint < 0:
            raise VjmError(f"tools: {t!r} is fixed to the robot's base: no joint moves it, so it has no stiffness "
                           f"to compute; name a frame the joints move")
    springs, six = _joints(d.get("joints") or {}, base_dir, tree, parse_link)
    links = _links(d.get("links") or {}, base_dir, tree, parse_link)
    if d.get("masses"):
        added = _masses(d["masses"], tree, base_dir)
        tree = Tree(tree.name, tree.joints, tree.frames, tree.bodies + added, tree.tools, tree.source,
                    tree.declared | {b.joint for b in added})
    payload = _payload(d["payload"], tree) if d.get("payload") is not None else None
    g = tuple(_vec3(d["gravity"], "gravity")) if "gravity" in d else GRAVITY
    strict = d.get("strict_limits", False)
    if not isinstance(strict, bool):
        raise VjmError(f"strict_limits must be true or false, got {strict!r}")
    home = d.get("home")
    if home is not None:
        if not isinstance(home, list) or len(home) != tree.nq:
            raise VjmError(f"home must be a list of {tree.nq} joint values ({', '.join(tree.q_names)}), got {home!r}")
        home = tuple(_num(v, "home") for v in home)
    return RobotModel(tree, springs, six, links, payload, g, str(d.get("name", tree.name)), path, dict(d), strict,
                      home, _payload_limit(d.get("payload_limit"), payload))


def _payload_limit(v, payload: Payload | None) -> float | None:
    """The rated load (kg) of ``payload_limit:``: > 0, and at least the ``payload:`` the file states."""
    if v is None:
        return None
    lim = _num(v, "payload_limit")
    if not lim > 0:
        raise VjmError(f"payload_limit must be > 0 (kg, the rated load), got {lim:g}")
    if payload is not None and payload.mass > lim:
        raise VjmError(f"payload.mass {payload.mass:g} kg exceeds payload_limit {lim:g} kg")
    return lim


def is_robot(d) -> bool:
    """Whether a model file's mapping describes a serial or tree robot (a format of
    :mod:`vjm.modelio.robotformats` recognises it: it names a URDF, holds a DH table ...)."""
    return bool(robotformats.recognised(d))
