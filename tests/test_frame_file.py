"""The frame file reader: valid files, and every malformed one rejected with a one-line message."""

from __future__ import annotations

import math
import re

import pytest
from conftest import shared_path

from workbench.io.outputs import write_frame
from workbench.model.frame import FrameFileError
from workbench.model.frame_file import frame_to_toml, parse_frame, read_frame

VALID = '''
name = "portal"
element_length = 0.02

[materials.al]
youngs_modulus = 70e9
density = 2700.0

[sections.bar]
area = 2.4e-4
second_moment = 1.28e-9

[points]
base_left = [0.0, 0.0]
drive = [0.0, 0.115]
top_left = [0.0, 0.5]
top_right = [0.6, 0.5]
base_right = [0.6, 0.0]

[[members]]
name = "left"
start = "base_left"
end = "top_left"
material = "al"
section = "bar"

[[members]]
name = "beam"
start = "top_left"
end = "top_right"
material = "al"
section = "bar"

[[members]]
name = "right"
start = "base_right"
end = "top_right"
material = "al"
section = "bar"

[[joints]]
name = "A"
member = "left"
span = [0.44, 0.5]
youngs_modulus = 24e9
cov = 0.09
group = "vertical"

[[supports]]
point = "base_left"
ux = "fixed"
uy = "fixed"
rz = 2.0e4

[[supports]]
point = "base_right"
ux = "fixed"
uy = "fixed"
rz = "fixed"

[[masses]]
point = "top_left"
mass = 0.06
rotary_inertia = 2.0e-5

[[springs]]
point = "drive"
dof = "ux"
stiffness = 1.5e4

[excitation]
point = "drive"
dof = "ux"

[[sensors]]
name = "s1"
point = "top_left"
dof = "ux"

[damping]
ratios = [0.005, 0.004]
'''


def write(tmp_path, text: str):
    path = tmp_path / "frame.toml"
    path.write_text(text)
    return path


def test_valid_frame_reads_every_table(tmp_path):
    frame = read_frame(write(tmp_path, VALID))
    assert [m.name for m in frame.members] == ["left", "beam", "right"]
    assert frame.joint("A").span == (0.44, 0.5) and frame.joint("A").group == "vertical"
    assert frame.supports[0].ux == math.inf and frame.supports[0].rz == 2.0e4
    assert frame.damping_ratio(4) == (0.005, 0.004, 0.004, 0.004)
    assert frame.excitation.point == "drive" and frame.sensors[0].dof == "ux"


def test_defaults_follow_the_contract(tmp_path):
    text = VALID.replace('element_length = 0.02\n', "").split("[damping]")[0]
    frame = read_frame(write(tmp_path, text))
    assert frame.element_length == 0.01 and frame.beam_theory == "euler-bernoulli"
    assert frame.damping_ratio(3) == (0.005,) * 3


def test_round_trip_through_the_writer(tmp_path):
    frame = read_frame(write(tmp_path, VALID))
    out = tmp_path / "copy.toml"
    write_frame(frame, out)
    assert read_frame(out) == frame


def test_reads_the_frame_written_by_another_program():
    path = shared_path("examples", "independent-two-test-campaign", "frame.toml")
    frame = read_frame(path)
    assert frame.joint_names == ("A",) and len(frame.sensors) == 3
    assert read_frame(path) == frame and frame_to_toml(frame)


def test_unknown_joint_name_is_named():
    frame = parse_frame({"name": "x", "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
                                                  "sections": {"s": {"area": 1e-4, "second_moment": 1e-9}},
                                                  "points": {"a": [0, 0], "b": [1, 0]},
                                                  "members": [{"name": "m", "start": "a", "end": "b",
                                                               "material": "al", "section": "s"}]})
    with pytest.raises(KeyError, match="no joint named 'Z'"):
        frame.joint("Z")


# (description, edit of the valid text, the field and problem the message must name)
MALFORMED = [
    ("not TOML", lambda t: t + "\n[[members]\n", "not valid TOML"),
    ("missing name", lambda t: t.replace('name = "portal"\n', ""), "name: required key is missing"),
    ("unknown top-level key", lambda t: "member = 3\n" + t, "member: unknown key"),
    ("typo in a material key", lambda t: t.replace("youngs_modulus = 70e9", "young_modulus = 70e9"),
     "materials.al.young_modulus: unknown key"),
    ("negative density", lambda t: t.replace("density = 2700.0", "density = -2700.0"),
     "materials.al.density: must be positive"),
    ("NaN modulus", lambda t: t.replace("youngs_modulus = 70e9", "youngs_modulus = nan"),
     "materials.al.youngs_modulus: must be finite"),
    ("string where a number is needed", lambda t: t.replace("area = 2.4e-4", 'area = "big"'),
     "sections.bar.area: expected a number, got string 'big'"),
    ("boolean where a number is needed", lambda t: t.replace("mass = 0.06", "mass = true"),
     "masses[0].mass: expected a number, got boolean true"),
    ("undefined material", lambda t: t.replace('material = "al"', 'material = "steel"', 1),
     "members[0].material: 'steel' is not defined in [materials]"),
    ("undefined point", lambda t: t.replace('end = "top_left"', 'end = "top_middle"', 1),
     "members[0].end: 'top_middle' is not defined in [points]"),
    ("zero-length member", lambda t: t.replace('end = "top_left"', 'end = "base_left"', 1),
     "members[0].end: a member needs two distinct points"),
    ("duplicate member name", lambda t: t.replace('name = "beam"', 'name = "left"'),
     "members[1].name: duplicate member name 'left'"),
    ("point on no member", lambda t: t.replace("drive = [0.0, 0.115]", "drive = [0.1, 0.115]"),
     "points.drive: point 'drive' at [0.1, 0.115] lies on no member"),
    ("joint span beyond its member", lambda t: t.replace("span = [0.44, 0.5]", "span = [0.44, 0.55]"),
     "joints[0].span: [0.44, 0.55] must satisfy 0 <= start < end <= 0.5 m"),
    ("joint span reversed", lambda t: t.replace("span = [0.44, 0.5]", "span = [0.5, 0.44]"),
     "joints[0].span: [0.5, 0.44] must satisfy"),
    ("joint on an unknown member", lambda t: t.replace('member = "left"', 'member = "centre"'),
     "joints[0].member: 'centre' is not defined in [[members]]"),
    ("negative cov", lambda t: t.replace("cov = 0.09", "cov = -0.09"), "joints[0].cov: must not be negative"),
    ("support dof neither fixed, free nor a stiffness",
     lambda t: t.replace('rz = "fixed"', 'rz = "clamped"'),
     "supports[1].rz: 'clamped' is not \"fixed\", \"free\" or a stiffness"),
    ("zero spring stiffness", lambda t: t.replace("stiffness = 1.5e4", "stiffness = 0.0"),
     "springs[0].stiffness: must be positive, got 0"),
    ("unknown dof name", lambda t: t.replace('dof = "ux"\nstiffness', 'dof = "uz"\nstiffness'),
     "springs[0].dof: 'uz' is not one of ux, uy, rz"),
    ("sensor on an undefined point", lambda t: t.replace('point = "top_left"\ndof = "ux"\n\n[damping]',
                                                         'point = "tip"\ndof = "ux"\n\n[damping]'),
     "sensors[0].point: 'tip' is not defined in [points]"),
    ("damping ratio of one", lambda t: t.replace("ratios = [0.005, 0.004]", "ratios = [0.005, 1.0]"),
     "damping.ratios[1]: must be below 1"),
    ("timoshenko without a Poisson ratio", lambda t: 'beam_theory = "timoshenko"\n' + t,
     "materials.al.poisson_ratio: required when beam_theory = \"timoshenko\""),
    ("unknown beam theory", lambda t: 'beam_theory = "reddy"\n' + t,
     "beam_theory: 'reddy' is not one of euler-bernoulli, timoshenko"),
    ("point with three coordinates", lambda t: t.replace("top_right = [0.6, 0.5]", "top_right = [0.6, 0.5, 0.0]"),
     "points.top_right: expected [x, y] in m"),
    ("duplicate joint", lambda t: t + '\n[[joints]]\nname = "A"\nmember = "beam"\nspan = [0.0, 0.05]\n'
                                      'youngs_modulus = 7e10\n', "joints[1].name: duplicate joint name 'A'"),
    ("overlapping joint zones", lambda t: t + '\n[[joints]]\nname = "B"\nmember = "left"\nspan = [0.40, 0.46]\n'
                                              'youngs_modulus = 7e10\n', "joints[1].span: overlaps joint 'A'"),
    ("two supports at one point", lambda t: t + '\n[[supports]]\npoint = "base_left"\nux = "fixed"\n',
     "supports[2].point: point 'base_left' already has a [[supports]] entry"),
]


@pytest.mark.parametrize("edit, expected", [(e, m) for _, e, m in MALFORMED],
                         ids=[d for d, _, _ in MALFORMED])
def test_malformed_frame_is_rejected_with_one_line(tmp_path, edit, expected):
    text = edit(VALID)
    assert text != VALID
    path = write(tmp_path, text)
    with pytest.raises(FrameFileError) as info:
        read_frame(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(str(path) + ": ")
    assert expected in message
    assert path.read_text() == text  # input files are never changed


def test_missing_file_is_one_line(tmp_path):
    with pytest.raises(FrameFileError, match="cannot read the frame file"):
        read_frame(tmp_path / "absent.toml")


def _beam(length: float, element_length: float, supports: list | None = None, **material) -> dict:
    return {"name": "beam", "element_length": element_length,
            "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0, **material}},
            "sections": {"s": {"area": 2.4e-4, "second_moment": 1.28e-9}},
            "points": {"a": [0.0, 0.0], "b": [length, 0.0]},
            "members": [{"name": "m", "start": "a", "end": "b", "material": "al", "section": "s"}],
            "supports": supports if supports is not None else [{"point": "a", "ux": "fixed", "uy": "fixed",
                                                                "rz": "fixed"}]}


def test_the_element_limit_keeps_the_first_mode_near_the_closed_form():
    # the limit's reason: a member cut into 4200 elements still gives the clamped beam's first frequency,
    # (1.87510407^2 / 2 pi) sqrt(EI / rho A L^4), to 1e-5; the limit (5000) sits just above
    from workbench.model.assembly import assemble
    from workbench.model.modal import model_modes
    from workbench.model.sanity import MAX_ELEMENTS_PER_MEMBER

    frame = parse_frame(_beam(4.2, 0.001))
    exact = 1.87510407 ** 2 / (2 * math.pi) * math.sqrt(70e9 * 1.28e-9 / (2700.0 * 2.4e-4 * 4.2 ** 4))
    assert 4200 < MAX_ELEMENTS_PER_MEMBER
    assert model_modes(assemble(frame), 2).frequency_hz[0] == pytest.approx(exact, rel=1e-5)
    with pytest.raises(FrameFileError, match=r"members\[0\].*5001 elements.*mm"):
        parse_frame(_beam(5.001, 0.001))


def test_a_free_free_frame_is_one_piece_with_three_rigid_modes():
    from workbench.model.assembly import assemble
    from workbench.model.modal import model_modes

    modes = model_modes(assemble(parse_frame(_beam(0.5, 0.01, supports=[]))), 5)
    assert modes.frequency_hz[:3] == pytest.approx([0, 0, 0], abs=1e-3)
    assert modes.frequency_hz[3] > 100.0


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["materials"]["al"].__setitem__("youngs_modulus", 70.0), "materials.al.youngs_modulus"),
    (lambda d: d["materials"]["al"].__setitem__("density", 2.7), "materials.al.density"),
    (lambda d: d["sections"]["s"].__setitem__("area", 240.0), "sections.s.area"),
    (lambda d: d["points"].__setitem__("b", [60.0, 0.0]) or d.__setitem__("element_length", 0.05), "members[0]"),
])
def test_values_outside_a_lab_article_warn_naming_the_field(edit, field):
    from workbench.model.sanity import UnitsWarning

    data = _beam(0.42, 0.01)
    edit(data)
    with pytest.warns(UnitsWarning, match=re.escape(field)):
        parse_frame(data)


def test_a_units_warning_is_one_line_and_the_command_still_answers(tmp_path):
    from conftest import dump_toml, run_cli

    data = _beam(0.42, 0.01)
    data["materials"]["al"]["density"] = 2.7  # g/cm3
    data["sensors"] = [{"name": "tip", "point": "b", "dof": "uy"}]
    data["excitation"] = {"point": "b", "dof": "uy"}
    (tmp_path / "frame.toml").write_text(dump_toml(data))
    code, err = run_cli(["modes", str(tmp_path / "frame.toml"), "--out", str(tmp_path / "out")])
    assert code == 0
    warned = [line for line in err.splitlines() if "warning" in line]
    assert len(warned) == 1 and "materials.al.density" in warned[0] and "g/cm3" in warned[0]
