"""Twisting column: a 6×1×1 column set spinning about its axis (benchmark, Aguirre et al. 2014).

Dynamic. The base x = 0 is fixed; the initial velocity is a twist about the column's axis,
v = ω(x) (0, −(z − z_c), y − y_c) with ω(x) = 100 sin(πx/12) rad/s; Neo-Hookean, E = 1.7e7 Pa,
ν = 0.45, ρ = 1100 kg/m³. The exact solution conserves the total (kinetic + elastic) energy,
275 ω₀² J at the start; the summary reports it at the start and the end and the relative loss,
``energy.npy`` its history (time, kinetic, elastic). Backward Euler's loss is large; BDF2
(``--scheme bdf2``) loses far less.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible.scenes.scene import Scene

__all__ = ["TwistingColumn"]

#: Peak angular velocity [rad/s].
OMEGA = 100.0


class TwistingColumn(Scene):
    """A column twisting about its axis; energy conservation of the time integrator."""

    name = "twisting-column"
    description = "6×1×1 column with an initial twist about its axis; total energy over time"
    figure = "benchmark (Aguirre et al. 2014)"
    dynamic = True
    defaults = {"E": 1.7e7, "nu": 0.45, "density": 1100.0, "extension": "none", "dt": 0.005,
                "t_end": 0.3, "resolution": 2}  # fmt: skip

    def create_mesh(self):
        """Return [0, 6] × [0, 1]² with ``resolution`` cells across."""
        n = self.parameters.resolution
        return dolfinx.mesh.create_box(self.comm, [[0.0, 0.0, 0.0], [6.0, 1.0, 1.0]], [6 * n, n, n])

    def boundary_conditions(self, space):
        """Fix the base x = 0."""
        facets = dolfinx.mesh.locate_entities_boundary(
            space.mesh, 2, lambda x: np.isclose(x[0], 0.0)
        )
        dofs = dolfinx.fem.locate_dofs_topological(space, 2, facets)
        return [dolfinx.fem.dirichletbc(np.zeros(3), dofs, space)], None

    def initial_velocity(self):
        """Return the twist about the axis y = z = 1/2."""

        def velocity(x):
            omega = OMEGA * np.sin(np.pi * x[0] / 12.0)
            return np.stack([0.0 * x[0], -omega * (x[2] - 0.5), omega * (x[1] - 0.5)])

        return velocity

    def _elastic_energy(self, run) -> float:
        forms = run.stepper.problem.forms
        local = dolfinx.fem.assemble_scalar(forms.energy)
        return run.mesh.comm.allreduce(local, op=MPI.SUM)

    def __init__(self, parameters, comm):
        super().__init__(parameters, comm)
        #: (time, kinetic, elastic) of every stored step.
        self.history: list[tuple[float, float, float]] = []

    def record(self, run) -> None:
        """Record kinetic and elastic energy."""
        self.history.append((run.time, run.kinetic_energy, self._elastic_energy(run)))

    def checkpoint_state(self) -> dict:
        """Return the energy history (its first entry is the initial energy)."""
        return {"history": [list(entry) for entry in self.history]}

    def restore(self, state: dict) -> None:
        """Continue the energy history from :meth:`checkpoint_state`."""
        self.history = [tuple(entry) for entry in state["history"]]

    def quantities(self, run) -> dict:
        """Return the total energy at the start and the end, and the relative loss."""
        start = self.history[0][1] + self.history[0][2]
        end = self.history[-1][1] + self.history[-1][2]
        return {
            "energy_initial": start,
            "energy_final": end,
            "energy_loss": 1.0 - end / start,
            "energy_initial_exact": 275.0 * OMEGA**2,
        }

    def files(self, run) -> dict:
        """Return (time, kinetic, elastic) per step."""
        return {"energy.npy": np.array(self.history)}
