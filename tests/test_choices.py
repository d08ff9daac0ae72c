"""Every option's choices are defined once (dolfinx_invertible.choices) and read from there.

The registry's entries resolve to what implements them; the command line offers exactly the
registry's names; Parameters refuses any other; no other module of the package spells a whole
set of choices again; the option table of docs/scenes.md is the one generated from them.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

from dolfinx_invertible import choices
from dolfinx_invertible.cli import parser
from dolfinx_invertible.scenes import Parameters, get_scene

REGISTRIES = {
    name: getattr(choices, name)
    for name in choices.__all__
    if isinstance(getattr(choices, name), choices.Choices)
}
PACKAGE = Path(choices.__file__).resolve().parent
#: The repository (the wheel lane tests an installed package: not its parent).
ROOT = Path(__file__).resolve().parent.parent


def test_every_choice_resolves_to_its_implementation():
    from dolfinx_invertible.scenes import make_material
    from dolfinx_invertible.solvers.integrators import Integrator

    for name, choice in choices.SCHEMES.items():
        integrator = choice.resolve()
        assert issubclass(integrator, Integrator) and integrator.name == name
    for name in choices.MODELS:
        model = make_material(Parameters(model=name, extension="none")).model
        assert type(model) is choices.MODELS.resolve(name)
    assert choices.EXTENSIONS.resolve("none") is None
    for name in ("c1", "c2", "ife"):
        assert choices.EXTENSIONS.resolve(name).__name__.lower() == name
    with pytest.raises(ValueError, match="scheme must be one of backward-euler, bdf2, newmark"):
        choices.SCHEMES.resolve("leapfrog")


def _scene_actions(scene: str) -> dict[str, argparse.Action]:
    top = parser()
    run = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    scenes = next(
        a for a in run.choices["run"]._actions if isinstance(a, argparse._SubParsersAction)
    )
    return {
        option: action
        for action in scenes.choices[scene]._actions
        for option in action.option_strings
    }


@pytest.mark.parametrize("scene", ["collapse", "cook-membrane"])
def test_the_command_line_offers_exactly_the_registry(scene):
    actions = _scene_actions(scene)
    for registry in REGISTRIES.values():
        if registry.option not in actions:  # --scheme: dynamic scenes only
            assert registry.option == "--scheme" and not get_scene(scene).dynamic
            continue
        assert list(actions[registry.option].choices) == list(registry.names), registry.option


@pytest.mark.parametrize(
    "field", [f for f in dataclasses.fields(Parameters) if f.metadata.get("choices")]
)
def test_parameters_refuse_a_name_outside_the_registry(field):
    registry = field.metadata["choices"]
    with pytest.raises(ValueError, match=f"{registry.option} must be one of"):
        Parameters(**{field.name: "not-a-choice"}).validate()


def _collections_of_strings(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            values = [
                element.value
                for element in node.elts
                if isinstance(element, ast.Constant) and isinstance(element.value, str)
            ]
            if len(values) == len(node.elts) and len(values) >= 2:
                yield node.lineno, frozenset(values)


def test_no_module_spells_a_set_of_choices_again():
    wanted = {frozenset(registry.names): name for name, registry in REGISTRIES.items()}
    found = []
    for path in PACKAGE.rglob("*.py"):
        if path.name == "choices.py":
            continue
        for line, values in _collections_of_strings(ast.parse(path.read_text())):
            if values in wanted:
                found.append(f"{path.relative_to(PACKAGE)}:{line} spells {wanted[values]}")
    assert not found, found


def test_the_documented_option_table_is_the_generated_one():
    script = ROOT / "tools" / "options_table.py"
    completed = subprocess.run([sys.executable, str(script), "--check"], capture_output=True)
    assert completed.returncode == 0, "docs/scenes.md: run python tools/options_table.py"
    table = (ROOT / "docs" / "scenes.md").read_text(encoding="utf-8")
    for registry in REGISTRIES.values():
        if registry.option != "--format":
            assert f"`{registry.option} {{{','.join(registry.names)}}}`" in table
