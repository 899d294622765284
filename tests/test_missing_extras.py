"""A missing optional package is refused with the package (and the extra of pyproject.toml
that brings it) to install, never "internal error ... this is a bug" (issue 45). Each case
hides the module in a child process (``sys.modules[name] = None``: its import raises
ModuleNotFoundError as if it were not installed) and runs the command line or the API there.

Every refusal ends the command with one exit code, that of
:class:`~appell.errors.MissingDependencyError` (1: the environment lacks a package, as
io/cli.py's docstring states), whichever package is missing.

Source of truth: pyproject.toml's ``[project.optional-dependencies]`` (``sweep`` brings dask,
``mjcf`` brings mujoco, ``control`` brings python-control) and its dependencies (h5py,
h5netcdf)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from processes import env_with_src

TINY_MJCF = """<mujoco model="tiny">
  <worldbody>
    <body name="bob" pos="0 0 0">
      <joint name="swing" type="hinge" axis="0 1 0"/>
      <geom type="sphere" size="0.1" mass="1" pos="0 0 -1"/>
    </body>
  </worldbody>
</mujoco>
"""

RUN = """
import sys
for name in {hidden!r}:
    sys.modules[name] = None  # as if the package were not installed
{body}
"""

COMMAND = "from appell.io.cli import main\nsys.exit(main({args!r}, standalone=False))"


def _run(hidden, body, cwd):
    done = subprocess.run(
        [sys.executable, "-c", RUN.format(hidden=list(hidden), body=textwrap.dedent(body))],
        capture_output=True,
        text=True,
        timeout=600,
        env=env_with_src(),
        cwd=cwd,
    )
    return done.returncode, done.stdout, done.stderr


def _refused(code, err, wanted):
    from appell.errors import MissingDependencyError

    assert code == MissingDependencyError.exit_code == 1, err
    assert wanted in err, err
    assert "internal error" not in err and "Traceback" not in err and "this is a bug" not in err, err


@pytest.mark.parametrize(
    "args",
    [["sweep", "pendulum", "--param", "m=1:2:2", "--t-end", "0.1"], ["cluster", "--workers", "1", "--port", "0"]],
    ids=["sweep", "cluster"],
)
def test_a_sweep_without_dask_names_the_extra(args, tmp_path):
    code, _, err = _run(["dask", "distributed"], COMMAND.format(args=args), tmp_path)
    _refused(code, err, "pip install 'appell[sweep]'")
    assert list(tmp_path.iterdir()) == []  # no dataset, no partial file


def test_the_sweep_api_without_dask_raises_missing_dependency(tmp_path):
    body = """
    import appell
    from appell.errors import MissingDependencyError
    try:
        appell.sweep(appell.load_model("pendulum"), ["m=1:2:2"], 0.1, progress=False)
    except MissingDependencyError as exc:
        print(exc)
    """
    code, out, err = _run(["dask", "distributed"], body, tmp_path)
    assert code == 0, err
    assert "needs the optional package 'dask'" in out and "appell[sweep]" in out


def test_a_mujoco_model_without_mujoco_names_the_extra(tmp_path):
    (tmp_path / "tiny.xml").write_text(TINY_MJCF)
    code, _, err = _run(["mujoco"], COMMAND.format(args=["simulate", "tiny.xml", "--t-end", "0.01"]), tmp_path)
    # mechanism/mjcf.py refuses it as a MissingDependencyError, naming the package and the extra
    _refused(code, err, "needs the optional package 'mujoco'")
    assert "pip install 'appell[mjcf]'" in err


@pytest.mark.parametrize(
    "suffix, module, wanted", [(".h5", "h5py", "pip install h5py"), (".nc", "h5netcdf", "h5netcdf")]
)
def test_a_writer_without_its_package_names_it(suffix, module, wanted, tmp_path):
    args = ["simulate", "pendulum", "--t-end", "0.1", "--backend", "numpy", "--out", f"motion{suffix}"]
    code, _, err = _run([module], COMMAND.format(args=args), tmp_path)
    _refused(code, err, wanted)
    assert not (tmp_path / f"motion{suffix}").exists()


def test_python_control_is_named_where_it_is_missing(tmp_path):
    body = """
    import appell
    from appell.errors import MissingDependencyError
    d = appell.derive(appell.load_model("pendulum"))
    linear = appell.linearise(d, {"x": 0.0, "y": -1.0, "x_dot": 0.0, "y_dot": 0.0})
    try:
        linear.control()
    except MissingDependencyError as exc:
        print(exc)
    """
    code, out, err = _run(["control"], body, tmp_path)
    assert code == 0, err
    assert "needs the optional package 'control'" in out and "pip install 'appell[control]'" in out
