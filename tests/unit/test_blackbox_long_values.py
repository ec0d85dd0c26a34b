"""A long value in a black box's ``model.toml`` is refused with a short message: its start and its length.

A format spec of 3,000 characters was quoted whole, twice (once by rivercal, once inside Python's own
complaint), in a message of over 6,000 characters; the fuzz of the model file's fields requires every
message to stay short. Quantity names, output series names and environment variables (also in the field
path) are quoted the same way, and a path (a template whose name is too long for the system) is shown by its
start and end.
"""

from __future__ import annotations

import re

import pytest

from rivercal.models import load_model
from rivercal.models.config import ModelFileError
from tests.blackbox_models import make_model

LONG = "a" * 3000


@pytest.mark.parametrize(("old", "new", "field", "why"), [
    ('format = ".6f"', f'format = "{LONG}"', r"blackbox\.quantities\.crest\.format",
     "is not a format spec for a number"),
    ("[blackbox.quantities.crest]", f"[blackbox.quantities.{LONG}]", r"blackbox\.quantities",
     "use letters, digits"),
    ('"S.h" = "level"', f'"{LONG}" = "level"', r"blackbox\.outputs", "is not '<station>.<quantity>'"),
    ('templates = [{ source = "input.json.tmpl" }]', f'templates = [{{ source = "{LONG}" }}]',
     r"blackbox\.templates\[0\]\.source", "is unreadable (File name too long)"),
    ('env = { TOY_MODE = "" }', f'env = {{ TOY_MODE = "", {LONG} = "\\u0000" }}', r"blackbox\.env\.a{40}…:",
     "is not an environment variable"),
])
def test_a_long_value_is_quoted_by_its_start_and_length(tmp_path, old, new, field, why) -> None:
    make_model(tmp_path)
    toml = tmp_path / "model.toml"
    text = toml.read_text()
    assert old in text
    toml.write_text(text.replace(old, new, 1))
    with pytest.raises(ModelFileError) as info:
        load_model(toml)
    message = str(info.value)
    assert re.search(field, message) and why in message
    assert re.search(r"\(3,\d\d\d characters\)", message) and "a" * 101 not in message
    assert len(message) < 500
