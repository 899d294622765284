"""Repeated entries in model files (appell.io.modelfile.repeat; docs/model-format.md,
Repeated entries): a chain written once for every index equals the chain written out, and
every mistake in a range or a placeholder names its file and line."""

from __future__ import annotations

import pytest

import appell
from appell.errors import ModelError

CHAIN = """
[model]
name = "chain"

[counts]
N = 3

[mechanism]
gravity = [0, "-g", 0]

[parameters]
g = 9.81
m = 1.0

[[bodies]]
for = "i in 1..N"
name = "link{i}"
mass = "m*{i}"
inertia = [0, 0, 0.1]
com = [0.5, 0, 0]

[[joints]]
name = "J1"
type = "revolute"
parent = "ground"
child = "link1"

[[joints]]
for = "i in 2..N"
name = "J{i}"
type = "revolute"
parent = "link{i-1}"
child = "link{i}"
origin = [1.0, 0, 0]

[initial]
"J{i in 1..N}" = "0.1*{i}"
"J{i in 1..N}'" = 0.0

[units]
"J{k in 1..N}" = "rad"
"""

WRITTEN_OUT = (
    """
[model]
name = "chain"

[mechanism]
gravity = [0, "-g", 0]

[parameters]
g = 9.81
m = 1.0
"""
    + "".join(
        f"""
[[bodies]]
name = "link{i}"
mass = "m*{i}"
inertia = [0, 0, 0.1]
com = [0.5, 0, 0]
"""
        for i in (1, 2, 3)
    )
    + """
[[joints]]
name = "J1"
type = "revolute"
parent = "ground"
child = "link1"
"""
    + "".join(
        f"""
[[joints]]
name = "J{i}"
type = "revolute"
parent = "link{i - 1}"
child = "link{i}"
origin = [1.0, 0, 0]
"""
        for i in (2, 3)
    )
    + """
[initial]
J1 = 0.1
J2 = 0.2
J3 = 0.30000000000000004
"J1'" = 0.0
"J2'" = 0.0
"J3'" = 0.0

[units]
J1 = "rad"
J2 = "rad"
J3 = "rad"
"""
)


def test_a_repeated_chain_is_the_chain_written_out():
    repeated, written = appell.loads_model(CHAIN), appell.loads_model(WRITTEN_OUT)
    assert repeated.coordinates == written.coordinates
    assert [b.name for b in repeated.bodies] == ["link1", "link2", "link3"]
    assert [b.mass for b in repeated.bodies] == [b.mass for b in written.bodies]
    assert [b.position for b in repeated.bodies] == [b.position for b in written.bodies]
    assert dict(repeated.initial) == pytest.approx(dict(written.initial))
    assert repeated.units == written.units
    assert [o.name for o in repeated.outputs] == [o.name for o in written.outputs]


def test_an_empty_range_writes_nothing():
    system = appell.loads_model(CHAIN.replace("N = 3", "N = 1"))
    assert [b.name for b in system.bodies] == ["link1"] and [q.name for q in system.coordinates] == ["J1"]


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), start=1) if needle in line)


@pytest.mark.parametrize(
    "old, new, says, at",
    [
        ('for = "i in 2..N"', 'for = "i from 2 to N"', "cannot read 'i from 2 to N' as a range", "i from 2 to N"),
        ('for = "i in 2..N"', 'for = "i in 2..M"', "unknown name 'M' (known here: N)", "i in 2..M"),
        ('parent = "link{i-1}"', 'parent = "link{j-1}"', "unknown name 'j' (known here: N, i)", "link{j-1}"),
        ('parent = "link{i-1}"', 'parent = "link{i/2}"', "only whole numbers, names", "link{i/2}"),
        (
            'parent = "link{i-1}"',
            "parent = \"link{__import__('os').getpid()}\"",
            "not a whole-number expression",
            "__import__",
        ),
        ('"J{i in 1..N}\'" = 0.0', '"J{i in 1..N}\'" = "{i//0}"', "division by zero", '"J{i in 1..N}\'"'),
        ("N = 3", "N = 3.5", "counts.N: must be a whole number", "N = 3.5"),
        ("N = 3", "N = 3\ni = 1", "the variable 'i' is also a count", 'for = "i in 1..N"'),
        ("[units]", '[units]\nJ2 = "rad"', "units.J2: given twice", '"J{k in 1..N}"'),
        ("N = 3", "N = 100000", "more than 20000 entries", 'for = "i in 1..N"'),
    ],
)
def test_mistakes_name_the_file_and_line(old, new, says, at):
    text = CHAIN.replace(old, new, 1)
    assert text != CHAIN
    with pytest.raises(ModelError) as info:
        appell.loads_model(text, source="chain.toml")
    assert says in info.value.message
    assert info.value.where == f"chain.toml:{line_of(text, at)}", info.value.message


def test_a_mistake_inside_a_copy_names_the_written_entry():
    """A copy's own error (here a body that is no body, for i = 3) points at the line of the
    written entry's key."""
    text = CHAIN.replace('parent = "link{i-1}"', 'parent = "link{2*i}"')
    with pytest.raises(ModelError) as info:
        appell.loads_model(text, source="chain.toml")
    assert "link4" in info.value.message
    assert info.value.where == f"chain.toml:{line_of(text, 'parent = ' + chr(34) + 'link{2*i}')}"
