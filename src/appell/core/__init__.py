"""Derivation pipeline (method.md §1–3): validation -> kinematics -> acceleration energy
-> constraints in second-order form -> partition -> reduced equations (1.4) and reactions (1.5).

:mod:`appell.core.derive` reads like the method; each other module is one stage.
"""


def __getattr__(name: str):
    """A submodule reached as an attribute (``appell.<package>.<module>``) is imported on first
    use (PEP 562): ``import appell`` imports none of them."""
    import importlib
    import importlib.util

    if importlib.util.find_spec(f"{__name__}.{name}") is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return importlib.import_module(f"{__name__}.{name}")
