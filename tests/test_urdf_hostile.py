"""The URDF reader on untrusted and broken files (issue 12 §3): no entity expansion, no
external entity, nothing else opened; every error names the file and the line. Issue 20:
non-physical inertias and masses, names appell cannot use (reserved, derived, too long,
odd characters), broken mimics and foreign encodings are refused naming the link or
joint, the line and what to do, on the command line as one error line with a hint."""

from __future__ import annotations

from pathlib import Path

import pytest

from appell.errors import ModelError
from appell.mechanism.urdf import parse_urdf, read_urdf

EXAMPLE = Path(__file__).resolve().parent.parent / "src" / "appell" / "examples" / "arm.urdf"

LINK = (
    '<link name="{}"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
    "</inertial></link>"
)


def _robot(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n</robot>\n'


def test_billion_laughs_is_refused_before_any_expansion():
    """An XML bomb: ten levels of entities each ten times the last (10^10 copies)."""
    levels = ['<!ENTITY l0 "lol">'] + [f'<!ENTITY l{k} "{("&l" + str(k - 1) + ";") * 10}">' for k in range(1, 10)]
    text = '<?xml version="1.0"?>\n<!DOCTYPE robot [\n' + "\n".join(levels) + ']>\n<robot name="&l9;"/>'
    with pytest.raises(ModelError, match="document type declaration") as err:
        parse_urdf(text, "bomb.urdf")
    assert err.value.where == "bomb.urdf:2"


def test_external_entity_cannot_read_another_file(tmp_path):
    """An external entity pointing at /etc/passwd is refused; the error quotes nothing of it."""
    path = tmp_path / "xxe.urdf"
    path.write_text(
        '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/passwd">]>\n'
        '<robot name="r"><link name="&secret;"/></robot>\n'
    )
    with pytest.raises(ModelError, match="document type declaration") as err:
        read_urdf(path)
    assert err.value.where == f"{path}:2"
    assert "root:" not in str(err.value)


def test_undeclared_entity_is_an_xml_error_with_its_line():
    with pytest.raises(ModelError, match="invalid XML: undefined entity") as err:
        parse_urdf(_robot('<link name="a"/>\n<link name="&x;"/>'), "e.urdf")
    assert err.value.where == "e.urdf:4"


def test_missing_mass_names_link_file_and_line():
    text = _robot(
        '<link name="a">\n  <inertial>\n    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>\n'
        "  </inertial>\n</link>"
    )
    with pytest.raises(ModelError, match="link 'a': <inertial> has no <mass>") as err:
        parse_urdf(text, "m.urdf")
    assert err.value.where == "m.urdf:4"


@pytest.mark.parametrize(
    "attribute, message",
    [
        ('xyz="0 0 1x"', "'1x' is not a number"),
        ('xyz="0 0"', "must be 3 number"),
        ('xyz="0 nan 0"', "'nan' is not a finite number"),
    ],
)
def test_malformed_numbers_are_reported_with_their_line(attribute, message):
    text = _robot(
        LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="continuous">\n'
        '  <parent link="a"/><child link="b"/>\n'
        f"  <origin {attribute}/>\n</joint>"
    )
    with pytest.raises(ModelError, match=message) as err:
        parse_urdf(text, "n.urdf")
    assert err.value.where == "n.urdf:7"


@pytest.mark.parametrize(
    "body, message, line",
    [
        (
            LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="screw"><parent link="a"/>'
            '<child link="b"/></joint>',
            "type 'screw'",
            5,
        ),
        (
            LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="fixed"><parent link="a"/>'
            '<child link="c"/></joint>',
            "names the link 'c'",
            5,
        ),
        (LINK.format("a") + "\n" + LINK.format("b"), "2 trees", 4),
        (LINK.format("a") + "\n" + LINK.format("a"), "defined twice", 4),
        ('<xacro:macro name="m"/>', "xacro macro", 3),
        (
            LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="revolute"><parent link="a"/>'
            '<child link="b"/></joint>',
            "has no <limit>",
            5,
        ),
        ('<link name="a"><inertial><mass value="-1"/></inertial></link>', "must be positive", 3),
    ],
)
def test_structural_errors_name_the_culprit(body, message, line):
    with pytest.raises(ModelError, match=message) as err:
        parse_urdf(_robot(body), "s.urdf")
    assert err.value.where == f"s.urdf:{line}"


def test_loop_of_links_is_refused_with_a_hint_to_use_closures():
    body = (
        "\n".join(LINK.format(n) for n in "abc")
        + "\n"
        + "\n".join(
            f'<joint name="{n}" type="continuous"><parent link="{p}"/><child link="{c}"/></joint>'
            for n, p, c in (("j1", "a", "b"), ("j2", "b", "c"), ("j3", "c", "b"))
        )
    )
    with pytest.raises(ModelError, match="child of two joints") as err:
        parse_urdf(_robot(body), "loop.urdf")
    assert "closures" in err.value.hint


def test_meshes_are_never_opened(monkeypatch):
    """The bundled arm names package:// and file:///etc/passwd meshes; reading it opens
    only the URDF itself."""
    import builtins
    import io

    opened = []
    real_open = io.open

    def spy(file, *args, **kwargs):
        opened.append(str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", spy)
    monkeypatch.setattr(io, "open", spy)
    robot = read_urdf(EXAMPLE)
    assert opened == [str(EXAMPLE)]
    assert robot.root == "base"
    assert [j.name for j in robot.joints_from_root()] == ["shoulder", "elbow", "slide", "wrist", "tool_mount"]


def test_arm_description_keeps_origins_axes_and_inertias():
    """Values as written in examples/arm.urdf; the prismatic axis (1, 0.2, 0) is normalised."""
    robot = read_urdf(EXAMPLE)
    slide = next(j for j in robot.joints if j.name == "slide")
    assert slide.type == "prismatic" and slide.parent == "fore" and slide.child == "slider"
    assert slide.xyz == (0.3, 0.0, 0.0) and slide.rpy == (0.0, 0.3, 0.0)
    assert slide.axis == pytest.approx((1 / 1.04**0.5, 0.2 / 1.04**0.5, 0.0))
    assert slide.limits == (-0.1, 0.2, 100.0, 0.5)
    upper = robot.link("upper").inertial
    assert upper.mass == 2.0 and upper.xyz == (0.02, 0.01, 0.2) and upper.rpy == (0.1, -0.2, 0.3)
    assert upper.inertia_matrix[0] == (0.030, 0.001, -0.002)


# ----------------------------------------------------------------------------- issue 20
# Hostile or non-physical content: refused with the link or joint, the file and the line,
# and what to do; never a traceback, never minutes of work.


def _chain(*names: str, inner: dict | None = None) -> str:
    """A base and one link per joint: link ``l<k>`` on line ``4 + 2k``, joint ``names[k]``
    (continuous, about y, child ``l<k>``) on line ``5 + 2k``; ``inner`` adds elements to joints."""
    lines, parent = [LINK.format("base")], "base"
    for k, name in enumerate(names):
        lines += [
            LINK.format(f"l{k}"),
            f'<joint name="{name}" type="continuous"><parent link="{parent}"/>'
            f'<child link="l{k}"/><axis xyz="0 1 0"/>{(inner or {}).get(name, "")}</joint>',
        ]
        parent = f"l{k}"
    return _robot("\n".join(lines))


def _arm(mass: str, inertia: str) -> str:
    """Link ``arm`` with ``<inertial>`` and ``<mass>`` on line 5 and ``<inertia>`` on line 6."""
    return _robot(
        LINK.format("base") + '\n<link name="arm">\n  <inertial><mass value="' + mass + '"/>\n'
        f"  <inertia {inertia}/></inertial>\n</link>\n"
        '<joint name="j" type="continuous"><parent link="base"/><child link="arm"/></joint>'
    )


def _inertia(xx, yy, zz, xy=0, xz=0, yz=0) -> str:
    return f'ixx="{xx}" ixy="{xy}" ixz="{xz}" iyy="{yy}" iyz="{yz}" izz="{zz}"'


@pytest.mark.parametrize(
    "mass, inertia, message, line",
    [
        ("1", _inertia(1, 1, 1, xy=2), r"not positive semi-definite \(a principal moment is -1\)", 5),
        ("1", _inertia(1, 1, 3), "principal moments 1, 1, 3 violate the triangle inequality", 5),
        # the diagonal alone passes; the products of inertia make the principal moments 0.5, 0.5, 2
        ("1", _inertia(1, 1, 1, 0.5, 0.5, 0.5), "principal moments 0.5, 0.5, 2 violate the triangle", 5),
        ("-1", _inertia(1, 1, 1), "mass -1.0 must be positive", 5),
        ("0", _inertia(1, 1, 1), "mass 0 with a non-zero inertia", 5),
        ("inf", _inertia(1, 1, 1), "'inf' is not a finite number", 5),
        ("1", _inertia(1, "nan", 1), "'nan' is not a finite number", 6),
    ],
)
def test_non_physical_mass_or_inertia_names_the_link(mass, inertia, message, line):
    with pytest.raises(ModelError, match=message) as err:
        parse_urdf(_arm(mass, inertia), "i.urdf")
    assert "'arm'" in err.value.message and err.value.where == f"i.urdf:{line}"
    assert err.value.hint


def test_a_rounding_sized_product_of_inertia_is_not_refused():
    """iCub's head (example-robot-data) has a zero diagonal beside ixy = 2.4e-35: principal
    moments +-2.4e-35, inside MuJoCo's floor of 1e-15 kg m^2; a product of 1e-9 is not."""
    link = parse_urdf(_arm("1", _inertia(0, 0, 0, xy=2.4e-35)), "i.urdf").link("arm")
    assert link.inertial is not None
    with pytest.raises(ModelError, match="not positive semi-definite"):
        parse_urdf(_arm("1", _inertia(0, 0, 0, xy=1e-9)), "i.urdf")


def test_mass_zero_and_inertia_zero_is_a_massless_frame():
    """Robot files write tool and sensor frames as mass 0, inertia 0: such a link is massless
    (as without <inertial>) and merged into its parent when fixed to it; on a moving joint
    with nothing beyond it, it is refused as a massless link."""
    from appell.mechanism.urdf import urdf_system

    frame = '<link name="tool"><inertial><mass value="0"/><inertia ' + _inertia(0, 0, 0) + "/></inertial></link>"
    text = _chain("j").replace(
        "\n</robot>",
        f'\n{frame}\n<joint name="tcp" type="fixed"><parent link="l0"/><child link="tool"/></joint>\n</robot>',
    )
    robot = parse_urdf(text, "f.urdf")
    assert robot.link("tool").inertial is None
    assert [q.name for q in urdf_system(robot).coordinates] == ["j"]
    with pytest.raises(ModelError, match="link 'tool' has no <inertial>: nothing moves with joint 'tcp'"):
        urdf_system(parse_urdf(text.replace('type="fixed"', 'type="continuous"'), "f.urdf"))


def test_the_root_links_inertia_is_not_used_nor_checked():
    """The root link is the ground: a placeholder inertia there (robot files write
    ixx = ixy = ... = 1e-6) changes nothing and is not refused."""
    text = _chain("j").replace(LINK.format("base"), LINK.format("base").replace('ixy="0"', 'ixy="3"'), 1)
    assert parse_urdf(text, "r.urdf").root == "base"


@pytest.mark.parametrize(
    "name, message",
    [
        ("sin", "joint name 'sin' is reserved"),
        ("pi", "joint name 'pi' is reserved"),
        ("E", "joint name 'E' is reserved"),
        ("t", "joint name 't' is reserved"),
        ("a__b", "joint name 'a__b' is not valid"),
        ("7up", r"joint '7up' \(named '_7up' in appell\): joint name '_7up' is not valid"),
        ("\u00e9lan", "joint name '_lan' is not valid"),
        ("lambda_c", "names starting with lambda_, control_, residual_ are those of result columns"),
        ("residual_c", "are those of result columns"),
    ],
)
def test_reserved_and_invalid_joint_names_are_refused(name, message):
    from appell.mechanism.urdf import urdf_system

    with pytest.raises(ModelError, match=message) as err:
        urdf_system(parse_urdf(_chain("a", name), "n.urdf"))
    assert f"joint {name!r}" in err.value.message and err.value.where == "n.urdf:7"
    assert "rename the joint" in err.value.hint


@pytest.mark.parametrize(
    "first, second, message",
    [
        ("x", "x_dot", "the name 'x_dot' is used twice: as a coordinate and as a speed"),
        ("x_dot", "x", "the name 'x_dot' is used twice"),
        ("x", "x_ddot", "'x_ddot' is reserved: it is the name of the second time derivative of the coordinate 'x'"),
        ("a", "F_a_x", "its column 'F_a_x' is the reaction column of joint 'a'"),
    ],
)
def test_a_joint_named_like_another_joints_derived_names_is_refused(first, second, message):
    from appell.mechanism.urdf import urdf_system

    with pytest.raises(ModelError, match=message) as err:
        urdf_system(parse_urdf(_chain(first, second), "d.urdf"))
    culprit = "x_dot" if "x_dot" in (first, second) else second
    line = 5 if culprit == first else 7
    assert err.value.message.startswith(f"joint {culprit!r}") and err.value.where == f"d.urdf:{line}"


def test_a_reserved_link_name_is_refused():
    from appell.mechanism.urdf import urdf_system

    with pytest.raises(ModelError, match="link 'cos': link name 'cos' is reserved") as err:
        urdf_system(parse_urdf(_chain("a").replace('"l0"', '"cos"'), "l.urdf"))
    assert err.value.where == "l.urdf:4"


def test_urdf_names_follow_the_model_files_rule():
    """URDF and model files apply the one name rule of appell.symbols: both accept and refuse
    the same names; a model file's name with a trailing newline is refused (its pattern once
    took "x\\n"; URDF maps the newline to '_')."""
    from appell.io.modelfile.loader import _Reader
    from appell.mechanism import urdf
    from appell.symbols import RESERVED_NAMES

    for name in sorted(RESERVED_NAMES) + ["x", "x1", "a_b", "a__b", "_a", "A9_", "x" * 64, "x" * 65, "I", "g2"]:
        try:
            _Reader("", "m.toml").name((), name, "joint")
            model_file = True
        except ModelError:
            model_file = False
        try:
            urdf._appell_name(name, "joint", "j.urdf:1")
            in_urdf = True
        except ModelError:
            in_urdf = False
        assert in_urdf == model_file, name
    with pytest.raises(ModelError, match="is not valid"):
        _Reader("", "m.toml").name((), "x\n", "coordinate")


@pytest.mark.parametrize("place", ["joint", "link", "parent"])
def test_a_ten_million_character_name_is_refused_at_once(place):
    """Refused before any other work (measured: well under a second); the message shows the
    start of the name and its length, not the name."""
    long = "q" * 10_000_000
    text = _chain("a")
    text = {
        "joint": text.replace('name="a"', f'name="{long}"'),
        "link": text.replace('<link name="l0">', f'<link name="{long}">'),
        "parent": text.replace('<parent link="base"/>', f'<parent link="{long}"/>'),
    }[place]
    with pytest.raises(ModelError, match="a name has at most 64 characters") as err:
        parse_urdf(text, "long.urdf")
    assert "(10000000 characters)" in err.value.message and len(str(err.value)) < 400
    assert err.value.where == f"long.urdf:{4 if place == 'link' else 5}"


def test_slashes_quotes_and_spaces_in_names_become_underscores():
    """Characters other than ASCII letters, digits and _ never reach an appell name (and
    so no generated code or file name): each becomes _."""
    from appell.mechanism.urdf import urdf_system

    text = _chain("arm/1 x").replace('"l0"', '"fore&quot;arm/L"')
    system = urdf_system(parse_urdf(text, "c.urdf"))
    assert [q.name for q in system.coordinates] == ["arm_1_x"]
    assert [b.name for b in system.bodies] == ["fore_arm_L"]
    names = [s.name for s in system.coordinates + system.speeds] + [o.name for o in system.outputs]
    assert all(n.isascii() and n.isidentifier() for n in names), names


@pytest.mark.parametrize(
    "text, message, line",
    [
        (_chain("a b", "a/b"), "joint 'a/b' and joint 'a b' have the same appell name 'a_b'", 7),
        (_chain("a").replace('"l0"', '"arm /L"'), r"link 'arm /L' \(named 'arm__L' in appell\)", 4),
    ],
)
def test_names_that_would_clash_or_double_an_underscore_are_refused(text, message, line):
    from appell.mechanism.urdf import urdf_system

    with pytest.raises(ModelError, match=message) as err:
        urdf_system(parse_urdf(text, "c.urdf"))
    assert err.value.where == f"c.urdf:{line}"


@pytest.mark.parametrize(
    "old, new, line",
    [
        ('<joint name="a"', '<joint name="a&#1;b"', 5),  # a control character in a joint name
        ('<link name="l0"', '<link name="l&#0;"', 4),  # NUL in a link name
        ('<link name="l0"', '<link name="l\x00"', 4),  # a raw NUL byte
    ],
)
def test_control_characters_in_names_are_invalid_xml(old, new, line):
    with pytest.raises(ModelError, match="invalid XML") as err:
        parse_urdf(_chain("a").replace(old, new), "x.urdf")
    assert err.value.where == f"x.urdf:{line}"


@pytest.mark.parametrize(
    "inner, message, line",
    [
        ({"a": '<mimic joint="b"/>', "b": '<mimic joint="a"/>'}, "the mimic joints 'a' -> 'b' -> 'a' form a cycle", 5),
        ({"b": '<mimic joint="c"/>', "c": '<mimic joint="b"/>'}, "the mimic joints 'b' -> 'c' -> 'b' form a cycle", 7),
        ({"a": '<mimic joint="a"/>'}, "joint 'a' mimics itself", 5),
        ({"b": '<mimic joint="zz"/>'}, "joint 'b' mimics 'zz', which is not a joint of the file", 7),
        ({"b": '<mimic joint="a" multiplier="nan"/>'}, r"'b': <mimic multiplier='nan'>: 'nan' is not a finite", 7),
        ({"b": '<mimic joint="a" offset="-inf"/>'}, r"'b': <mimic offset='-inf'>: '-inf' is not a finite", 7),
    ],
)
def test_broken_mimics_name_the_joints(inner, message, line):
    with pytest.raises(ModelError, match=message) as err:
        parse_urdf(_chain("a", "b", "c", inner=inner), "m.urdf")
    assert err.value.where == f"m.urdf:{line}"


def test_a_mimic_of_a_fixed_joint_is_refused_and_a_chain_of_mimics_is_two_constraints():
    from appell.mechanism.urdf import urdf_mechanism

    chain = _chain("a", "b", "c", inner={"b": '<mimic joint="a" multiplier="2"/>', "c": '<mimic joint="b"/>'})
    _, constraints = urdf_mechanism(parse_urdf(chain, "m.urdf"))
    assert [(c.name, str(c.expr)) for c in constraints] == [("b_mimic", "-2.0*a + b"), ("c_mimic", "-1.0*b + c")]
    text = _chain("a", "b", inner={"b": '<mimic joint="a"/>'}).replace(
        'name="a" type="continuous"', 'name="a" type="fixed"'
    )
    with pytest.raises(ModelError, match="joint 'b' mimics 'a', but 'a' is a fixed joint") as err:
        urdf_mechanism(parse_urdf(text, "m.urdf"))
    assert err.value.where == "m.urdf:7"


def test_a_mimic_on_a_fixed_joint_is_not_applied_with_a_note():
    """Talos' gripper files put <mimic> on fixed joints: the joint does not move, so nothing is
    coupled; said, not refused (issue 22)."""
    from appell.errors import AppellNote
    from appell.mechanism.urdf import urdf_mechanism

    text = _chain("a", "b", inner={"b": '<mimic joint="a"/>'}).replace(
        'name="b" type="continuous"', 'name="b" type="fixed"'
    )
    assert 'name="b" type="fixed"' in text
    with pytest.warns(AppellNote, match=r"<mimic> on 1 fixed joint \(b\) not applied"):
        mech, constraints = urdf_mechanism(parse_urdf(text, "m.urdf"))
    assert constraints == () and [j.name for j in mech.joints if j.kind != "fixed"] == ["a"]


LATIN1 = (
    '<?xml version="1.0" encoding="{}"?>\n<!-- Gelenk f\u00fcr den Arm -->\n<robot name="caf\u00e9">\n'
    '<link name="bas\u00e9"/>\n' + LINK.format("arm") + "\n"
    '<joint name="j" type="continuous"><parent link="bas\u00e9"/><child link="arm"/></joint>\n</robot>\n'
)


@pytest.mark.parametrize(
    "declared, codec",
    [("ISO-8859-1", "latin-1"), ("UTF-16", "utf-16"), ("windows-1252", "cp1252"), ("UTF-8", "utf-8-sig")],
)
def test_a_declared_encoding_is_honoured(tmp_path, declared, codec):
    """The file is read as bytes and expat decodes it as its declaration (and BOM) says."""
    path = tmp_path / "enc.urdf"
    path.write_bytes(LATIN1.format(declared).encode(codec))
    robot = read_urdf(path)
    assert robot.name == "caf\u00e9" and robot.root == "bas\u00e9"
    assert [j.name for j in robot.joints] == ["j"]


@pytest.mark.parametrize(
    "data, message, line",
    [
        (LATIN1.format("klingon").encode("latin-1"), r"encoding that is not read \(unknown encoding: klingon\)", 1),
        (b'<?xml version="1.0" encoding="Shift_JIS"?>\n<robot name="r"/>\n', "encoding that is not read", 1),
        (LATIN1.format("UTF-8").encode("latin-1"), r"invalid XML: not well-formed \(invalid token\)", 2),
        (_robot(LINK.format("a")).encode() + b"<!-- \xff\xfe -->\n", r"not well-formed \(invalid token\)", 5),
        (LATIN1.format("UTF-16").encode("utf-8"), "encoding specified in XML declaration is incorrect", 1),
    ],
)
def test_an_unreadable_encoding_or_invalid_bytes_are_refused_with_the_line(tmp_path, data, message, line):
    path = tmp_path / "bad.urdf"
    path.write_bytes(data)
    with pytest.raises(ModelError, match=message) as err:
        read_urdf(path)
    assert err.value.where == f"{path}:{line}" and "UTF-8" in err.value.hint


@pytest.mark.parametrize(
    "content, line",
    [
        (_arm("1", _inertia(1, 1, 3)).encode(), 5),
        (_chain("a", "sin").encode(), 7),
        (_chain("x", "x_dot").encode(), 7),
        (_chain("q" * 10_000_000).encode(), 5),
        (_chain("a").replace('"l0"', '"l&#1;"').encode(), 4),
        (_chain("a", "b", inner={"a": '<mimic joint="b"/>', "b": '<mimic joint="a"/>'}).encode(), 5),
        (LATIN1.format("klingon").encode("latin-1"), 1),
        (b'<?xml version="1.0"?>\n<robot name="\xff"/>\n', 2),
    ],
)
def test_the_command_line_prints_one_error_line_with_a_hint_and_exits_2(tmp_path, content, line):
    from click.testing import CliRunner

    from appell.io.cli import cli

    path = tmp_path / "hostile.urdf"
    path.write_bytes(content)
    result = CliRunner().invoke(cli, ["derive", str(path)])
    lines = result.output.splitlines()
    assert result.exit_code == 2, result.output
    assert [k for k, text in enumerate(lines) if text.startswith("error:")] == [0], result.output
    assert lines[0].startswith(f"error: {path}:{line}: ") and lines[1].startswith("  hint: "), result.output
    assert len(lines) == 2 and "Traceback" not in result.output and "internal error" not in result.output


def test_what_a_urdf_holds_beyond_the_mechanism_is_noted_not_refused(tmp_path):
    """Transmissions, simulator tags and joint damping change a robot's motion elsewhere;
    appell does not apply them, so it says so: an AppellNote in Python, a 'note:' line on
    the command line, exit 0 (issue 22 §3). Materials and a zero <dynamics> stay silent."""
    import warnings

    from click.testing import CliRunner

    from appell.errors import AppellNote
    from appell.io.cli import cli
    from appell.mechanism.urdf import urdf_system

    text = (
        _chain("j")
        .replace(
            "\n</robot>",
            """
<transmission name="t1"><type>transmission_interface/SimpleTransmission</type></transmission>
<transmission name="t2"><type>transmission_interface/SimpleTransmission</type></transmission>
<gazebo reference="l0"><mu1>0.2</mu1></gazebo>
<material name="blue"><color rgba="0 0 1 1"/></material>
</robot>""",
        )
        .replace("</joint>", '<dynamics damping="0.3" friction="0"/></joint>', 1)
    )
    path = tmp_path / "noted.urdf"
    path.write_text(text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        urdf_system(path)
    notes = [str(w.message) for w in caught if issubclass(w.category, AppellNote)]
    assert notes == [
        f"{path}: 1 joint <dynamics> (damping, friction) not applied: add them as [[loads]] or "
        "actuator torques in a model file",
        f"{path}: 2 <transmission> elements not read (actuator models; apply joint torques with actuators instead)",
        f"{path}: 1 <gazebo> element not read (simulator plug-ins and surface properties)",
    ]
    result = CliRunner().invoke(cli, ["derive", str(path)])
    assert result.exit_code == 0, result.output
    assert result.stderr.count("note: ") == 3 and "2 <transmission> elements" in result.stderr
    quiet = tmp_path / "quiet.urdf"
    quiet.write_text(_chain("j"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        urdf_system(quiet)
    assert not [w for w in caught if issubclass(w.category, AppellNote)]


def test_a_frame_composed_near_a_pitch_of_90_degrees_keeps_every_digit(tmp_path):
    """A massless link fixed by roll, pitch and yaw with the pitch 1e-7 rad short of 90 degrees,
    then a hinge: the arm's mass centre at zero angle equals the product of the two origins'
    transforms (NumPy, as Pinocchio composes them) to 1e-14 m (issue 22: "roll-pitch-yaw angles
    near right angles lose digits"). The merged link's rotation now reaches the builder as the
    matrix itself; the earlier round trip through angles read back from it was measured exact
    to rounding too (2.8e-17 at 1e-12 rad from 90 degrees), as near gimbal lock only the sum of
    roll and yaw is ill-conditioned and the matrix depends on nothing else."""
    import numpy as np

    from appell.mechanism.urdf import urdf_system

    pitch = np.pi / 2 - 1e-7
    (tmp_path / "tilt.urdf").write_text(f"""<robot name="tilt">
  <link name="base"/>
  <link name="mount"/>
  <link name="arm"><inertial><origin xyz="1 0 0"/><mass value="1"/>
    <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="tilt" type="fixed"><parent link="base"/><child link="mount"/>
    <origin xyz="0 0 0" rpy="0.2 {pitch!r} 0.3"/></joint>
  <joint name="hinge" type="revolute"><parent link="mount"/><child link="arm"/>
    <origin xyz="0.1 0.2 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>""")
    system = urdf_system(tmp_path / "tilt.urdf")

    def rpy(r, p, y):
        cx, sx, cy, sy, cz, sz = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        return Rz @ Ry @ Rx

    expected = rpy(0.2, pitch, 0.3) @ (np.array([0.1, 0.2, 0.3]) + np.array([1.0, 0, 0]))
    arm = next(b for b in system.bodies if b.name == "arm")
    got = np.array(arm.position.subs({q: 0 for q in system.coordinates}).evalf(), float).ravel()
    assert np.abs(got - expected).max() < 1e-14
