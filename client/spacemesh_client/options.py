"""The generate options the SDK sends, by the names the service and the model use.

The SDK depends on no other SpaceMesh package, so it mirrors the names of
``spacemesh.runtime.options.OPTION_FIELDS`` here (tests/client checks that they are
equal, and that :meth:`Client.generate` takes exactly these keywords). From this table
come the REST query parameters (:func:`query_params`), the gRPC fields (the same names),
the ``spacemesh-client generate`` flags, and the reading of the resolved options a
response reports (``X-SpaceMesh-<Name>`` headers, ``MeshReply`` fields).

:meth:`Option.parse` reads a flag's text by the service's one rule
(``spacemesh.runtime.options.parse_value``; tests/client checks that both accept and
refuse the same texts): an integer option takes only digits with an optional sign
(``--seed 1e3`` and ``--samples 2.0`` are refused, not converted), a number option a
decimal number with an optional exponent (not ``nan`` or ``inf``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: The text of an integer option: decimal digits with an optional sign.
INTEGER_TEXT = re.compile(r"[+-]?[0-9]+")
#: The text of a number option: decimal digits with an optional sign, fraction and exponent.
NUMBER_TEXT = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: What each text pattern's option type is called in an error.
_EXPECTED = {int: "an integer (digits only, no fraction or exponent)", float: "a number"}


@dataclass(frozen=True)
class Option:
    """One generate option.

    Attributes
    ----------
    name : str
        Keyword argument, query parameter, gRPC field and JSON key.
    kind : type
        ``int``, ``float``, ``bool`` or ``str``.
    help : str
        One line for ``--help``.
    """

    name: str
    kind: type
    help: str

    @property
    def flag(self) -> str:
        """The command-line flag: ``start_time`` -> ``--start-time``."""
        return "--" + self.name.replace("_", "-")

    @property
    def header(self) -> str:
        """The name of the response header that reports it (lower case)."""
        return "x-spacemesh-" + self.name.replace("_", "-")

    def parse(self, text: str) -> Any:
        """A flag's text as :attr:`kind`, by the service's rule.

        Parameters
        ----------
        text : str
            Surrounding whitespace is ignored.

        Returns
        -------
        Any
            ``int``, ``float`` or ``str`` (a bool option is a flag without a value).

        Raises
        ------
        ValueError
            Text that is not of the option's type: "NAME must be an integer ...".
        """
        stripped = text.strip()
        pattern = {int: INTEGER_TEXT, float: NUMBER_TEXT}.get(self.kind)
        if pattern is None:
            return stripped
        if pattern.fullmatch(stripped) is None:
            raise ValueError(f"{self.name} must be {_EXPECTED[self.kind]}, not {text!r}")
        return self.kind(stripped)

    def from_text(self, text: str) -> Any:
        """A reported value (a header) as :attr:`kind`; None when it cannot be read."""
        try:
            if self.kind is bool:
                return text.strip().lower() == "true"
            return self.kind(text)
        except ValueError:
            return None


#: Every generate option, in the service's order.
GENERATE_OPTIONS: tuple[Option, ...] = (
    Option("seed", int, "random seed: the same seed and options give the same mesh "
           "(default: the server picks one and reports it)"),
    Option("steps", int, "sampler steps (default: the model's)"),
    Option("sampler", str, "ddim or ddpm (default: the model's)"),
    Option("start", str, "where the vertices start: noise (the paper) or points (chosen on "
           "the input) (default: the model's)"),
    Option("start_time", float, "with --start points: fraction of the diffusion to denoise "
           "from, 0..1 (0: the chosen points as they are)"),
    Option("target_vertices", int, "vertices of the mesh (within 10%%), 4..10,000; needs "
           "--start points"),
    Option("tolerance", float, "the smallest mesh whose mean distance from the points is "
           "at most this fraction of their diagonal, 1e-4..0.5; not with --target-vertices"),
    Option("samples", int, "try this many seeds (1..16) and keep the mesh that fits best"),
    Option("raw", bool, "the networks' mesh without the geometry stage"),
    Option("surface", str, "auto, closed or open: closed is watertight, open is trimmed to "
           "where the points are (scans seen from some sides only); auto (default) opens "
           "when the points leave a large part of the closed mesh unsupported"),
    Option("face_type", str, "triangles (default) or polygons: flat regions merged into "
           "planar polygons (quads needs a model trained on quad meshes)"),
)
#: Names of :data:`GENERATE_OPTIONS`.
OPTION_NAMES: tuple[str, ...] = tuple(o.name for o in GENERATE_OPTIONS)
#: The generate options a repair takes too.
REPAIR_OPTION_NAMES = ("seed", "steps", "sampler")


def chosen(**values: Any) -> dict[str, Any]:
    """The options given (not None), by name."""
    unknown = set(values) - set(OPTION_NAMES)
    if unknown:
        raise TypeError(f"unknown generate options: {', '.join(sorted(unknown))}")
    return {k: v for k, v in values.items() if v is not None}


def query_params(options: Mapping[str, Any]) -> dict[str, Any]:
    """Options as REST query parameters (booleans as ``true``/``false``)."""
    return {k: (str(v).lower() if isinstance(v, bool) else v) for k, v in options.items()}


def options_from_headers(headers: Mapping[str, str]) -> dict[str, Any]:
    """The resolved options a REST response reports (those it has headers for)."""
    h = {k.lower(): v for k, v in headers.items()}
    values = {o.name: o.from_text(h[o.header]) for o in GENERATE_OPTIONS if o.header in h}
    return {k: v for k, v in values.items() if v is not None}
