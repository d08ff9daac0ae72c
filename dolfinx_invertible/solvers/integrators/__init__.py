"""Implicit time integrators written as incremental potentials, one class per module.

Every step of :class:`~dolfinx_invertible.ImplicitDynamics` minimises over the new displacement x

    E(x) = ½ W ‖x − x̃‖²_M + Π(x),

whose stationarity condition is the integrator's discrete momentum balance; being a
minimisation, the energy line search and the step limits apply unchanged. An integrator keeps
its history (displacement, velocity, and what else its formula reads), returns W and x̃ for a
step (:meth:`~.base.Integrator.inertia`) and advances its history once the step is accepted
(:meth:`~.base.Integrator.commit`).

- :mod:`.base`: :class:`Integrator`, the protocol, and :class:`MultistepIntegrator`, the
  integrators whose velocity is a combination of the positions at the last steps;
- :mod:`.backward_euler`: :class:`BackwardEuler`, first order, L-stable;
- :mod:`.bdf2`: :class:`BDF2`, second order, variable step;
- :mod:`.newmark`: :class:`Newmark`, the average-acceleration rule, second order and
  energy-conserving for linear elasticity.

:data:`INTEGRATORS` is built from the ``--scheme`` registry
(:data:`dolfinx_invertible.choices.SCHEMES`): adding an integrator is a module here and an
entry there.
"""

from __future__ import annotations

from dolfinx_invertible.choices import SCHEMES
from dolfinx_invertible.solvers.integrators.backward_euler import BackwardEuler
from dolfinx_invertible.solvers.integrators.base import Integrator, MultistepIntegrator
from dolfinx_invertible.solvers.integrators.bdf2 import BDF2
from dolfinx_invertible.solvers.integrators.newmark import Newmark

__all__ = [
    "BDF2",
    "INTEGRATORS",
    "BackwardEuler",
    "Integrator",
    "MultistepIntegrator",
    "Newmark",
]

#: Integrators by ``scheme`` name.
INTEGRATORS: dict[str, type[Integrator]] = {name: SCHEMES.resolve(name) for name in SCHEMES}
