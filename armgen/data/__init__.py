"""The package data: bundled robots, examples, the firmware stub, and the templates of the C text
that armgen generates (``templates/``, read by :func:`render_template`)."""

from __future__ import annotations

from functools import cache
from importlib import resources
from string import Template


@cache
def _template(name: str) -> Template:
    # A template is a block of lines: like a line of text it does not carry its file's last line
    # break (Jinja's default too), so a rendered template fills a placeholder standing alone on
    # its own line, and text that Python joins with "\n" fills one the same way.
    text = (resources.files(__name__) / "templates" / name).read_text(encoding="utf-8")
    template = Template(text.removesuffix("\n"))
    if not template.is_valid():
        raise ValueError(f"template {name}: a '$' that starts no placeholder (write '$$' for a '$')")
    return template


def render_template(name: str, /, **values: object) -> str:
    """The text of ``armgen/data/templates/<name>`` with its ``$placeholders`` (``string.Template``)
    replaced by ``values``, without the file's last line break. The values and the placeholders
    must match exactly: a missing value is a KeyError, a value the template does not use a
    TypeError (as for a function's arguments) — a template and its caller changed apart."""
    template = _template(name)
    unused = sorted(set(values) - set(template.get_identifiers()))
    if unused:
        raise TypeError(f"template {name} has no placeholder for {', '.join(unused)}")
    try:
        return template.substitute(values)
    except KeyError as missing:
        raise KeyError(f"template {name} needs a value for {missing.args[0]}") from None
