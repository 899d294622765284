"""Model files: systems written in TOML with a safe math syntax (docs/model-format.md).

:func:`load_model` reads a file, :func:`loads_model` a string; both return a
:class:`appell.model.System` or raise :class:`appell.errors.ModelError` with the file and
line. Expressions are parsed by :func:`parse_expression`, which builds SymPy objects
from a whitelisted grammar without ``eval``.
"""

from .expressions import ExpressionError, parse_expression
from .loader import load_model, loads_model

__all__ = ["ExpressionError", "load_model", "loads_model", "parse_expression"]
