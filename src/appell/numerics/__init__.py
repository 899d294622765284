"""Numerics: compiled blocks and the split solve at a state (NumPy and C backends), the
independent augmented-system cross-check, and the Dynamics contract with the simulator.
"""


def __getattr__(name: str):
    """A submodule reached as an attribute (``appell.<package>.<module>``) is imported on first
    use (PEP 562): ``import appell`` imports none of them."""
    import importlib
    import importlib.util

    if importlib.util.find_spec(f"{__name__}.{name}") is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return importlib.import_module(f"{__name__}.{name}")
