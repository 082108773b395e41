"""The options of one generate request, defined, parsed, defaulted and validated in one place.

REST, gRPC and both command lines build a :class:`GenerateOptions` from what the user
sent; :func:`parse_value` is the one rule by which a value as sent (command-line, query or
form text, a JSON value) becomes an option's type, and :meth:`GenerateOptions.resolve`
fills the model's defaults and checks every range once, raising :class:`OptionError` (the
service answers it with 422 problem+json, the command lines with a one-line message and
exit 2). The engine, the batcher and :class:`~spacemesh.runtime.pipeline.MeshGenerator`
then pass the resolved options, typed, along unchanged. :data:`OPTION_FIELDS` lists the
public names and :data:`OPTION_KINDS` their types; the SDK mirrors both, and the parsing
rule (tests keep them in sync).

The parsing rule, by type:

- **integer** (``seed``, ``steps``, ``target_vertices``, ``samples``): an integer (a JSON
  integer), or text of decimal digits with an optional sign (:data:`INTEGER_TEXT`).
  Nothing else: ``1e3``, ``1.0``, ``2.0``, ``0x10``, ``1_000`` and JSON ``1.0`` are
  refused, never rounded or converted;
- **number** (``start_time``, ``tolerance``): a number (JSON integer or float), or decimal
  text with an optional fraction and exponent (:data:`NUMBER_TEXT`: ``0.5``, ``5e-3``);
  ``nan`` and ``inf`` are not numbers here;
- **boolean** (``raw``): true or false, or one of :data:`TRUE_WORDS` /
  :data:`FALSE_WORDS` (any case);
- **text** (``sampler``, ``start``, ``surface``, ``face_type``): text only.

Surrounding whitespace of text is ignored; empty text is "not given".
"""

from __future__ import annotations

import numbers
import operator
import re
import types
import typing
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from spacemesh.geometry.surface import SURFACE_MODES
from spacemesh.runtime.schedule import METHODS
from spacemesh.runtime.spec import MAX_RETRY_SEEDS, ModelSpec

#: Where the vertices start: pure noise (the paper) or points chosen on the input.
START_MODES = ("noise", "points")
#: Generate options that a repair does not take (it reads ``seed``, ``steps`` and
#: ``sampler``).
GENERATE_ONLY = ("start", "start_time", "target_vertices", "tolerance", "samples", "raw",
                 "surface", "face_type")
#: What ``face_type`` may ask for (``quads`` needs a connectivity network trained on
#: quad-dominant meshes, which the shipped model is not).
FACE_TYPES = ("triangles", "polygons", "quads")
#: Most seeds one ``samples`` request may try.
MAX_SAMPLES = 16
#: Fewest vertices a mesh may be asked for (a tetrahedron).
MIN_TARGET_VERTICES = 4
#: Most vertices a mesh may be asked for.
MAX_TARGET_VERTICES = 10_000
#: Smallest and largest ``tolerance`` (fractions of the input's bounding-box diagonal).
MIN_TOLERANCE = 1e-4
MAX_TOLERANCE = 0.5
#: The release's ``feature_boost``: farthest points on sharp features count twice as far.
FEATURE_BOOST = 1.0
#: The vertex start a release records in ``manifest["sampler"]``: farthest-point
#: samples of the input, with points on sharp features counted twice as far
#: (``feature_boost``), not denoised (the shipped denoiser moves good vertices away
#: from the surface: docs/RESULTS.md has the start-time sweep), 200 of them unless the
#: request sets a target.
POINTS_START = {"start": "points", "start_time": 0.0, "vertices": 200,
                "feature_boost": FEATURE_BOOST}
#: The ``sampler.retry_seeds`` a release records when it is repackaged with this code
#: (``spacemesh export MODEL_VERSION_DIR``; a freshly trained run records none).
RELEASE_RETRY_SEEDS = 4
#: Largest seed (int64 in the gRPC contract; seeds + samples + retries stay below it).
MAX_SEED = 2**63 - 1 - MAX_SAMPLES - MAX_RETRY_SEEDS
#: The text of an integer option: decimal digits with an optional sign.
INTEGER_TEXT = re.compile(r"[+-]?[0-9]+")
#: The text of a number option: decimal digits with an optional sign, fraction and exponent.
NUMBER_TEXT = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: Most digits of an integer option's text (more are beyond every option's range).
MAX_INTEGER_DIGITS = 30
#: Spellings of a boolean option (case-insensitive).
TRUE_WORDS = ("true", "1", "yes", "on", "t", "y")
FALSE_WORDS = ("false", "0", "no", "off", "f", "n")
#: Most characters of a refused value quoted in an error message.
_SHOWN_CHARACTERS = 40


class OptionError(ValueError):
    """An option the model cannot honour.

    Attributes
    ----------
    option : str
        The option's public name.
    """

    def __init__(self, option: str, message: str) -> None:
        super().__init__(message)
        self.option = option


@dataclass(frozen=True)
class GenerateOptions:
    """What a generate request may choose; None means the model's default.

    Attributes
    ----------
    seed : int
        The same seed (and options) gives the same mesh.
    steps : int, optional
        Sampler steps of the whole schedule (with ``start=points`` only those below
        ``start_time`` run).
    sampler : {"ddim", "ddpm"}, optional
    start : {"noise", "points"}, optional
        ``noise``: the paper's diffusion from pure noise. ``points``: vertices chosen on
        the input by farthest-point sampling, noised to ``start_time`` and denoised from
        there (SDEdit).
    start_time : float, optional
        Fraction t/T of the diffusion where ``start=points`` begins; 0 uses the chosen
        points as they are. Only with ``start=points``.
    target_vertices : int, optional
        Vertices of the final mesh (within 10%; fewer with ``face_type="polygons"``,
        whose flat regions lose their interior vertices); without it the count is a
        fixed function of the input (the same for every seed).
    tolerance : float, optional
        The mesh's size is the smallest the search finds whose mean distance from the
        input points to the mesh is at most this fraction of the input's bounding-box
        diagonal (the fit report's ``points_to_mesh_mean_rel``; ``tolerance_met`` says
        whether it was reached within the search's cap). Not with ``target_vertices``;
        needs ``start=points``.
    samples : int
        Seeds ``seed .. seed + samples - 1`` are generated and the mesh that fits the
        input best is returned (ties: the lower seed).
    raw : bool
        Return the networks' mesh as the model's own decode gives it, without the
        geometry stage (:mod:`spacemesh.geometry`).
    surface : {"auto", "closed", "open"}, optional
        ``closed``: a watertight mesh; ``open``: the closed mesh trimmed to where the
        points are (:mod:`spacemesh.geometry.surface`); ``auto`` (the default): open
        when the points leave a large part of the closed mesh unsupported (a one-sided
        scan). With ``raw`` only ``closed`` (its default there).
    face_type : {"triangles", "polygons", "quads"}, optional
        ``triangles``: a triangle mesh (a model whose decode makes polygons has them
        triangulated); ``polygons``: the edges collapsed whose collapse leaves the
        surface where it was (flat regions lose their interior vertices), then flat
        regions merged into planar polygons
        (:mod:`spacemesh.geometry.polygons`; every merged face's corners within 0.1% of
        the diagonal of its plane; a decode's own polygons are kept as they are);
        ``quads`` needs a model trained on quad-dominant meshes (refused otherwise).
        Default: what the model's decode makes (``triangles`` for a decode with
        ``max_sides`` 3, the shipped model's; ``polygons`` otherwise). With ``raw``
        only that default.
    """

    seed: int = 0
    steps: int | None = None
    sampler: str | None = None
    start: str | None = None
    start_time: float | None = None
    target_vertices: int | None = None
    tolerance: float | None = None
    samples: int = 1
    raw: bool = False
    surface: str | None = None
    face_type: str | None = None

    def resolve(self, spec: ModelSpec) -> GenerateOptions:
        """These options with the model's defaults filled in, every range checked.

        Parameters
        ----------
        spec : ModelSpec

        Returns
        -------
        GenerateOptions
            No field is None except ``target_vertices``, ``tolerance`` and, with
            ``start=noise``, ``start_time``; resolving it again gives it back unchanged.

        Raises
        ------
        OptionError
            The first option out of range, by its public name.
        """
        seed = _integer("seed", self.seed, 0, MAX_SEED)
        steps = spec.steps if self.steps is None else _integer(
            "steps", self.steps, 1, spec.schedule.timesteps)
        sampler = spec.method if self.sampler is None else parse_text("sampler", self.sampler)
        if sampler not in METHODS:
            raise OptionError("sampler", f"sampler must be one of {', '.join(METHODS)}, "
                                         f"not {sampler!r}")
        start = spec.start if self.start is None else parse_text("start", self.start)
        if start not in START_MODES:
            raise OptionError("start", f"start must be one of {', '.join(START_MODES)}, "
                                       f"not {start!r}")
        if start == "noise" and self.start_time is not None:
            raise OptionError("start_time", "start_time applies to start=points only")
        start_time: float | None  # None with start=noise: the whole diffusion
        start_time = spec.start_time if self.start_time is None else self.start_time
        if start == "points":
            start_time = parse_number("start_time", start_time)
            if not 0.0 <= start_time <= 1.0:  # NaN fails too
                raise OptionError("start_time",
                                  f"start_time must be in [0, 1], not {start_time}")
        else:
            start_time = None  # the whole diffusion
        target_vertices = None
        if self.target_vertices is not None:
            target_vertices = _integer("target_vertices", self.target_vertices,
                                       MIN_TARGET_VERTICES, MAX_TARGET_VERTICES)
            if start == "noise":
                raise OptionError("target_vertices",
                                  "target_vertices needs start=points (from noise the "
                                  "network picks the count)")
        tolerance = None if self.tolerance is None else _tolerance(self.tolerance)
        if tolerance is not None:
            if self.target_vertices is not None:
                raise OptionError("tolerance", "tolerance and target_vertices cannot both be "
                                               "set: the tolerance chooses the vertex count")
            if start == "noise":
                raise OptionError("tolerance", "tolerance needs start=points (from noise the "
                                               "network picks the count)")
        samples = _integer("samples", self.samples, 1, MAX_SAMPLES)
        raw = parse_boolean("raw", self.raw)
        surface = _surface(self.surface, raw)
        face_type = _face_type(self.face_type, raw, spec)
        return replace(self, seed=seed, steps=steps, sampler=sampler, start=start,
                       start_time=start_time, target_vertices=target_vertices,
                       tolerance=tolerance, samples=samples, raw=raw, surface=surface,
                       face_type=face_type)

    @classmethod
    def parse(cls, values: Mapping[str, Any]) -> GenerateOptions:
        """Options from values as sent, each parsed by :func:`parse_value`.

        Parameters
        ----------
        values : mapping
            Values by public name: text (a command line, a query string, a form) or
            typed values (JSON, gRPC); None or empty text: not given (the default).

        Returns
        -------
        GenerateOptions
            Typed, not yet resolved (:meth:`resolve` checks the ranges).

        Raises
        ------
        OptionError
            A name that is not an option, or the first value not of its option's type.
        """
        unknown = sorted(set(values) - set(OPTION_FIELDS))
        if unknown:
            raise OptionError(unknown[0], f"unknown option{'s' if len(unknown) > 1 else ''}: "
                                          f"{', '.join(unknown)}")
        given = {name: parse_value(name, OPTION_KINDS[name], value)
                 for name, value in values.items()}
        return cls(**{name: value for name, value in given.items() if value is not None})

    def to_dict(self) -> dict[str, Any]:
        """The options by public name."""
        return asdict(self)


def _surface(value: Any, raw: bool) -> str:
    """The resolved ``surface``: ``auto`` by default, ``closed`` with ``raw`` (the only
    one it takes: trimming is part of the geometry stage that ``raw`` skips)."""
    if value is None:
        return "closed" if raw else "auto"
    surface = parse_text("surface", value)
    if surface not in SURFACE_MODES:
        raise OptionError("surface", f"surface must be one of {', '.join(SURFACE_MODES)}, "
                                     f"not {surface!r}")
    if raw and surface != "closed":
        raise OptionError("surface", f"surface={surface} needs the geometry stage, which raw "
                                     "skips (a raw mesh is the closed decode)")
    return surface


def _face_type(value: Any, raw: bool, spec: ModelSpec) -> str:
    """The resolved ``face_type``: by default what the model's decode makes; another
    one changes the faces after the geometry stage (so not with ``raw``); ``quads``
    needs a model whose decode makes quad-dominant meshes, which no shipped model
    does."""
    native = "triangles" if spec.decode.max_sides == 3 else "polygons"
    if value is None:
        return native
    face_type = parse_text("face_type", value)
    if face_type not in FACE_TYPES:
        raise OptionError("face_type", f"face_type must be one of {', '.join(FACE_TYPES)}, "
                                       f"not {face_type!r}")
    if face_type == "quads":
        raise OptionError("face_type", "face_type=quads needs a connectivity network "
                                       "trained on quad-dominant meshes, which this model "
                                       "does not have (polygons merges flat regions into "
                                       "planar polygons)")
    if raw and face_type != native:
        raise OptionError("face_type", f"face_type={face_type} needs the geometry stage, "
                                       f"which raw skips (this model's decode makes "
                                       f"{native})")
    return face_type


def _kind(annotation: Any) -> type:
    """``int | None`` -> ``int``."""
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        return next(a for a in typing.get_args(annotation) if a is not type(None))
    return typing.cast(type, annotation)


#: Public option names, in the order of :class:`GenerateOptions`.
OPTION_FIELDS = tuple(f.name for f in fields(GenerateOptions))
#: Each option's type (``int``, ``float``, ``bool`` or ``str``), from its annotation.
OPTION_KINDS: dict[str, type] = {
    name: _kind(hint) for name, hint in typing.get_type_hints(GenerateOptions).items()}


# ---------------------------------------------------------------------- parsing
def _shown(value: Any) -> str:
    """``repr(value)``, cut short for an error message."""
    text = repr(value)
    return text if len(text) <= _SHOWN_CHARACTERS else text[:_SHOWN_CHARACTERS - 3] + "..."


def parse_integer(name: str, value: Any) -> int:
    """An integer option's value: an integer, or :data:`INTEGER_TEXT`.

    Parameters
    ----------
    name : str
        The option's public name (for the error).
    value : Any
        Text, or an integer (``int`` or a numpy integer; not a bool, not a float even
        when it is integral).

    Returns
    -------
    int

    Raises
    ------
    OptionError
        Anything else, e.g. ``"1e3"``, ``"1.0"`` or ``2.0``: "NAME must be an integer".
    """
    if isinstance(value, str):
        text = value.strip()
        if INTEGER_TEXT.fullmatch(text) is None:
            raise OptionError(name, f"{name} must be an integer (digits only, no fraction "
                                    f"or exponent), not {_shown(value)}")
        if len(text.lstrip("+-")) > MAX_INTEGER_DIGITS:
            raise OptionError(name, f"{name} must be an integer of at most "
                                    f"{MAX_INTEGER_DIGITS} digits, not {_shown(value)}")
        return int(text)
    if not isinstance(value, bool):
        try:
            return operator.index(value)
        except TypeError:
            pass
    raise OptionError(name, f"{name} must be an integer (digits only, no fraction or "
                            f"exponent), not {_shown(value)}")


def parse_number(name: str, value: Any) -> float:
    """A number option's value: a real number (not a bool), or :data:`NUMBER_TEXT`.

    Parameters
    ----------
    name : str
    value : Any

    Returns
    -------
    float
        Possibly NaN or infinite when sent as a float (the range checks refuse them).

    Raises
    ------
    OptionError
        Anything else: "NAME must be a number".
    """
    if isinstance(value, str):
        if NUMBER_TEXT.fullmatch(value.strip()) is None:
            raise OptionError(name, f"{name} must be a number, not {_shown(value)}")
        return float(value)
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return float(value)
    raise OptionError(name, f"{name} must be a number, not {_shown(value)}")


def parse_boolean(name: str, value: Any) -> bool:
    """A boolean option's value: a bool, or one of :data:`TRUE_WORDS` / :data:`FALSE_WORDS`
    (also the integers 1 and 0).

    Raises
    ------
    OptionError
        Anything else: "NAME must be true or false".
    """
    if isinstance(value, bool):
        return value
    if isinstance(value, (str, int)):
        word = str(value).strip().lower()
        if word in FALSE_WORDS:
            return False
        if word in TRUE_WORDS:
            return True
    raise OptionError(name, f"{name} must be true or false, not {_shown(value)}")


def parse_text(name: str, value: Any) -> str:
    """A text option's value (surrounding whitespace removed).

    Raises
    ------
    OptionError
        Not text.
    """
    if not isinstance(value, str):
        raise OptionError(name, f"{name} must be text, not {_shown(value)}")
    return value.strip()


#: The parser of each option type.
_PARSERS: dict[type, typing.Callable[[str, Any], Any]] = {
    int: parse_integer, float: parse_number, bool: parse_boolean, str: parse_text}


def parse_value(name: str, kind: type, value: Any) -> Any:
    """One option's value as sent, as its type: the one parsing rule of every option.

    REST (query, form and JSON body, streaming routes too), gRPC and both command lines
    parse every option here (the SDK mirrors it; a test keeps the two in sync).

    Parameters
    ----------
    name : str
        The option's public name.
    kind : type
        ``int``, ``float``, ``bool`` or ``str`` (:data:`OPTION_KINDS` for the generate
        options).
    value : Any
        Text, or a typed value (JSON, gRPC); None or ``""``: not given.

    Returns
    -------
    Any
        ``kind``, or None when not given.

    Raises
    ------
    OptionError
        A value that is not of the option's type (:func:`parse_integer`,
        :func:`parse_number`, :func:`parse_boolean`, :func:`parse_text`).
    """
    if value is None or (isinstance(value, str) and value == ""):
        return None
    return _PARSERS[kind](name, value)


def _tolerance(value: Any) -> float:
    """``value`` as a float in ``[MIN_TOLERANCE, MAX_TOLERANCE]``."""
    number = parse_number("tolerance", value)
    if not MIN_TOLERANCE <= number <= MAX_TOLERANCE:  # NaN fails too
        raise OptionError("tolerance", f"tolerance must be in {MIN_TOLERANCE:g}..."
                                       f"{MAX_TOLERANCE:g} of the diagonal, not {number}")
    return number


def _integer(name: str, value: Any, low: int, high: int) -> int:
    """``value`` as an int in ``[low, high]`` (:func:`parse_integer`)."""
    number = parse_integer(name, value)
    if not low <= number <= high:
        raise OptionError(name, f"{name} must be in {low}..{high}, not {number}")
    return number
