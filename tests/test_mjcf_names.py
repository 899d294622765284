"""MJCF names that are not identifiers (issue 41 part 1: "any name MJCF allows is read (a name
that is not an identifier is mapped to one, and every output, table and message shows the
original)"). A four-bar written as Menagerie writes names (``crank-joint``, ``knee-loop``,
``crank-motor``) is simulated and inverted on the command line beside the same file with plain
names: every column and message shows the hyphenated names, never the identifiers they are
mapped to, the trajectory's columns are read by them, and the numbers are those of the plain
file (whose inverse dynamics tests/test_inverse.py checks against MuJoCo's blocks)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from click.testing import CliRunner

from appell.io.cli import cli
from test_inverse import _read_csv, _write_csv

mujoco = pytest.importorskip("mujoco")

#: the plain four-bar's names -> as a Menagerie file might spell them
RENAMED = {
    "crank": "crank-link",
    "coupler": "coupler-link",
    "rocker": "rocker-link",
    "A": "crank-joint",
    "B": "coupler-joint",
    "D": "rocker-joint",
    "C": "knee-loop",
    "drive": "crank-motor",
    "pull": "tendon-pull",
    "sum": "sum-tendon",
}
#: what appell maps them to (never to be seen in a table or message)
MAPPED = {name.replace("-", "_") for name in RENAMED.values()}


def _files(tmp_path):
    from test_mjcf_menagerie import closed_four_bar

    plain, _ = closed_four_bar()
    hyphen = plain
    for old, new in RENAMED.items():
        hyphen = re.sub(rf'((?:name|joint|body1|body2|tendon)=")({old})(")', rf"\g<1>{new}\g<3>", hyphen)
    assert hyphen.count("-link") == 5 and "crank-joint" in hyphen
    (tmp_path / "plain.xml").write_text(plain)
    (tmp_path / "hyphen.xml").write_text(hyphen)
    return tmp_path / "plain.xml", tmp_path / "hyphen.xml"


def _as_shown(name: str) -> str:
    """A plain file's column as the hyphenated file's should read: each name between
    underscores (or the ends) renamed."""
    if name.startswith("drive_"):  # the column's prefix, not the actuator 'drive'
        return "drive_" + _as_shown(name[len("drive_") :])
    return "_".join(RENAMED.get(part, part) for part in name.split("_")) if name != "t" else name


def _check_no_identifier(text: str):
    for ident in MAPPED:
        assert not re.search(
            rf"(?<![A-Za-z0-9-]){ident}(?![A-Za-z0-9])", text.replace("->", " ").split("names mapped to identifiers")[0]
        ), ident


def test_inverse_reads_and_shows_the_files_names(tmp_path):
    plain, hyphen = _files(tmp_path)
    t = np.linspace(0.0, 0.5, 11)
    crank = 0.4 * np.sin(2 * t)
    runner = CliRunner()
    outs = {}
    for model, column, drive in ((plain, "A", "drive"), (hyphen, "crank-joint", "crank-motor")):
        motion = _write_csv(tmp_path / f"{model.stem}-motion.csv", {"t": t, column: crank})
        out = tmp_path / f"{model.stem}-out.csv"
        result = runner.invoke(
            cli,
            [
                "inverse",
                str(model),
                "--trajectory",
                str(motion),
                "--mjcf",
                "actuators=controls",
                "--drive",
                drive,
                "--out",
                str(out),
            ],
        )
        assert result.exit_code == 0, result.output
        outs[model.stem] = (_read_csv(out), result.output, out.read_text().splitlines()[0])
    ref, _, _ = outs["plain"]
    got, text, header = outs["hyphen"]
    assert {"crank-joint_ddot", "drive_crank-motor", "lambda_knee-loop_x", "F_rocker-joint_y"} <= set(got)
    assert "given crank-joint; completed from the loops: coupler-joint, rocker-joint" in text
    _check_no_identifier(header)
    _check_no_identifier(text)
    assert set(got) == {_as_shown(n) for n in ref}
    for name, values in ref.items():
        assert np.array_equal(got[_as_shown(name)], values), name
    # a message naming the model's coordinates names them as the file does
    motion = _write_csv(tmp_path / "both.csv", {"t": t, "crank-joint": crank, "rocker-joint": crank})
    result = runner.invoke(cli, ["inverse", str(hyphen), "--trajectory", str(motion), "--out", str(tmp_path / "x.csv")])
    assert result.exit_code == 2 and "crank-joint, rocker-joint are not independent" in result.output
    _check_no_identifier(result.output)


def test_simulate_writes_the_files_names(tmp_path):
    """The CSV, HDF5 and netCDF files of ``appell simulate`` name every column as the MJCF file does."""
    plain, hyphen = _files(tmp_path)
    tables = {}
    for model in (plain, hyphen):
        out = tmp_path / f"{model.stem}-sim.csv"
        result = CliRunner().invoke(cli, ["simulate", str(model), "--t-end", "0.05", "--out", str(out)])
        assert result.exit_code == 0, result.output
        tables[model.stem] = (_read_csv(out), out.read_text().splitlines()[0])
    ref, _ = tables["plain"]
    got, header = tables["hyphen"]
    assert {"crank-joint", "coupler-joint_dot", "lambda_knee-loop_x", "F_crank-joint_x"} <= set(got)
    _check_no_identifier(header)
    assert set(got) == {_as_shown(n) for n in ref}
    for name, values in ref.items():
        assert np.allclose(got[_as_shown(name)], values, rtol=1e-12, atol=1e-12), name
    h5py = pytest.importorskip("h5py")
    out = tmp_path / "hyphen-sim.h5"
    assert CliRunner().invoke(cli, ["simulate", str(hyphen), "--t-end", "0.05", "--out", str(out)]).exit_code == 0
    with h5py.File(out) as f:
        assert {"crank-joint", "coupler-joint_dot"} <= set(f["states"]) and "F_crank-joint_x" in f["outputs"]
        assert "knee-loop_x" in f["multipliers"] and "rocker-joint" in list(f.attrs["coordinate_names"])
        _check_no_identifier(" ".join(list(f["states"]) + list(f["outputs"]) + list(f["multipliers"])))
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    out = tmp_path / "hyphen-sim.nc"
    assert CliRunner().invoke(cli, ["simulate", str(hyphen), "--t-end", "0.05", "--out", str(out)]).exit_code == 0
    with xr.open_dataset(out) as ds:
        assert {"crank-joint", "lambda_knee-loop_x", "F_rocker-joint_y"} <= set(ds.data_vars)
        _check_no_identifier(" ".join(map(str, ds.data_vars)))
