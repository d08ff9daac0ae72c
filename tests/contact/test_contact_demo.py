"""The bowl-drop demo's scene, reusable through its setup function: the cube hits the bowl's
bottom within half a second, without any boundary vertex ever inside the bowl's wall.
"""

import importlib.util
import pathlib
import sys

from mpi4py import MPI

import pytest

from dolfinx_invertible.contact import ContactTerm, Sphere

ROOT = pathlib.Path(__file__).resolve().parents[2]


def load_demo():
    spec = importlib.util.spec_from_file_location("bowl_drop", ROOT / "demos" / "bowl_drop.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up there
    spec.loader.exec_module(module)
    return module


@pytest.mark.mpi
def test_bowl_drop_setup_and_impact():
    demo = load_demo()
    scene = demo.setup(MPI.COMM_WORLD, cells=3)
    assert isinstance(scene.term, ContactTerm)
    assert isinstance(scene.obstacles[0], Sphere) and scene.obstacles[0].inside
    assert scene.step_limit.term is scene.term
    # At rest in the middle of the bowl: the corners are 1 − √3·0.2 from the wall.
    assert scene.term.minimum_gap() == pytest.approx(1.0 - 3**0.5 * 0.2)
    figures = demo.run(scene, end_time=0.5)
    assert figures["steps"] == 50
    assert figures["penetrations"] == 0 and figures["iterate_penetrations"] == 0
    assert 0.0 < figures["minimum_gap"] < scene.term.barrier.distance  # it did hit
    assert figures["kinetic_energy"] < 0.5 * figures["peak_kinetic_energy"]  # and was stopped
