"""The URDF reader on untrusted and broken files (issue 12 §3): no entity expansion, no
external entity, nothing else opened; every error names the file and the line."""

from __future__ import annotations

from pathlib import Path

import pytest

from appell.errors import ModelError
from appell.mechanism.urdf import parse_urdf, read_urdf

EXAMPLE = Path(__file__).resolve().parent.parent / "src" / "appell" / "examples" / "arm.urdf"

LINK = '<link name="{}"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>' \
       '</inertial></link>'


def _robot(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n</robot>\n'


def test_billion_laughs_is_refused_before_any_expansion():
    """An XML bomb: ten levels of entities each ten times the last (10^10 copies)."""
    levels = ['<!ENTITY l0 "lol">'] + [f'<!ENTITY l{k} "{("&l%d;" % (k - 1)) * 10}">' for k in range(1, 10)]
    text = '<?xml version="1.0"?>\n<!DOCTYPE robot [\n' + "\n".join(levels) + ']>\n<robot name="&l9;"/>'
    with pytest.raises(ModelError, match="document type declaration") as err:
        parse_urdf(text, "bomb.urdf")
    assert err.value.where == "bomb.urdf:2"


def test_external_entity_cannot_read_another_file(tmp_path):
    """An external entity pointing at /etc/passwd is refused; the error quotes nothing of it."""
    path = tmp_path / "xxe.urdf"
    path.write_text('<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY secret SYSTEM "file:///etc/passwd">]>\n'
                    '<robot name="r"><link name="&secret;"/></robot>\n')
    with pytest.raises(ModelError, match="document type declaration") as err:
        read_urdf(path)
    assert err.value.where == f"{path}:2"
    assert "root:" not in str(err.value)


def test_undeclared_entity_is_an_xml_error_with_its_line():
    with pytest.raises(ModelError, match="invalid XML: undefined entity") as err:
        parse_urdf(_robot('<link name="a"/>\n<link name="&x;"/>'), "e.urdf")
    assert err.value.where == "e.urdf:4"


def test_missing_mass_names_link_file_and_line():
    text = _robot('<link name="a">\n  <inertial>\n    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>\n'
                  '  </inertial>\n</link>')
    with pytest.raises(ModelError, match="link 'a': <inertial> has no <mass>") as err:
        parse_urdf(text, "m.urdf")
    assert err.value.where == "m.urdf:4"


@pytest.mark.parametrize("attribute, message", [
    ('xyz="0 0 1x"', "'1x' is not a number"),
    ('xyz="0 0"', "must be 3 number"),
    ('xyz="0 nan 0"', "'nan' is not a finite number"),
])
def test_malformed_numbers_are_reported_with_their_line(attribute, message):
    text = _robot(LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="continuous">\n'
                  '  <parent link="a"/><child link="b"/>\n'
                  f'  <origin {attribute}/>\n</joint>')
    with pytest.raises(ModelError, match=message) as err:
        parse_urdf(text, "n.urdf")
    assert err.value.where == "n.urdf:7"


@pytest.mark.parametrize("body, message, line", [
    (LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="screw"><parent link="a"/>'
     '<child link="b"/></joint>', "type 'screw'", 5),
    (LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="fixed"><parent link="a"/>'
     '<child link="c"/></joint>', "names the link 'c'", 5),
    (LINK.format("a") + "\n" + LINK.format("b"), "2 trees", 4),
    (LINK.format("a") + "\n" + LINK.format("a"), "defined twice", 4),
    ('<xacro:macro name="m"/>', "xacro macro", 3),
    (LINK.format("a") + "\n" + LINK.format("b") + '\n<joint name="j" type="revolute"><parent link="a"/>'
     '<child link="b"/></joint>', "has no <limit>", 5),
    ('<link name="a"><inertial><mass value="-1"/></inertial></link>', "must be positive", 3),
])
def test_structural_errors_name_the_culprit(body, message, line):
    with pytest.raises(ModelError, match=message) as err:
        parse_urdf(_robot(body), "s.urdf")
    assert err.value.where == f"s.urdf:{line}"


def test_loop_of_links_is_refused_with_a_hint_to_use_closures():
    body = "\n".join(LINK.format(n) for n in "abc") + "\n" + "\n".join(
        f'<joint name="{n}" type="continuous"><parent link="{p}"/><child link="{c}"/></joint>'
        for n, p, c in (("j1", "a", "b"), ("j2", "b", "c"), ("j3", "c", "b")))
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
