"""The one parsing rule of every option (``spacemesh.runtime.options.parse_value``).

REST (query, form, JSON, streaming), gRPC and both command lines parse options here, so
these cases hold everywhere: integer options take only integers (``1e3``, ``1.0`` and
JSON ``2.0`` are refused, never converted), number options decimal numbers, boolean
options true/false words, text options text.
"""

from __future__ import annotations

import numpy as np
import pytest

from spacemesh.runtime.options import (
    OPTION_FIELDS,
    OPTION_KINDS,
    GenerateOptions,
    OptionError,
    parse_value,
)

#: (kind, value as sent, parsed value); None: not given.
ACCEPTED = [
    (int, "7", 7), (int, " +7 ", 7), (int, "-3", -3), (int, "0", 0), (int, 7, 7),
    (int, np.int64(7), 7), (int, str(2**62 + 1), 2**62 + 1), (int, "", None), (int, None, None),
    (float, "0.5", 0.5), (float, ".5", 0.5), (float, "5.", 5.0), (float, "5e-3", 0.005),
    (float, "-1E2", -100.0), (float, 1, 1.0), (float, 0.25, 0.25), (float, np.float32(0.5), 0.5),
    (bool, "true", True), (bool, "FALSE", False), (bool, " yes ", True), (bool, "0", False),
    (bool, 1, True), (bool, True, True),
    (str, "ddim", "ddim"), (str, " points ", "points"),
]
#: (kind, value as sent): refused with "NAME must be ...".
REFUSED = [
    (int, "1e3"), (int, "1.0"), (int, "2.0"), (int, "500.0"), (int, 1e3), (int, 1.0),
    (int, 2.0), (int, "0x10"), (int, "1_000"), (int, "\u0661\u0662"), (int, "seven"),
    (int, " "), (int, True), (int, [1]), (int, "9" * 31),
    (float, "nan"), (float, "inf"), (float, "1_0"), (float, "half"), (float, "0x1p3"),
    (float, True), (float, [0.5]),
    (bool, "maybe"), (bool, "2"), (bool, 2), (bool, 1.0), (bool, [True]),
    (str, 5), (str, ["ddim"]),
]
WORDS = {int: "an integer", float: "a number", bool: "true or false", str: "text"}


@pytest.mark.parametrize(("kind", "value", "parsed"), ACCEPTED, ids=repr)
def test_accepted_values_are_typed(kind, value, parsed):
    result = parse_value("option", kind, value)
    assert result == parsed and type(result) is type(parsed)


@pytest.mark.parametrize(("kind", "value"), REFUSED, ids=repr)
def test_refused_values_name_the_option_and_the_type(kind, value):
    with pytest.raises(OptionError) as info:
        parse_value("option", kind, value)
    assert info.value.option == "option"
    assert str(info.value).startswith(f"option must be {WORDS[kind]}"), str(info.value)


def test_a_refused_value_is_quoted_short():
    with pytest.raises(OptionError) as info:
        parse_value("seed", int, "x" * 10_000)
    assert len(str(info.value)) < 120


def test_every_option_has_a_kind():
    assert tuple(OPTION_KINDS) == OPTION_FIELDS
    assert set(OPTION_KINDS.values()) == {int, float, bool, str}


def test_generate_options_parse_text_as_the_service_does():
    options = GenerateOptions.parse({"seed": "7", "steps": None, "start": "points",
                                     "start_time": "0.5", "target_vertices": "60",
                                     "tolerance": "", "samples": "2", "raw": "true"})
    assert options == GenerateOptions(seed=7, start="points", start_time=0.5,
                                      target_vertices=60, samples=2, raw=True)
    for values, name in (({"seed": "1e3"}, "seed"), ({"samples": "2.0"}, "samples"),
                         ({"target_vertices": "500.0"}, "target_vertices"),
                         ({"colour": "red"}, "colour")):
        with pytest.raises(OptionError) as info:
            GenerateOptions.parse(values)
        assert info.value.option == name and name in str(info.value)
