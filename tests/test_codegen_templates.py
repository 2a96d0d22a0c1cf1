"""The C text armgen generates lives in armgen/data/templates/codegen/ (issue 36): every template
there is rendered by the generators, each time with exactly the values its placeholders name,
and the loader refuses a missing or an unused value."""

from importlib import resources
from string import Template

import casadi as ca
import pytest

import armgen.data
from armgen.codegen.api_kernel import Signature, extension_source
from armgen.codegen.compiled import batch_source, kernel_source
from armgen.codegen.generate import CodegenConfig, generate
from armgen.codegen.ptp_c import render_ptp_evaluator
from armgen.data import render_template
from armgen.robot import load_robot
from armgen.symbolic.model import SymbolicModel

CODEGEN_TEMPLATES = resources.files("armgen.data") / "templates" / "codegen"


def _render_everything() -> None:
    """Every generator of armgen.codegen, on inputs that take each branch: planar3 (3 DOF: no
    acceleration limits, straight-line probes), modular8 (8 DOF: all speed limits, the looped
    probe of the steps' q twins, floor), the PTP evaluator, a planner kernel, the verifier's batch,
    the API's compiled kernel (extension module)."""
    for robot in ("planar3", "modular8"):
        generate(CodegenConfig(load_robot(robot)))
    render_ptp_evaluator("armgen", "float")
    x = ca.SX.sym("x", 2)
    kernel_source(ca.Function("demo", [x], [ca.sin(x) * x[1]]), "armgen_kernel")
    batch_source("planar3", SymbolicModel(load_robot("planar3")).functions())
    extension_source("planar3", "armgen_api_demo",
                     {name: Signature.of(f) for name, f in SymbolicModel(load_robot("planar3")).functions().items()},
                     "double")


def test_every_template_is_rendered_with_exactly_its_placeholders(monkeypatch):
    rendered: dict[str, list[set[str]]] = {}
    template_of = armgen.data._template

    class Recording(Template):
        def substitute(self, mapping, /, **values):
            rendered[self.name].append(set(mapping) | set(values))
            return super().substitute(mapping, **values)

    def recording(name: str) -> Template:
        template = Recording(template_of(name).template)
        template.name = name
        rendered.setdefault(name, [])
        return template

    monkeypatch.setattr(armgen.data, "_template", recording)
    _render_everything()
    files = {f"codegen/{entry.name}" for entry in CODEGEN_TEMPLATES.iterdir()}
    assert set(rendered) == files, f"never rendered: {sorted(files - set(rendered))}"
    for name, calls in rendered.items():
        placeholders = set(template_of(name).get_identifiers())
        for keys in calls:
            assert keys == placeholders, (f"{name}: placeholders without a value {sorted(placeholders - keys)}, "
                                          f"values without a placeholder {sorted(keys - placeholders)}")


def test_a_missing_or_an_unused_value_is_refused():
    assert render_template("codegen/literal.c", P="ARM", value="0.5") == "ARM_LIT(0.5)"
    with pytest.raises(KeyError, match="codegen/literal.c needs a value for value"):
        render_template("codegen/literal.c", P="ARM")
    with pytest.raises(TypeError, match="codegen/literal.c has no placeholder for unit"):
        render_template("codegen/literal.c", P="ARM", value="0.5", unit="m")


def test_templates_hold_no_stray_dollar_and_end_with_one_line_break():
    """A '$' that starts no placeholder would be a C text error string.Template rejects late; the
    loader drops the file's last line break, so a second one would change the generated text."""
    for entry in CODEGEN_TEMPLATES.iterdir():
        text = entry.read_text(encoding="utf-8")
        assert Template(text).is_valid(), entry.name
        assert text.endswith("\n") and not text.endswith("\n\n"), entry.name
