"""The options the commands of :mod:`appell.io.cli` share: the model argument, ``--set``,
``--floating-base``, ``--no-cache``, ``--reactions-in``, ``--mjcf`` (:func:`_model_options`),
``--backend``, ``--complete``, ``--adjust``, ``--expand`` and the integrator's options
(:func:`_solver_options`, one per name of :data:`~appell.workflows.SOLVER_OPTIONS`).

Click and the standard library only: the integrators' names and defaults shown in the help are
read from the simulation layer when the help is written (``appell --help`` needs no SymPy).
"""

from __future__ import annotations

import functools

import click

from appell.workflows import SOLVER_OPTIONS


def parse_assignments(items, option: str = "'--set'") -> dict[str, str]:
    """``["m=2", "x'=0.1"]`` -> ``{"m": "2", "x'": "0.1"}`` (values checked by the loader)."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name or not value:
            raise click.BadParameter(f"{item!r} is not NAME=VALUE", param_hint=option)
        out[name] = value
    return out


_CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}
_model_argument = click.argument("model", metavar="MODEL")
_backend_option = click.option(
    "--backend",
    type=click.Choice(["auto", "c", "numpy"]),
    default="auto",
    show_default=True,
    help="Numeric code: C compiled and cached on first use (auto: C when a compiler is found, else NumPy), or NumPy.",
)
#: ``appell simulate``'s: also ``tree``, a URDF robot or an MJCF tree on the numeric tree route (:mod:`appell.io.cli_tree`)
_simulate_backend_option = click.option(
    "--backend",
    type=click.Choice(["auto", "c", "numpy", "tree"]),
    default="auto",
    show_default=True,
    help="Numeric code: C compiled and cached on first use (auto: C when a compiler is found, else NumPy; "
    "a URDF or MJCF tree without a compiler: tree), NumPy, or tree: a URDF robot or a MuJoCo model "
    "by the articulated-body algorithm in NumPy, neither derived nor compiled.",
)
_set_option = click.option(
    "--set",
    "assignments",
    multiple=True,
    metavar="NAME=VALUE",
    help='Override a parameter or an initial value (repeatable), e.g. --set M=1500 --set "phi\'=0.2".',
)
_floating_option = click.option(
    "--floating-base",
    "floating_base",
    is_flag=True,
    help="A .urdf robot's root link moves on a free joint 'root_joint' (a quadruped, "
    "a humanoid): world translations and yaw, pitch, roll, the motion of Pinocchio's free flyer.",
)


def _keep(key):
    """A click callback keeping an option's value in the command's context (``ctx.meta``), for
    :func:`_derivation`: the options every model command has, without a parameter each."""

    def callback(ctx, param, value):
        ctx.meta[key] = value
        return value

    return callback


_cache_option = click.option(
    "--no-cache",
    "no_cache",
    is_flag=True,
    expose_value=False,
    callback=_keep("appell.no_cache"),
    help="Derive the model again instead of reading the derivation stored by an earlier run "
    "(the derivation cache, $APPELL_CACHE_DIR), and store nothing.",
)
_reactions_option = click.option(
    "--reactions-in",
    "reactions_in",
    default=None,
    metavar="AXES",
    expose_value=False,
    callback=_keep("appell.reactions_in"),
    help="Axes of the joint reactions of a [mechanism] model: world (ground), joint, "
    "child, parent or a body's name (default: the model file's reactions_in, else "
    "world).",
)
_mjcf_option = click.option(
    "--mjcf",
    "mjcf",
    multiple=True,
    metavar="NAME=VALUE",
    expose_value=False,
    callback=lambda ctx, param, value: ctx.meta.__setitem__("appell.mjcf", parse_assignments(value, "'--mjcf'")),
    help="How a MuJoCo model (.xml) is read (repeatable): frictionloss=ignore (leave MuJoCo's "
    "dry friction out; else refused), armature=rotors|energy, actuators=programs|controls "
    "(ctrl 0, or unknowns for inverse dynamics and servo constraints).",
)


_expand_option = click.option(
    "--expand",
    is_flag=True,
    help="Print each reaction also in the state (t, q, w), with the accelerations of the "
    "reduced equations substituted (long); by default its (1.5) formula names them.",
)


def _model_options(command):
    """``--set``, ``--floating-base``, ``--no-cache``, ``--reactions-in`` and ``--mjcf``, the
    options of every command that loads a model."""
    return _set_option(_floating_option(_cache_option(_reactions_option(_mjcf_option(command)))))


_complete_option = click.option(
    "--complete",
    is_flag=True,
    help="Change given initial values that violate a constraint (servo constraints "
    "included) so that it holds, and print each change; without it such a start "
    "is refused (exit 2).",
)
_adjust_option = click.option(
    "--adjust",
    "adjust",
    multiple=True,
    metavar="NAME",
    help="An initial value to compute from the constraints instead of taking it as given "
    '(repeatable, e.g. --adjust "xi\'"); implies --complete with these values only.',
)


class _Positive(click.ParamType):
    """A positive number (``inf`` allowed where ``infinite``); anything else is bad input."""

    name = "positive number"

    def __init__(self, infinite: bool = False):
        self.infinite = infinite

    def convert(self, value, param, ctx):
        import math

        if isinstance(value, float):
            return value
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"must be a positive number, got {value!r}", param, ctx)
        if not number > 0 or math.isnan(number) or (math.isinf(number) and not self.infinite):
            self.fail(f"must be a positive{'' if self.infinite else ' finite'} number, got {value}", param, ctx)
        return number


class _Choice(click.Choice):
    """A choice whose names are read on first use (``load()``): the integrators' names come
    from the simulation layer, which ``appell --help`` does not import."""

    def __init__(self, load):
        self._load, self.case_sensitive = load, True

    @property
    def choices(self):
        return tuple(self._load())

    @choices.setter
    def choices(self, value):  # click's own __init__ is not run
        pass


class _Option(click.Option):
    """An option whose help is written on first use (``help_of()``: the defaults of
    :class:`~appell.simulation.options.SimulationOptions`, read where they are kept)."""

    def __init__(self, *args, help_of=None, **kwargs):
        super().__init__(*args, **kwargs)
        self._help_of = help_of

    def get_help_record(self, ctx):
        if self._help_of is not None:
            self.help, self._help_of = self._help_of(), None
        return super().get_help_record(ctx)


def _defaults():
    from appell.simulation.options import DEFAULT_SAMPLES, SimulationOptions

    return SimulationOptions(), DEFAULT_SAMPLES


def _methods():
    from appell.simulation.simulate import METHODS

    return list(METHODS)


def _solver_options(command):
    """The integrator's options (:data:`SOLVER_OPTIONS`), each defaulting to the model's
    ``[simulation]`` value, collected into the command's ``solver`` argument
    (``{name: value, or None where not given}``) for :func:`~appell.workflows.command_options`.
    Their choices and the defaults in their help are read when they are used."""
    positive = _Positive()
    table = " (default: the model's [simulation] value, else {})."

    def default(text, of):
        return lambda: text + table.format(of(*_defaults()))

    def option(*names, text, of=None, **kwargs):
        return click.option(
            *names,
            cls=_Option,
            default=None,
            help_of=default(text, of) if of else None,
            help=None if of else text,
            **kwargs,
        )

    options = [
        option("--method", type=_Choice(_methods), text="Integration method", of=lambda d, n: d.method),
        option(
            "--rtol",
            type=positive,
            metavar="R",
            text="Relative tolerance of the integrator",
            of=lambda d, n: f"{d.rtol:g}".replace("e-0", "e-"),
        ),
        option(
            "--atol",
            type=positive,
            metavar="A",
            text="Absolute tolerance of the integrator",
            of=lambda d, n: f"{d.atol:g}".replace("e-0", "e-"),
        ),
        option(
            "--max-step",
            "max_step",
            type=_Positive(infinite=True),
            metavar="H",
            text="Largest integration step",
            of=lambda d, n: "unbounded",
        ),
        option(
            "--t0",
            "t0",
            type=float,
            metavar="T",
            text="Start time; the initial values hold at t0",
            of=lambda d, n: f"{d.t0:g}",
        ),
        option(
            "--samples",
            type=click.IntRange(min=2),
            metavar="N",
            text="N equally spaced output times from t0 to t_end",
            of=lambda d, n: n,
        ),
        option(
            "--output-step",
            "output_step",
            type=positive,
            metavar="H",
            text="Output times t0, t0 + H, ... and t_end (excludes --samples).",
        ),
        option(
            "--stabilization",
            type=click.Choice(["projection", "baumgarte", "none"]),
            text="Constraint drift control",
            of=lambda d, n: d.stabilization,
        ),
        option(
            "--setting",
            "settings",
            multiple=True,
            metavar="KEY=VALUE",
            text="Any key of a model file's [simulation] table, its value in TOML (e.g. --setting rest_speed=1e-5, "
            "--setting unilateral={contact=1}); repeatable; the flags above win.",
        ),
    ]

    @functools.wraps(command)
    def with_solver(*args, **kwargs):
        kwargs["solver"] = {name: kwargs.pop(name) for name in SOLVER_OPTIONS}
        return command(*args, **kwargs)

    for option in reversed(options):
        with_solver = option(with_solver)
    return with_solver
