"""The importer registry (appell.mechanism.formats, issue 21 item 7): the loader, the command
line and the [mechanism] table read a format through its one entry, so that a new format is
one entry, and a format's rules (floating base, suffixes in any case) hold everywhere."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

import appell
from appell.errors import ModelError
from appell.mechanism import formats
from appell.mechanism.formats import IMPORTERS, Importer, described, importer_for

EXAMPLES = Path(appell.__file__).parent / "examples"


def test_every_suffix_has_one_importer():
    assert importer_for("robot.URDF").name == "URDF" and importer_for("a/b.xml").name == "MJCF"
    assert importer_for("model.toml") is None
    assert len(formats.suffixes()) == len(set(formats.suffixes()))
    assert importer_for("gripper.sdf").name == "SDF"
    assert described() == (
        "a model file (.toml), a robot description (.urdf), a MuJoCo model (.xml, .mjcf) or an SDFormat model (.sdf)"
    )


def test_a_new_format_is_one_entry(tmp_path, monkeypatch):
    """A format registered in IMPORTERS is read by appell.load_model and by every command,
    with --set applied: here a '.pend' file whose reader returns the bundled pendulum."""
    from appell.io.cli import cli

    def read(path, floating_base):
        assert path.read_text() == "a pendulum"
        return appell.load_model("pendulum")

    monkeypatch.setattr(formats, "IMPORTERS", IMPORTERS + (Importer("PEND", (".pend",), "a pendulum file", read),))
    source = tmp_path / "one.pend"
    source.write_text("a pendulum")
    system = appell.load_model(source, {"m": 2.5})
    assert system.name == "pendulum" and dict((p.symbol.name, p.value) for p in system.parameters)["m"] == 2.5
    result = CliRunner().invoke(cli, ["derive", str(source), "--only", "reactions"])
    assert result.exit_code == 0, result.output + result.stderr
    assert "lambda_rod" in result.output
    with pytest.raises(ModelError, match=r"does not apply to a pendulum file \(PEND\)"):
        appell.load_model(source, floating_base=True)


def test_the_mechanism_table_reads_a_urdf_through_its_entry(tmp_path, monkeypatch):
    """[mechanism] urdf = ... reads the robot by the URDF entry's mechanism reader."""
    seen = []
    urdf = next(imp for imp in IMPORTERS if imp.name == "URDF")

    def spy(path, floating_base):
        seen.append(Path(path).name)
        return urdf.mechanism(path, floating_base)

    patched = tuple(
        Importer(
            i.name, i.suffixes, i.what, i.system, spy if i is urdf else i.mechanism, i.key, i.floating_base, i.extra
        )
        for i in IMPORTERS
    )
    monkeypatch.setattr(formats, "IMPORTERS", patched)
    (tmp_path / "arm.urdf").write_text((EXAMPLES / "arm.urdf").read_text())
    model = tmp_path / "on_a_table.toml"
    model.write_text('[model]\nname = "on_a_table"\n[mechanism]\nurdf = "arm.urdf"\nreactions = "none"\n')
    system = appell.load_model(model)
    assert seen == ["arm.urdf"] and len(system.coordinates) > 0
