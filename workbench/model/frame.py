"""The frame file (``frame.toml``, CONTRACTS.md section 1) and the `Frame` record.

A frame is a planar set of straight beams (members) joined rigidly where they meet, with bolted
joints as zones of a member whose Young's modulus is random (paper section 2.2.2, Figure 3c).
`read_frame` validates everything the contract lists and raises `FrameFileError` with a one-line
message naming the file, the field and the problem.

One optional key extends the contract: ``axial_force`` (N, tension positive) on a member, the
locked-in axial load whose geometric stiffness the gap diagnosis needs.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "DOF_NAMES",
    "BEAM_THEORIES",
    "DEFAULT_DAMPING_RATIO",
    "FrameFileError",
    "Material",
    "Section",
    "Member",
    "Joint",
    "Support",
    "PointMass",
    "GroundSpring",
    "DofRef",
    "Sensor",
    "Frame",
    "read_frame",
    "parse_frame",
    "frame_to_toml",
    "write_frame",
    "toml_string",
    "member_length",
    "locate_point",
]

DOF_NAMES = ("ux", "uy", "rz")
BEAM_THEORIES = ("euler-bernoulli", "timoshenko")
DEFAULT_ELEMENT_LENGTH = 0.01  # m
DEFAULT_DAMPING_RATIO = 0.005
FIXED = math.inf  # a support dof of infinite stiffness is removed from the system
# Relative to the frame's size: how far a point may sit from a member and still be on it.
_ON_MEMBER_TOLERANCE = 1e-9


class FrameFileError(ValueError):
    """A frame file breaks the contract; the message is one line: ``file: field: problem``."""


@dataclass(frozen=True)
class Material:
    name: str
    youngs_modulus: float  # Pa
    density: float  # kg/m3
    poisson_ratio: float | None = None


@dataclass(frozen=True)
class Section:
    name: str
    area: float  # m2
    second_moment: float  # m4
    shear_coefficient: float | None = None


@dataclass(frozen=True)
class Member:
    name: str
    start: str
    end: str
    material: str
    section: str
    axial_force: float = 0.0  # N, tension positive (extension of the contract)


@dataclass(frozen=True)
class Joint:
    name: str
    member: str
    span: tuple[float, float]  # m from the member's start
    youngs_modulus: float  # Pa, mean of the zone's modulus
    cov: float = 0.0
    group: str = ""

    def __post_init__(self) -> None:
        if not self.group:
            object.__setattr__(self, "group", self.name)


@dataclass(frozen=True)
class Support:
    """Support conditions at a point; each dof is None (free), `math.inf` (fixed) or N/m, N.m/rad."""

    point: str
    ux: float | None = None
    uy: float | None = None
    rz: float | None = None

    def stiffness(self, dof: str) -> float | None:
        return getattr(self, dof)


@dataclass(frozen=True)
class PointMass:
    point: str
    mass: float  # kg
    rotary_inertia: float = 0.0  # kg.m2


@dataclass(frozen=True)
class GroundSpring:
    point: str
    dof: str
    stiffness: float  # N/m or N.m/rad


@dataclass(frozen=True)
class DofRef:
    point: str
    dof: str


@dataclass(frozen=True)
class Sensor:
    name: str
    point: str
    dof: str


@dataclass(frozen=True)
class Frame:
    """A validated frame file. Immutable: change it with `dataclasses.replace`."""

    name: str
    points: dict[str, tuple[float, float]]
    materials: dict[str, Material]
    sections: dict[str, Section]
    members: tuple[Member, ...]
    joints: tuple[Joint, ...] = ()
    supports: tuple[Support, ...] = ()
    masses: tuple[PointMass, ...] = ()
    springs: tuple[GroundSpring, ...] = ()
    excitation: DofRef | None = None
    sensors: tuple[Sensor, ...] = ()
    damping_ratios: tuple[float, ...] = (DEFAULT_DAMPING_RATIO,)
    beam_theory: str = "euler-bernoulli"
    element_length: float = DEFAULT_ELEMENT_LENGTH  # m
    description: str = ""
    source: str = field(default="<frame>", compare=False)

    def member(self, name: str) -> Member:
        for m in self.members:
            if m.name == name:
                return m
        raise KeyError(f"{self.source}: members: no member named {name!r}")

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        known = ", ".join(j.name for j in self.joints) or "none"
        raise KeyError(f"{self.source}: joints: no joint named {name!r} (known: {known})")

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    def damping_ratio(self, mode_count: int) -> tuple[float, ...]:
        """Modal damping ratios of the first `mode_count` modes; the last given value repeats."""
        r = self.damping_ratios
        return tuple(r[min(k, len(r) - 1)] for k in range(mode_count))


def member_length(frame: Frame, member: Member) -> float:
    """Length of `member` in m."""
    (x0, y0), (x1, y1) = frame.points[member.start], frame.points[member.end]
    return math.hypot(x1 - x0, y1 - y0)


def locate_point(
    points: dict[str, tuple[float, float]], member: Member, xy: tuple[float, float]
) -> float | None:
    """Distance in m along `member` from its start to `xy`, or None if `xy` is not on it."""
    (x0, y0), (x1, y1) = points[member.start], points[member.end]
    dx, dy = x1 - x0, y1 - y0
    length = math.hypot(dx, dy)
    scale = max(1.0, max(abs(c) for p in points.values() for c in p))
    tol = _ON_MEMBER_TOLERANCE * scale
    s = ((xy[0] - x0) * dx + (xy[1] - y0) * dy) / length
    off = abs((xy[0] - x0) * dy - (xy[1] - y0) * dx) / length
    if off > tol or s < -tol or s > length + tol:
        return None
    return min(max(s, 0.0), length)


def read_frame(path: str | Path) -> Frame:
    """Read and validate a frame file (CONTRACTS.md section 1).

    Parameters
    ----------
    path : str or Path
        The ``frame.toml`` file. It is only read.

    Returns
    -------
    Frame
        The validated frame; SI units, as in the file.

    Raises
    ------
    FrameFileError
        One line naming the file, the field and the problem.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise FrameFileError(f"{path}: cannot read the frame file: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FrameFileError(f"{path}: not valid TOML: {exc}") from None
    return parse_frame(data, source=str(path))


class _Reader:
    """Typed access to one TOML table that names the file and the field in every error."""

    def __init__(self, source: str, where: str, table: Any, allowed: set[str] | None,
                 required: set[str]):
        self.source, self.where = source, where
        if not isinstance(table, dict):
            self.fail("", f"expected a table, got {_kind(table)}")
        unknown = [] if allowed is None else sorted(set(table) - allowed)
        if unknown:
            self.fail(unknown[0], f"unknown key (allowed: {', '.join(sorted(allowed))})")
        for key in sorted(required):
            if key not in table:
                self.fail(key, "required key is missing")
        self.table = table

    def field(self, key: str) -> str:
        if not key:
            return self.where
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str, problem: str) -> None:
        raise FrameFileError(f"{self.source}: {self.field(key)}: {problem}")

    def has(self, key: str) -> bool:
        return key in self.table

    def string(self, key: str, default: str | None = None) -> str:
        value = self.table.get(key, default)
        if not isinstance(value, str) or (key in self.table and not value.strip()):
            self.fail(key, f"expected a non-empty string, got {_kind(value)}")
        return value

    def number(self, key: str, *, default: float | None = None, positive: bool = False,
               nonnegative: bool = False, below: float | None = None) -> float:
        value = self.table.get(key, default)
        return _number(self, key, value, positive=positive, nonnegative=nonnegative, below=below)

    def choice(self, key: str, options: tuple[str, ...], default: str | None = None) -> str:
        value = self.table.get(key, default)
        if value not in options:
            self.fail(key, f"{value!r} is not one of {', '.join(options)}")
        return value

    def name_in(self, key: str, defined: dict | set, what: str) -> str:
        value = self.string(key)
        if value not in defined:
            self.fail(key, f"{value!r} is not defined in {what}")
        return value


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"string {value!r}"
    if isinstance(value, (int, float)):
        return f"number {value!r}"
    return type(value).__name__


def _number(r: _Reader, key: str, value: Any, *, positive=False, nonnegative=False, below=None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        r.fail(key, f"expected a number, got {_kind(value)}")
    value = float(value)
    if not math.isfinite(value):
        r.fail(key, f"must be finite, got {value}")
    if positive and value <= 0.0:
        r.fail(key, f"must be positive, got {value:g}")
    if nonnegative and value < 0.0:
        r.fail(key, f"must not be negative, got {value:g}")
    if below is not None and value >= below:
        r.fail(key, f"must be below {below:g}, got {value:g}")
    return value


def _array_of_tables(r: _Reader, key: str) -> list:
    value = r.table.get(key, [])
    if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
        r.fail(key, f"expected an array of tables [[{key}]], got {_kind(value)}")
    return value


def _dof(r: _Reader, key: str) -> str:
    return r.choice(key, DOF_NAMES)


def parse_frame(data: dict[str, Any], source: str = "<frame>") -> Frame:
    """Validate a frame already parsed from TOML into a dict; see `read_frame`."""
    top = _Reader(
        source, "", data,
        allowed={"name", "description", "beam_theory", "element_length", "materials", "sections",
                 "points", "members", "joints", "supports", "masses", "springs", "excitation",
                 "sensors", "damping"},
        required={"name", "materials", "sections", "points", "members"},
    )
    name = top.string("name")
    description = top.string("description", "") if top.has("description") else ""
    theory = top.choice("beam_theory", BEAM_THEORIES, "euler-bernoulli")
    element_length = top.number("element_length", default=DEFAULT_ELEMENT_LENGTH, positive=True)
    timoshenko = theory == "timoshenko"

    def named_tables(key: str, what: str) -> dict[str, Any]:
        tables = _Reader(source, key, data[key], None, set())
        if not tables.table:
            tables.fail("", f"at least one {what} is required")
        return tables.table

    def timoshenko_only(r: _Reader, key: str, **limits: Any) -> float | None:
        # optional for Euler-Bernoulli, required for Timoshenko
        if not (r.has(key) or timoshenko):
            return None
        if not r.has(key):
            r.fail(key, "required when beam_theory = \"timoshenko\"")
        return r.number(key, **limits)

    materials: dict[str, Material] = {}
    for mname, table in named_tables("materials", "material").items():
        r = _Reader(source, f"materials.{mname}", table,
                    {"youngs_modulus", "density", "poisson_ratio"}, {"youngs_modulus", "density"})
        nu = timoshenko_only(r, "poisson_ratio", below=0.5)
        if nu is not None and nu <= -1.0:
            r.fail("poisson_ratio", f"must lie in (-1, 0.5), got {nu:g}")
        materials[mname] = Material(mname, r.number("youngs_modulus", positive=True),
                                    r.number("density", positive=True), nu)

    sections: dict[str, Section] = {}
    for sname, table in named_tables("sections", "section").items():
        r = _Reader(source, f"sections.{sname}", table,
                    {"area", "second_moment", "shear_coefficient"}, {"area", "second_moment"})
        sections[sname] = Section(sname, r.number("area", positive=True), r.number("second_moment", positive=True),
                                  timoshenko_only(r, "shear_coefficient", positive=True))

    points: dict[str, tuple[float, float]] = {}
    pts = _Reader(source, "points", data["points"], None, set())
    if not pts.table:
        pts.fail("", "at least two points are required")
    for pname, xy in pts.table.items():
        if (not isinstance(xy, list) or len(xy) != 2
                or any(isinstance(c, bool) or not isinstance(c, (int, float)) for c in xy)):
            pts.fail(pname, f"expected [x, y] in m, got {xy!r}")
        if not all(math.isfinite(c) for c in xy):
            pts.fail(pname, f"coordinates must be finite, got {xy!r}")
        points[pname] = (float(xy[0]), float(xy[1]))
    seen_xy: dict[tuple[float, float], str] = {}
    for pname, xy in points.items():
        if xy in seen_xy:
            pts.fail(pname, f"same coordinates as point {seen_xy[xy]!r}")
        seen_xy[xy] = pname

    members: list[Member] = []
    member_tables = _array_of_tables(top, "members")
    if not member_tables:
        top.fail("members", "at least one [[members]] is required")
    for i, table in enumerate(member_tables):
        r = _Reader(source, f"members[{i}]", table,
                    {"name", "start", "end", "material", "section", "axial_force"},
                    {"name", "start", "end", "material", "section"})
        mname = r.string("name")
        if any(m.name == mname for m in members):
            r.fail("name", f"duplicate member name {mname!r}")
        start, end = r.name_in("start", points, "[points]"), r.name_in("end", points, "[points]")
        if start == end:
            r.fail("end", "a member needs two distinct points")
        members.append(Member(mname, start, end, r.name_in("material", materials, "[materials]"),
                              r.name_in("section", sections, "[sections]"),
                              r.number("axial_force", default=0.0)))
    by_name = {m.name: m for m in members}

    for pname, xy in points.items():
        if not any(locate_point(points, m, xy) is not None for m in members):
            pts.fail(pname, f"point {pname!r} at {list(xy)} lies on no member")

    joints: list[Joint] = []
    for i, table in enumerate(_array_of_tables(top, "joints")):
        r = _Reader(source, f"joints[{i}]", table,
                    {"name", "member", "span", "youngs_modulus", "cov", "group"},
                    {"name", "member", "span", "youngs_modulus"})
        jname = r.string("name")
        if any(j.name == jname for j in joints):
            r.fail("name", f"duplicate joint name {jname!r}")
        mname = r.name_in("member", by_name, "[[members]]")
        span = table["span"]
        if (not isinstance(span, list) or len(span) != 2
                or any(isinstance(c, bool) or not isinstance(c, (int, float)) for c in span)):
            r.fail("span", f"expected [start, end] in m along the member, got {span!r}")
        a, b = float(span[0]), float(span[1])
        length = member_length(Frame(name, points, materials, sections, tuple(members)), by_name[mname])
        if not (math.isfinite(a) and math.isfinite(b)) or not (0.0 <= a < b <= length * (1 + 1e-12)):
            r.fail("span", f"[{a:g}, {b:g}] must satisfy 0 <= start < end <= {length:g} m "
                           f"(length of member {mname!r})")
        for other in joints:
            if other.member == mname and a < other.span[1] and other.span[0] < b:
                r.fail("span", f"overlaps joint {other.name!r} on member {mname!r}")
        group = r.string("group") if r.has("group") else jname
        joints.append(Joint(jname, mname, (a, min(b, length)), r.number("youngs_modulus", positive=True),
                            r.number("cov", default=0.0, nonnegative=True), group))

    supports: list[Support] = []
    for i, table in enumerate(_array_of_tables(top, "supports")):
        r = _Reader(source, f"supports[{i}]", table, {"point", *DOF_NAMES}, {"point"})
        point = r.name_in("point", points, "[points]")
        if any(s.point == point for s in supports):
            r.fail("point", f"point {point!r} already has a [[supports]] entry")
        values: dict[str, float | None] = {}
        for dof in DOF_NAMES:
            v = table.get(dof, "free")
            if v == "fixed":
                values[dof] = FIXED
            elif v == "free":
                values[dof] = None
            elif isinstance(v, str):
                r.fail(dof, f"{v!r} is not \"fixed\", \"free\" or a stiffness")
            else:
                values[dof] = _number(r, dof, v, positive=True)
        supports.append(Support(point, **values))

    masses: list[PointMass] = []
    for i, table in enumerate(_array_of_tables(top, "masses")):
        r = _Reader(source, f"masses[{i}]", table, {"point", "mass", "rotary_inertia"}, {"point", "mass"})
        masses.append(PointMass(r.name_in("point", points, "[points]"), r.number("mass", positive=True),
                                r.number("rotary_inertia", default=0.0, nonnegative=True)))

    springs: list[GroundSpring] = []
    for i, table in enumerate(_array_of_tables(top, "springs")):
        r = _Reader(source, f"springs[{i}]", table, {"point", "dof", "stiffness"}, {"point", "dof", "stiffness"})
        springs.append(GroundSpring(r.name_in("point", points, "[points]"), _dof(r, "dof"),
                                    r.number("stiffness", positive=True)))

    excitation = None
    if "excitation" in data:
        r = _Reader(source, "excitation", data["excitation"], {"point", "dof"}, {"point", "dof"})
        excitation = DofRef(r.name_in("point", points, "[points]"), _dof(r, "dof"))

    sensors: list[Sensor] = []
    for i, table in enumerate(_array_of_tables(top, "sensors")):
        r = _Reader(source, f"sensors[{i}]", table, {"name", "point", "dof"}, {"name", "point", "dof"})
        sname = r.string("name")
        if any(s.name == sname for s in sensors):
            r.fail("name", f"duplicate sensor name {sname!r}")
        sensors.append(Sensor(sname, r.name_in("point", points, "[points]"), _dof(r, "dof")))

    ratios: tuple[float, ...] = (DEFAULT_DAMPING_RATIO,)
    if "damping" in data:
        r = _Reader(source, "damping", data["damping"], {"ratios"}, {"ratios"})
        values = r.table["ratios"]
        if not isinstance(values, list) or not values:
            r.fail("ratios", f"expected a non-empty list of damping ratios, got {_kind(values)}")
        ratios = tuple(_number(r, f"ratios[{k}]", v, nonnegative=True, below=1.0)
                       for k, v in enumerate(values))

    return Frame(name=name, points=points, materials=materials, sections=sections,
                 members=tuple(members), joints=tuple(joints), supports=tuple(supports),
                 masses=tuple(masses), springs=tuple(springs), excitation=excitation,
                 sensors=tuple(sensors), damping_ratios=ratios, beam_theory=theory,
                 element_length=element_length, description=description, source=source)


def toml_string(value: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = []
    for ch in value:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if value == FIXED:
        return '"fixed"'
    return repr(float(value))


def frame_to_toml(frame: Frame) -> str:
    """The frame file text of ``frame``; `read_frame` of it gives back an equal `Frame`."""
    out = [f"name = {_toml_value(frame.name)}"]
    if frame.description:
        out.append(f"description = {_toml_value(frame.description)}")
    out += [f"beam_theory = {_toml_value(frame.beam_theory)}",
            f"element_length = {_toml_value(frame.element_length)}"]

    def table(header: str, items: dict[str, Any]) -> None:
        out.append("")
        out.append(header)
        out.extend(f"{k} = {_toml_value(v)}" for k, v in items.items() if v is not None)

    for m in frame.materials.values():
        table(f"[materials.{m.name}]", {"youngs_modulus": m.youngs_modulus, "density": m.density,
                                        "poisson_ratio": m.poisson_ratio})
    for s in frame.sections.values():
        table(f"[sections.{s.name}]", {"area": s.area, "second_moment": s.second_moment,
                                       "shear_coefficient": s.shear_coefficient})
    table("[points]", {k: list(v) for k, v in frame.points.items()})
    for m in frame.members:
        table("[[members]]", {"name": m.name, "start": m.start, "end": m.end, "material": m.material,
                              "section": m.section, "axial_force": m.axial_force or None})
    for j in frame.joints:
        table("[[joints]]", {"name": j.name, "member": j.member, "span": list(j.span),
                             "youngs_modulus": j.youngs_modulus, "cov": j.cov, "group": j.group})
    for s in frame.supports:
        table("[[supports]]", {"point": s.point, "ux": s.ux, "uy": s.uy, "rz": s.rz})
    for pm in frame.masses:
        table("[[masses]]", {"point": pm.point, "mass": pm.mass, "rotary_inertia": pm.rotary_inertia})
    for sp_ in frame.springs:
        table("[[springs]]", {"point": sp_.point, "dof": sp_.dof, "stiffness": sp_.stiffness})
    if frame.excitation is not None:
        table("[excitation]", {"point": frame.excitation.point, "dof": frame.excitation.dof})
    for s in frame.sensors:
        table("[[sensors]]", {"name": s.name, "point": s.point, "dof": s.dof})
    table("[damping]", {"ratios": list(frame.damping_ratios)})
    return "\n".join(out) + "\n"


def write_frame(frame: Frame, path: str | Path) -> None:
    """Write ``frame`` as a frame file, whole or not at all (a temporary file renamed into place)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(frame_to_toml(frame), encoding="utf-8")
    tmp.replace(path)
