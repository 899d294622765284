"""Input and output: model files (safe TOML + expression parser), text/LaTeX/JSON printing,
the HTML report and the command line.
"""


def __getattr__(name: str):
    """A submodule reached as an attribute (``appell.<package>.<module>``) is imported on first
    use (PEP 562): ``import appell`` imports none of them."""
    import importlib
    import importlib.util

    if importlib.util.find_spec(f"{__name__}.{name}") is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return importlib.import_module(f"{__name__}.{name}")
