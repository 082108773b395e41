"""The request options of both servers, in one table, resolved in one place.

The generate options are :class:`spacemesh.runtime.options.GenerateOptions`: their names
(:data:`~spacemesh.runtime.options.OPTION_FIELDS`), types (its annotations) and
descriptions (its numpydoc ``Attributes``) make :data:`GENERATE_OPTIONS`. With the two
service options, ``format`` (every route) and ``weld`` (``/repair``), they give the
options of each route (:data:`GENERATE_ROUTE_OPTIONS`, :data:`REPAIR_ROUTE_OPTIONS`),
from which come

- the REST query parameters, form fields and JSON body fields a route reads, and their
  OpenAPI description (:meth:`RequestOption.parameter`, :meth:`RequestOption.schema`);
- the gRPC fields read (:func:`grpc_values`; the proto fields have the same names);
- the ``X-SpaceMesh-*`` headers and reply fields of the resolved options
  (:func:`reported_options`, :func:`spacemesh_service.outputs.value_headers`).

:func:`resolve_request` turns the values a request sent into a :class:`RequestOptions`:
every name must be an option of the route, every value is parsed by the model's one rule
(:func:`spacemesh.runtime.options.parse_value`: integers only from integer text, so
``seed=1e3`` or ``samples=2.0`` is refused, never converted), then the service's policy
(a random seed when none is given, ``settings.default_steps``), then
:meth:`GenerateOptions.resolve` once, then ``settings.max_steps``. Every option error,
``format``, ``weld`` and ``max_growth`` included, is a 422 ``invalid-option`` naming the
option (``option``); a name the route does not take is one too (``option``, and
``unknown``: every such name). Generate-only options (``start``, ``start_time``,
``target_vertices``, ``tolerance``, ``samples``, ``raw``, ``surface``, ``face_type``) are
not options of ``/repair``.
"""

from __future__ import annotations

import re
import secrets
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from typing import Any

from spacemesh.geometry.surface import SURFACE_MODES
from spacemesh.runtime.options import (
    FACE_TYPES,
    GENERATE_ONLY,
    MAX_SAMPLES,
    MAX_SEED,
    MAX_TARGET_VERTICES,
    MAX_TOLERANCE,
    MIN_TARGET_VERTICES,
    MIN_TOLERANCE,
    OPTION_FIELDS,
    OPTION_KINDS,
    START_MODES,
    GenerateOptions,
    OptionError,
    parse_value,
)
from spacemesh.runtime.schedule import METHODS
from spacemesh.runtime.spec import ModelSpec
from spacemesh_service import problems as P
from spacemesh_service.outputs import OUTPUT_FORMATS
from spacemesh_service.problems import Problem
from spacemesh_service.settings import Settings

#: Seeds picked by the server when a request gives none lie in ``[0, 2**31)``.
RANDOM_SEED_BITS = 31

#: What the service adds to an option's description (instead of "Default: the model's.").
_NOTES = {"seed": "Picked at random (and reported) when absent.",
          "target_vertices": "Needs `start=points`.",
          "tolerance": "Needs `start=points`; not with `target_vertices`.",
          "surface": "Default: auto (closed with `raw`).",
          "face_type": "Default: what the model's decode makes (the shipped model's: "
                       "triangles)."}
#: Values an option may take, where they are a fixed set.
_CHOICES: dict[str, tuple[str, ...]] = {"sampler": METHODS, "start": START_MODES,
                                        "surface": SURFACE_MODES, "face_type": FACE_TYPES,
                                        "format": OUTPUT_FORMATS}
#: Inclusive ranges of the numeric options (None: no bound here; the model's).
_RANGES: dict[str, tuple[float | None, float | None]] = {
    "seed": (0, MAX_SEED), "steps": (1, None), "start_time": (0.0, 1.0),
    "target_vertices": (MIN_TARGET_VERTICES, MAX_TARGET_VERTICES), "samples": (1, MAX_SAMPLES),
    "tolerance": (MIN_TOLERANCE, MAX_TOLERANCE),
    "max_growth": (0.0, 1.0),
}
_JSON_TYPES = {bool: "boolean", int: "integer", float: "number", str: "string"}
_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")


@dataclass(frozen=True)
class RequestOption:
    """One option of a route.

    Attributes
    ----------
    name : str
        The public name (query parameter, form and JSON field, gRPC field).
    kind : type
        ``int``, ``float``, ``bool`` or ``str``.
    description : str
    """

    name: str
    kind: type
    description: str

    @property
    def choices(self) -> tuple[str, ...]:
        """The values it may take, when they are a fixed set."""
        return _CHOICES.get(self.name, ())

    def parse(self, value: Any) -> Any:
        """A value as sent (query or form text, JSON value, gRPC field) as :attr:`kind`,
        by the model's one rule (:func:`spacemesh.runtime.options.parse_value`).

        Only the type is converted here; ranges and choices are checked by
        :func:`resolve_request`.

        Parameters
        ----------
        value : Any
            None or ``""``: not given.

        Returns
        -------
        Any
            None when not given.

        Raises
        ------
        OptionError
            A value that is not of the option's type.
        """
        return parse_value(self.name, self.kind, value)

    def schema(self) -> dict[str, Any]:
        """Its JSON schema (OpenAPI)."""
        schema: dict[str, Any] = {"type": _JSON_TYPES[self.kind], "description": self.description}
        if self.choices:
            schema["enum"] = list(self.choices)
        low, high = _RANGES.get(self.name, (None, None))
        if low is not None:
            schema["minimum"] = low
        if high is not None:
            schema["maximum"] = high
        return schema

    def parameter(self) -> dict[str, Any]:
        """Its OpenAPI query parameter."""
        return {"name": self.name, "in": "query", "required": False,
                "description": self.description, "schema": self.schema()}


def attribute_docs(cls: type) -> dict[str, str]:
    """The descriptions of a class's numpydoc ``Attributes`` section, by name (roles and
    double backticks made plain)."""
    lines = (cls.__doc__ or "").splitlines()
    docs: dict[str, list[str]] = {}
    current: str | None = None
    inside, indent = False, 0
    for line in lines:
        text = line.strip()
        if text == "Attributes":
            inside, indent = True, len(line) - len(line.lstrip())
            continue
        if not inside or set(text) == {"-"}:
            continue
        depth = len(line) - len(line.lstrip())
        if text and depth == indent and " : " not in text:
            break  # the next section
        if text and depth == indent:
            current = text.split(" : ")[0]
            docs[current] = []
        elif text and current is not None:
            docs[current].append(text)
    return {name: _ROLE.sub(r"\1", " ".join(words)).replace("``", "`")
            for name, words in docs.items()}


def _generate_options() -> tuple[RequestOption, ...]:
    docs = attribute_docs(GenerateOptions)
    table = []
    for field in fields(GenerateOptions):
        text = docs.get(field.name, "")
        choices = _CHOICES.get(field.name)
        if choices:
            text = f"One of {', '.join(choices)}. {text}".strip()
        if field.name in _NOTES:
            text += " " + _NOTES[field.name]
        elif field.default is None:
            text += " Default: the model's."
        table.append(RequestOption(field.name, OPTION_KINDS[field.name], text.strip()))
    return tuple(table)


#: The generate options, in :data:`~spacemesh.runtime.options.OPTION_FIELDS` order.
GENERATE_OPTIONS: tuple[RequestOption, ...] = _generate_options()
#: The output format (every route).
FORMAT = RequestOption("format", str, f"One of {', '.join(OUTPUT_FORMATS)} (default glb).")
#: Repair only: merge vertices at equal positions first.
WELD = RequestOption("weld", bool, "Merge vertices at exactly equal positions before the "
                     "repair (meshes split at UV seams or hard edges, e.g. GLB); default "
                     "false. The output is the welded mesh repaired.")
#: Repair only: the largest share of the mesh's faces a region may grow to.
MAX_GROWTH = RequestOption("max_growth", float, "Largest share (0 to 1) of the mesh's faces "
                           "a repair region may grow to (default 0.25, at most the server's "
                           "max_repair_growth); beyond it: 422 region-growth-exceeded.")
#: The options of ``POST /generate`` and gRPC ``Generate``.
GENERATE_ROUTE_OPTIONS: tuple[RequestOption, ...] = (FORMAT, *GENERATE_OPTIONS)
#: The options of ``POST /repair`` and gRPC ``Repair``.
REPAIR_ROUTE_OPTIONS: tuple[RequestOption, ...] = (
    FORMAT, *(o for o in GENERATE_OPTIONS if o.name not in GENERATE_ONLY), WELD, MAX_GROWTH)


@dataclass(frozen=True)
class RequestOptions:
    """A request's options, checked.

    Attributes
    ----------
    format : str
        One of :data:`~spacemesh_service.outputs.OUTPUT_FORMATS`.
    sent : GenerateOptions
        What the request asked for, with the service's policy applied (its seed, or one
        picked at random; ``settings.default_steps`` when it names no steps): what the
        generator is given.
    resolved : GenerateOptions
        ``sent`` resolved against the model (every default filled in).
    weld : bool
        Repair only.
    max_growth : float or None
        Repair only (None: the default, ``spacemesh.repair.DEFAULT_MAX_GROWTH``).
    """

    format: str
    sent: GenerateOptions
    resolved: GenerateOptions
    weld: bool = False
    max_growth: float | None = None

    @property
    def batch_key(self) -> tuple[int, str, str, float]:
        """What requests must share to run in one batch: the sampler settings."""
        r = self.resolved
        return (int(r.steps or 0), str(r.sampler), str(r.start), float(r.start_time or 0.0))


def option_problem(error: OptionError) -> Problem:
    """The problem of a bad option: 422 ``invalid-option``, its ``option`` member naming
    it (every option of every route: the generate options, ``format``, ``weld``,
    ``max_growth``)."""
    return Problem(P.INVALID_OPTION, str(error), option=error.option)


def refuse_unknown(names: Iterable[str], table: tuple[RequestOption, ...]) -> None:
    """Refuse the names a request sent that are not options of its route.

    Parameters
    ----------
    names : iterable of str
        The option names sent (query parameters, form fields other than the route's
        body fields, JSON keys other than ``points`` and ``normals``).
    table : tuple of RequestOption
        The route's options.

    Raises
    ------
    Problem
        422 ``invalid-option`` naming them: ``option`` (the first, in sorted order) and
        ``unknown`` (all of them); a generate-only option sent to ``/repair`` is said to
        be one.
    """
    taken = [o.name for o in table]
    unknown = sorted(set(names) - set(taken))
    if not unknown:
        return
    named = ", ".join(f"{n} (an option of /generate only)" if n in GENERATE_ONLY else repr(n)
                      for n in unknown)
    plural = "s" if len(unknown) > 1 else ""
    raise Problem(P.INVALID_OPTION, f"unknown option{plural} {named}: this route takes "
                  f"{', '.join(taken)}", option=unknown[0], unknown=unknown)


def _output_format(value: Any) -> str:
    fmt = "glb" if value is None else str(value).strip().lower().lstrip(".")
    if fmt not in OUTPUT_FORMATS:
        raise OptionError("format", f"format must be one of {', '.join(OUTPUT_FORMATS)}, "
                                    f"not {fmt!r}")
    return fmt


def resolve_request(values: Mapping[str, Any], table: tuple[RequestOption, ...],
                    spec: ModelSpec, settings: Settings) -> RequestOptions:
    """Check a request's options and resolve them against the model, once.

    Parameters
    ----------
    values : mapping
        Option values as sent, by name (missing, None or ``""``: not given); a name not
        in ``table`` is refused (:func:`refuse_unknown`).
    table : tuple of RequestOption
        The route's options (:data:`GENERATE_ROUTE_OPTIONS` or
        :data:`REPAIR_ROUTE_OPTIONS`).
    spec : ModelSpec
    settings : Settings
        ``default_steps`` and ``max_steps`` apply.

    Returns
    -------
    RequestOptions

    Raises
    ------
    Problem
        :func:`refuse_unknown` of names the route does not take, else
        :func:`option_problem` of the first bad option.
    """
    refuse_unknown(values, table)
    try:
        given = {o.name: o.parse(values.get(o.name)) for o in table}
        fmt = _output_format(given.pop("format", None))
        weld = bool(given.pop("weld", None))
        max_growth = _max_growth(given.pop("max_growth", None), settings)
        chosen = {k: v for k, v in given.items() if v is not None}
        if chosen.get("seed") is None:
            chosen["seed"] = secrets.randbits(RANDOM_SEED_BITS)
        if chosen.get("steps") is None and settings.default_steps is not None:
            chosen["steps"] = min(settings.default_steps, spec.schedule.timesteps)
        sent = GenerateOptions(**chosen)
        resolved = sent.resolve(spec)
        most = min(settings.max_steps, spec.schedule.timesteps)
        if resolved.steps is not None and resolved.steps > most:
            raise OptionError("steps", f"steps must be in 1..{most}, not {resolved.steps}")
    except OptionError as error:
        raise option_problem(error) from None
    return RequestOptions(fmt, sent, resolved, weld, max_growth)


def _max_growth(value: float | None, settings: Settings) -> float | None:
    """``max_growth`` checked against 0 .. ``settings.max_repair_growth``."""
    most = settings.max_repair_growth
    if value is not None and not 0.0 <= value <= most:
        raise OptionError("max_growth", f"max_growth must be in 0..{most:g}, not {value!r}")
    return value


def grpc_values(request: Any, table: tuple[RequestOption, ...]) -> dict[str, Any]:
    """The options of a gRPC request message, by name (unset fields: None).

    Every option of ``table`` is a field of the message with the same name; ``optional``
    ones are None when unset.
    """
    by_name = request.DESCRIPTOR.fields_by_name
    return {o.name: (getattr(request, o.name)
                     if not by_name[o.name].has_presence or request.HasField(o.name) else None)
            for o in table}


def reported_options(options: GenerateOptions, names: tuple[str, ...] = OPTION_FIELDS
                     ) -> dict[str, Any]:
    """The resolved options a reply reports, by name (``target_vertices`` None when not
    asked for: the JSON format has it as null; headers and gRPC leave it out)."""
    values = options.to_dict()
    return {k: values[k] for k in names}
