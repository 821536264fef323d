"""Reading and writing the frame file (``frame.toml``, CONTRACTS.md section 1).

`read_frame` validates everything the contract lists and raises `FrameFileError` with a one-line
message naming the file, the field and the problem; `parse_frame` does the same on a dict already
parsed from TOML, one function per table of the file, in the file's order. `frame_to_toml` gives
the text back (`workbench.io.outputs.write_frame` writes it to disk).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, NoReturn

from workbench.model.frame import (
    BEAM_THEORIES,
    DEFAULT_DAMPING_RATIO,
    DEFAULT_ELEMENT_LENGTH,
    DOF_NAMES,
    FIXED,
    DofRef,
    Frame,
    FrameFileError,
    GroundSpring,
    Joint,
    Material,
    Member,
    PointMass,
    Section,
    Sensor,
    Support,
    member_length,
    points_on_member,
)
from workbench.model.sanity import check_frame

__all__ = ["read_frame", "parse_frame", "frame_to_toml", "toml_string"]

Points = dict[str, tuple[float, float]]

_TOP_KEYS = {"name", "description", "beam_theory", "element_length", "materials", "sections", "points",
             "members", "joints", "supports", "masses", "springs", "excitation", "sensors", "damping"}
_TOP_REQUIRED = {"name", "materials", "sections", "points", "members"}


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
                 required: set[str]) -> None:
        self.source, self.where = source, where
        if not isinstance(table, dict):
            self.fail("", f"expected a table, got {_kind(table)}")
        unknown = [] if allowed is None else sorted(set(table) - allowed)
        if unknown:
            self.fail(unknown[0], f"unknown key (allowed: {', '.join(sorted(allowed or ()))})")
        for key in sorted(required):
            if key not in table:
                self.fail(key, "required key is missing")
        self.table: dict[str, Any] = table

    def field(self, key: str) -> str:
        if not key:
            return self.where
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str, problem: str) -> NoReturn:
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

    def name_in(self, key: str, defined: dict[str, Any] | set[str], what: str) -> str:
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


def _number(r: _Reader, key: str, value: Any, *, positive: bool = False, nonnegative: bool = False,
            below: float | None = None) -> float:
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


def _array_of_tables(r: _Reader, key: str) -> list[dict[str, Any]]:
    value = r.table.get(key, [])
    if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
        r.fail(key, f"expected an array of tables [[{key}]], got {_kind(value)}")
    return value


def _dof(r: _Reader, key: str) -> str:
    return r.choice(key, DOF_NAMES)


def _named_tables(source: str, data: dict[str, Any], key: str, what: str) -> dict[str, Any]:
    tables = _Reader(source, key, data[key], None, set())
    if not tables.table:
        tables.fail("", f"at least one {what} is required")
    return tables.table


def _timoshenko_only(r: _Reader, key: str, timoshenko: bool, **limits: Any) -> float | None:
    """An optional number for Euler-Bernoulli beams, required for Timoshenko ones."""
    if not (r.has(key) or timoshenko):
        return None
    if not r.has(key):
        r.fail(key, "required when beam_theory = \"timoshenko\"")
    return r.number(key, **limits)


def _materials(source: str, data: dict[str, Any], timoshenko: bool) -> dict[str, Material]:
    materials: dict[str, Material] = {}
    for mname, table in _named_tables(source, data, "materials", "material").items():
        r = _Reader(source, f"materials.{mname}", table,
                    {"youngs_modulus", "density", "poisson_ratio"}, {"youngs_modulus", "density"})
        nu = _timoshenko_only(r, "poisson_ratio", timoshenko, below=0.5)
        if nu is not None and nu <= -1.0:
            r.fail("poisson_ratio", f"must lie in (-1, 0.5), got {nu:g}")
        materials[mname] = Material(mname, r.number("youngs_modulus", positive=True),
                                    r.number("density", positive=True), nu)
    return materials


def _sections(source: str, data: dict[str, Any], timoshenko: bool) -> dict[str, Section]:
    sections: dict[str, Section] = {}
    for sname, table in _named_tables(source, data, "sections", "section").items():
        r = _Reader(source, f"sections.{sname}", table,
                    {"area", "second_moment", "shear_coefficient"}, {"area", "second_moment"})
        sections[sname] = Section(sname, r.number("area", positive=True), r.number("second_moment", positive=True),
                                  _timoshenko_only(r, "shear_coefficient", timoshenko, positive=True))
    return sections


def _points(source: str, data: dict[str, Any]) -> tuple[Points, _Reader]:
    """The named points (m) and their table's reader (the check that each lies on a member needs it)."""
    points: Points = {}
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
    return points, pts


def _members(top: _Reader, points: Points, materials: dict[str, Material],
             sections: dict[str, Section]) -> list[Member]:
    members: list[Member] = []
    member_tables = _array_of_tables(top, "members")
    if not member_tables:
        top.fail("members", "at least one [[members]] is required")
    for i, table in enumerate(member_tables):
        r = _Reader(top.source, f"members[{i}]", table,
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
    return members


def _check_points_on_members(pts: _Reader, points: Points, members: tuple[Member, ...]) -> None:
    on_some = {name for m in members for name in points_on_member(points, m)}
    for pname, xy in points.items():
        if pname not in on_some:
            pts.fail(pname, f"point {pname!r} at {list(xy)} lies on no member")


def _joints(top: _Reader, frame: Frame) -> list[Joint]:
    """The joint zones of ``frame`` (its points and members already validated)."""
    by_name = {m.name: m for m in frame.members}
    joints: list[Joint] = []
    for i, table in enumerate(_array_of_tables(top, "joints")):
        r = _Reader(top.source, f"joints[{i}]", table,
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
        length = member_length(frame, by_name[mname])
        if not (math.isfinite(a) and math.isfinite(b)) or not (0.0 <= a < b <= length * (1 + 1e-12)):
            r.fail("span", f"[{a:g}, {b:g}] must satisfy 0 <= start < end <= {length:g} m "
                           f"(length of member {mname!r})")
        for other in joints:
            if other.member == mname and a < other.span[1] and other.span[0] < b:
                r.fail("span", f"overlaps joint {other.name!r} on member {mname!r}")
        group = r.string("group") if r.has("group") else jname
        joints.append(Joint(jname, mname, (a, min(b, length)), r.number("youngs_modulus", positive=True),
                            r.number("cov", default=0.0, nonnegative=True), group))
    return joints


def _supports(top: _Reader, points: Points) -> list[Support]:
    supports: list[Support] = []
    for i, table in enumerate(_array_of_tables(top, "supports")):
        r = _Reader(top.source, f"supports[{i}]", table, {"point", *DOF_NAMES}, {"point"})
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
    return supports


def _masses(top: _Reader, points: Points) -> list[PointMass]:
    masses: list[PointMass] = []
    for i, table in enumerate(_array_of_tables(top, "masses")):
        r = _Reader(top.source, f"masses[{i}]", table, {"point", "mass", "rotary_inertia"}, {"point", "mass"})
        masses.append(PointMass(r.name_in("point", points, "[points]"), r.number("mass", positive=True),
                                r.number("rotary_inertia", default=0.0, nonnegative=True)))
    return masses


def _springs(top: _Reader, points: Points) -> list[GroundSpring]:
    springs: list[GroundSpring] = []
    for i, table in enumerate(_array_of_tables(top, "springs")):
        r = _Reader(top.source, f"springs[{i}]", table, {"point", "dof", "stiffness"},
                    {"point", "dof", "stiffness"})
        springs.append(GroundSpring(r.name_in("point", points, "[points]"), _dof(r, "dof"),
                                    r.number("stiffness", positive=True)))
    return springs


def _excitation(source: str, data: dict[str, Any], points: Points) -> DofRef | None:
    if "excitation" not in data:
        return None
    r = _Reader(source, "excitation", data["excitation"], {"point", "dof"}, {"point", "dof"})
    return DofRef(r.name_in("point", points, "[points]"), _dof(r, "dof"))


def _sensors(top: _Reader, points: Points) -> list[Sensor]:
    sensors: list[Sensor] = []
    for i, table in enumerate(_array_of_tables(top, "sensors")):
        r = _Reader(top.source, f"sensors[{i}]", table, {"name", "point", "dof"}, {"name", "point", "dof"})
        sname = r.string("name")
        if any(s.name == sname for s in sensors):
            r.fail("name", f"duplicate sensor name {sname!r}")
        sensors.append(Sensor(sname, r.name_in("point", points, "[points]"), _dof(r, "dof")))
    return sensors


def _damping(source: str, data: dict[str, Any]) -> tuple[float, ...]:
    if "damping" not in data:
        return (DEFAULT_DAMPING_RATIO,)
    r = _Reader(source, "damping", data["damping"], {"ratios"}, {"ratios"})
    values = r.table["ratios"]
    if not isinstance(values, list) or not values:
        r.fail("ratios", f"expected a non-empty list of damping ratios, got {_kind(values)}")
    return tuple(_number(r, f"ratios[{k}]", v, nonnegative=True, below=1.0) for k, v in enumerate(values))


def parse_frame(data: dict[str, Any], source: str = "<frame>") -> Frame:
    """Validate a frame already parsed from TOML into a dict; see `read_frame`.

    Tables are checked in the file's order, so the first error reported is the first in the file
    (names are only checked against the tables above them).
    """
    top = _Reader(source, "", data, allowed=_TOP_KEYS, required=_TOP_REQUIRED)
    name = top.string("name")
    description = top.string("description", "") if top.has("description") else ""
    theory = top.choice("beam_theory", BEAM_THEORIES, "euler-bernoulli")
    element_length = top.number("element_length", default=DEFAULT_ELEMENT_LENGTH, positive=True)
    timoshenko = theory == "timoshenko"
    materials = _materials(source, data, timoshenko)
    sections = _sections(source, data, timoshenko)
    points, pts = _points(source, data)
    members = tuple(_members(top, points, materials, sections))
    _check_mesh_size(source, points, members, element_length)
    _check_points_on_members(pts, points, members)
    joints = _joints(top, Frame(name, points, materials, sections, members))
    supports = _supports(top, points)
    masses = _masses(top, points)
    springs = _springs(top, points)
    excitation = _excitation(source, data, points)
    sensors = _sensors(top, points)
    ratios = _damping(source, data)
    frame = Frame(name=name, points=points, materials=materials, sections=sections,
                 members=members, joints=tuple(joints), supports=tuple(supports),
                 masses=tuple(masses), springs=tuple(springs), excitation=excitation,
                 sensors=tuple(sensors), damping_ratios=ratios, beam_theory=theory,
                 element_length=element_length, description=description, source=source)
    check_frame(frame)
    return frame


MAX_ELEMENTS = 400_000  # 1.2 million dofs, the largest models the scale targets ask for; far beyond, memory runs out


def _check_mesh_size(source: str, points: dict, members: tuple, element_length: float) -> None:
    """Refuse a mesh too large to build before it is allocated (an element length of 1e-6 m ended in MemoryError)."""
    count = sum(math.ceil(math.dist(points[m.start], points[m.end]) / element_length) for m in members)
    if count > MAX_ELEMENTS:
        raise ValueError(f"{source}: element_length: {element_length:g} m would make {count} elements (at most "
                         f"{MAX_ELEMENTS}); use a longer element_length, or check the units of the coordinates (m)")


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

    for mat in frame.materials.values():
        table(f"[materials.{mat.name}]", {"youngs_modulus": mat.youngs_modulus, "density": mat.density,
                                          "poisson_ratio": mat.poisson_ratio})
    for sec in frame.sections.values():
        table(f"[sections.{sec.name}]", {"area": sec.area, "second_moment": sec.second_moment,
                                         "shear_coefficient": sec.shear_coefficient})
    table("[points]", {k: list(v) for k, v in frame.points.items()})
    for m in frame.members:
        if m.locked_force:  # the diagnosis's candidate only: a frame file has no key for it
            raise ValueError(f"{frame.source}: member {m.name!r}: a locked-in force has no frame-file key")
        table("[[members]]", {"name": m.name, "start": m.start, "end": m.end, "material": m.material,
                              "section": m.section, "axial_force": m.axial_force or None})
    for j in frame.joints:
        table("[[joints]]", {"name": j.name, "member": j.member, "span": list(j.span),
                             "youngs_modulus": j.youngs_modulus, "cov": j.cov, "group": j.group})
    for sup in frame.supports:
        table("[[supports]]", {"point": sup.point, "ux": sup.ux, "uy": sup.uy, "rz": sup.rz})
    for pm in frame.masses:
        table("[[masses]]", {"point": pm.point, "mass": pm.mass, "rotary_inertia": pm.rotary_inertia})
    for sp_ in frame.springs:
        if sp_.mass:  # the diagnosis's stinger candidate only: a frame file has no key for it
            raise ValueError(f"{frame.source}: the spring at {sp_.point!r}: a moving mass has no frame-file key")
        table("[[springs]]", {"point": sp_.point, "dof": sp_.dof, "stiffness": sp_.stiffness})
    if frame.excitation is not None:
        table("[excitation]", {"point": frame.excitation.point, "dof": frame.excitation.dof})
    for sen in frame.sensors:
        table("[[sensors]]", {"name": sen.name, "point": sen.point, "dof": sen.dof})
    table("[damping]", {"ratios": list(frame.damping_ratios)})
    return "\n".join(out) + "\n"
