"""Every DOLFINx version difference the plugin bridges lives here, and only here.

The rest of the package calls these functions instead of the version-specific DOLFINx API.
Written against DOLFINx 0.5.2 (Debian bookworm) first; later versions add branches here.
"""

from __future__ import annotations

import contextlib

try:
    # The PyPI wheel (dolfinx-solver-*) loads its own MPI library through mpi4py, which must
    # happen before any DOLFINx binding loads; importing dolfinx_solver does that in order.
    import dolfinx_solver  # noqa: F401
except ImportError:
    pass

import dolfinx  # noqa: E402  (after the wheel's MPI)
import dolfinx.common
import dolfinx.fem
import dolfinx.io
import numpy as np
from petsc4py import PETSc

__all__ = [
    "DOLFINX_VERSION",
    "KERNEL_SIGNATURE",
    "KERNEL_TAKES_CUSTOM_DATA",
    "vector_function_space",
    "scalar_function_space",
    "petsc_vector",
    "evaluate_expression",
    "xdmf_file",
    "XDMF_XINCLUDE_NAMESPACE",
    "KSP_CONVERGED_NEGATIVE_CURVATURE",
    "SNES_DIVERGED_NOT_FINITE",
    "VTX_AVAILABLE",
    "vtx_writer",
]

DOLFINX_VERSION = tuple(int(part) for part in dolfinx.__version__.split(".")[:2])

# ufcx tabulate_tensor: (A, w, c, coordinate_dofs, entity_local_index, quadrature_permutation),
# plus a ``void* custom_data`` from DOLFINx 0.10 on.
KERNEL_TAKES_CUSTOM_DATA = DOLFINX_VERSION >= (0, 10)


def _kernel_signature():
    import numba

    pointer = numba.types.CPointer
    arguments = [
        pointer(numba.types.float64),
        pointer(numba.types.float64),
        pointer(numba.types.float64),
        pointer(numba.types.float64),
        pointer(numba.types.int32),
        pointer(numba.types.uint8),
    ]
    if KERNEL_TAKES_CUSTOM_DATA:
        arguments.append(numba.types.voidptr)
    return numba.types.void(*arguments)


KERNEL_SIGNATURE = _kernel_signature()


def _reason(reasons, *names: str) -> int:
    for name in names:
        if hasattr(reasons, name):
            return getattr(reasons, name)
    raise AttributeError(f"petsc4py has none of {', '.join(names)} in {reasons.__name__}")


# petsc4py renames converged reasons with PETSc (the DOLFINx 0.9 and 0.11 stacks ship newer
# PETSc than bookworm's 3.18); the values keep their meaning.
#: CG stopped at a direction of negative curvature (``CONVERGED_CG_NEG_CURVE`` up to PETSc 3.18).
KSP_CONVERGED_NEGATIVE_CURVATURE = _reason(
    PETSc.KSP.ConvergedReason, "CONVERGED_NEG_CURVE", "CONVERGED_CG_NEG_CURVE"
)
#: The residual is not finite (``DIVERGED_FNORM_NAN`` up to PETSc 3.22).
SNES_DIVERGED_NOT_FINITE = _reason(
    PETSc.SNES.ConvergedReason,
    "DIVERGED_FUNCTION_NANORINF",
    "DIVERGED_FNORM_NANORINF",
    "DIVERGED_FNORM_NAN",
)


def vector_function_space(mesh, degree: int = 1, family: str = "Lagrange"):
    """Vector-valued space with one component per geometric dimension."""
    if DOLFINX_VERSION < (0, 7):
        return dolfinx.fem.VectorFunctionSpace(mesh, (family, degree))
    return dolfinx.fem.functionspace(mesh, (family, degree, (mesh.geometry.dim,)))


def scalar_function_space(mesh, degree: int = 0, family: str = "DG"):
    """Scalar space, by default ("DG", 0) for per-cell diagnostics."""
    if DOLFINX_VERSION < (0, 7):
        return dolfinx.fem.FunctionSpace(mesh, (family, degree))
    return dolfinx.fem.functionspace(mesh, (family, degree))


def petsc_vector(function):
    """Return the PETSc vector wrapping a Function's dofs (ghosted)."""
    if DOLFINX_VERSION < (0, 8):
        return function.vector
    return function.x.petsc_vec


def evaluate_expression(expression, mesh, cells: np.ndarray) -> np.ndarray:
    """Values of a compiled ``dolfinx.fem.Expression`` on ``cells``: (n_cells, points × size)."""
    if DOLFINX_VERSION < (0, 7):
        return expression.eval(cells)
    return expression.eval(mesh, cells)


# The XInclude namespace DOLFINx's XDMFFile declares (and our series rewrite must keep):
# "http://" in 0.5, "https://" in 0.9 and later. The versions in between are not supported.
XDMF_XINCLUDE_NAMESPACE = (
    "http://www.w3.org/2001/XInclude"
    if DOLFINX_VERSION < (0, 9)
    else "https://www.w3.org/2001/XInclude"
)


def xdmf_file(comm, path, mode: str = "w"):
    """Return an XDMF file (``mode`` "w", "a" or "r")."""
    return dolfinx.io.XDMFFile(comm, str(path), mode)


def cpp_object(wrapper):
    """Return the C++ object behind a DOLFINx Python object (a Mesh, Constant, Form, ...).

    Most wrappers hold it as ``_cpp_object`` (0.5's Mesh as ``_mesh``); 0.5's Form subclasses it.
    """
    for attribute in ("_cpp_object", "_mesh"):
        if hasattr(wrapper, attribute):
            return getattr(wrapper, attribute)
    return wrapper


def custom_form(spaces, kernel_address: int, coefficients, constants, mesh):
    """Return a DOLFINx Form over all cells whose cell integral is a custom kernel.

    ``spaces`` are Python FunctionSpaces (none for a functional), ``coefficients`` Functions and
    ``constants`` Constants, in the order the kernel reads them.
    """
    from dolfinx import cpp

    if DOLFINX_VERSION < (0, 7):
        integrals = {cpp.fem.IntegralType.cell: ([(-1, kernel_address)], None)}
        return cpp.fem.Form_float64(
            [cpp_object(space) for space in spaces],
            integrals,
            [cpp_object(coefficient) for coefficient in coefficients],
            [cpp_object(constant) for constant in constants],
            False,
            cpp_object(mesh),
        )
    if DOLFINX_VERSION < (0, 9):
        raise NotImplementedError(
            f"custom kernel forms are not bridged for DOLFINx {dolfinx.__version__}"
        )
    tdim = mesh.topology.dim
    # Owned cells only: ghost cells are integrated by their owner, as DOLFINx's default domain.
    cells = np.arange(mesh.topology.index_map(tdim).size_local, dtype=np.int32)
    # From 0.9 on an integral receives only the coefficients listed here; any other arrives as
    # zeros, silently. Our kernels read every coefficient.
    active = np.arange(len(coefficients), dtype=np.int8)
    # 0.9 keys integrals by subdomain id (-1: everywhere); from 0.10 the id is the integral's
    # position in its list.
    integral_id = -1 if DOLFINX_VERSION < (0, 10) else 0
    # dolfinx.fem.IntegralType: the C++ enum under its 0.11 name (_IntegralType) too.
    integrals = {dolfinx.fem.IntegralType.cell: [(integral_id, kernel_address, cells, active)]}
    entity_maps = {} if DOLFINX_VERSION < (0, 10) else []
    cpp_form = cpp.fem.Form_float64(
        [cpp_object(space) for space in spaces],
        integrals,
        [cpp_object(coefficient) for coefficient in coefficients],
        [cpp_object(constant) for constant in constants],
        False,
        entity_maps,
        mesh=cpp_object(mesh),
    )
    return dolfinx.fem.Form(cpp_form)


def form_data(form) -> tuple[np.ndarray, list[np.ndarray]]:
    """Return a compiled form's packed constant values and its coefficients' value arrays.

    Together with the mesh geometry they are everything the form's kernels read. The coefficient
    arrays (owned and ghost values) are the Functions' own, not copies.
    """
    import dolfinx.cpp

    cpp_form = cpp_object(form)
    constants = dolfinx.cpp.fem.pack_constants(cpp_form)
    return constants, [coefficient.x.array for coefficient in cpp_form.coefficients]


def coordinate_element_degree(mesh) -> int:
    """Polynomial degree of the mesh geometry map."""
    geometry = mesh.geometry
    # 0.11 deprecates ``cmap`` for ``cmaps`` (one per cell type of a mixed mesh).
    cmap = geometry.cmaps[0] if hasattr(geometry, "cmaps") else geometry.cmap
    return cmap.degree


def element_family_and_degree(space) -> tuple[str, int]:
    """UFL family name ("Lagrange", "Q", "DG", ...) and polynomial degree of a space's element."""
    element = space.ufl_element()
    if DOLFINX_VERSION < (0, 7):
        return element.family(), element.degree()
    # basix.ufl elements (0.7 on) name continuous and discontinuous Lagrange alike "P".
    family = element.family_name
    if family == "P":
        family = "DG" if element.discontinuous else "Lagrange"
    return family, int(element.degree)


def element_degree(space) -> int:
    """Polynomial degree of a space's element."""
    return element_family_and_degree(space)[1]


def basix_element(space):
    """Return the scalar Basix element of a (blocked) Lagrange space."""
    return space.element.basix_element


def cell_dofs(space) -> np.ndarray:
    """Dofs of every local cell (owned cells first, then ghosts): (n_cells, dofs per cell)."""
    dofmap = space.dofmap
    if DOLFINX_VERSION < (0, 7):
        return dofmap.list.array.reshape(-1, dofmap.dof_layout.num_dofs)
    return np.asarray(dofmap.list)


def create_vector(form):
    """Return a ghosted PETSc vector laid out like the test space of a linear form."""
    import dolfinx.fem.petsc

    if DOLFINX_VERSION < (0, 11):
        return dolfinx.fem.petsc.create_vector(form)
    # 0.11 builds vectors from function spaces, not forms.
    return dolfinx.fem.petsc.create_vector(form.function_spaces[0])


def create_matrix(form):
    """Return a PETSc matrix with the sparsity pattern of a bilinear form."""
    import dolfinx.fem.petsc

    return dolfinx.fem.petsc.create_matrix(form)


def assemble_matrix_into(matrix, form, bcs, diagonal: float) -> None:
    """Add a bilinear form to ``matrix``, then flush it so that another form can be added.

    Dirichlet rows and columns are zeroed and ``diagonal`` goes on the Dirichlet diagonal.

    The flush is not optional: DOLFINx inserts the diagonal with INSERT_VALUES, and a later
    ADD_VALUES without a flush in between is an error that release builds of DOLFINx 0.5 ignore
    (the second form is silently dropped in serial) and that MPI assembly reports.
    """
    import dolfinx.fem.petsc
    from petsc4py import PETSc

    # Positional: the diagonal keyword is ``diagonal`` up to 0.9 and ``diag`` from 0.10 on.
    dolfinx.fem.petsc.assemble_matrix(matrix, form, bcs, diagonal)
    matrix.assemble(PETSc.Mat.AssemblyType.FLUSH)


def lift_residual(residual, jacobians, bcs, solution) -> None:
    """Dirichlet conditions on an assembled Newton residual, as DOLFINx's NonlinearProblem.

    Each bilinear form in ``jacobians`` is lifted on its own: lifting is linear in the matrix, so
    lifting by each summand equals lifting by the sum. ``solution`` must have current ghosts.
    Afterwards the Dirichlet rows of ``residual`` hold ``solution - g``.
    """
    import dolfinx.fem.petsc
    from petsc4py import PETSc

    # Positional arguments: the scale keyword of 0.5 is called alpha from 0.7 on.
    for jacobian in jacobians:
        dolfinx.fem.petsc.apply_lifting(residual, [jacobian], [bcs], [solution], -1.0)
    residual.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    dolfinx.fem.petsc.set_bc(residual, bcs, solution, -1.0)


def snes_solve(snes, solution) -> None:
    """``snes.solve(None, solution)``, letting an interrupt from a Python callback through.

    petsc4py 3.22 and later wrap an exception raised inside a callback (residual, tangent,
    line search) into ``PETSc.Error`` with the original as its ``__cause__``; an interrupt
    (``KeyboardInterrupt``, or any ``BaseException`` that is not an ``Exception``) must reach the
    caller as itself, as it does with older petsc4py.
    """
    try:
        snes.solve(None, solution)
    except Exception as error:
        cause = error.__cause__
        while cause is not None:
            if not isinstance(cause, Exception):
                raise cause from None
            cause = cause.__cause__
        raise


def set_dirichlet_values(vector, bcs) -> None:
    """Overwrite the owned Dirichlet entries of a PETSc vector with the boundary values."""
    import dolfinx.fem.petsc

    dolfinx.fem.petsc.set_bc(vector, bcs)


def locate_points(mesh, points: np.ndarray) -> np.ndarray:
    """For each point (shape (n, 3)), an owned cell of this rank containing it, or -1."""
    import dolfinx.geometry

    tdim = mesh.topology.dim
    points = np.ascontiguousarray(points, dtype=np.float64)
    if DOLFINX_VERSION < (0, 7):
        tree = dolfinx.geometry.BoundingBoxTree(mesh, tdim)
        candidates = dolfinx.geometry.compute_collisions(tree, points)
    else:
        tree = dolfinx.geometry.bb_tree(mesh, tdim)
        candidates = dolfinx.geometry.compute_collisions_points(tree, points)
    colliding = dolfinx.geometry.compute_colliding_cells(mesh, candidates, points)
    owned = mesh.topology.index_map(tdim).size_local
    cells = np.full(len(points), -1, dtype=np.int32)
    for index in range(len(points)):
        found = colliding.links(index)
        found = found[found < owned]
        if len(found) > 0:
            cells[index] = found[0]
    return cells


def geometry_dofmap(mesh) -> np.ndarray:
    """Geometry nodes of every local cell (owned and ghost) as a (cells, nodes) array."""
    geometry = mesh.geometry
    if DOLFINX_VERSION < (0, 7):
        dofmap = geometry.dofmap  # an AdjacencyList
        # A rank may hold no cell: the width then comes from the coordinate element.
        nodes = geometry.cmap.create_dof_layout().num_dofs
        return dofmap.array.reshape(dofmap.num_nodes, nodes)
    # 0.11 deprecates ``dofmap`` for ``dofmaps`` (one per cell type of a mixed mesh).
    return geometry.dofmaps[0] if hasattr(geometry, "dofmaps") else geometry.dofmap


def boundary_condition_dof_count(bc) -> int:
    """Return number of dofs a DirichletBC constrains that this rank owns."""
    _, owned = bc.dof_indices()
    return int(owned)


def connectivity_array(connectivity, width: int) -> np.ndarray:
    """Return a topology connectivity whose rows all have ``width`` entries as an (n, width) array.

    Every DOLFINx keeps the flat ``array`` with offsets; only its type's name changed.
    """
    return np.asarray(connectivity.array, dtype=np.int32).reshape(-1, width)


def constrained_local_dofs(bc) -> np.ndarray:
    """Return the local dof indices (owned and ghost, components unrolled) a DirichletBC fixes."""
    dofs, _ = bc.dof_indices()
    return np.asarray(dofs, dtype=np.int32)


def create_mesh_from_cells(comm, points: np.ndarray, cells: np.ndarray, cell_name: str):
    """Return a mesh of degree-1 cells given on rank 0 (other ranks pass empty arrays).

    ``cell_name`` is "triangle" or "tetrahedron"; ``points`` has shape (n, gdim).
    """
    import ufl

    gdim = points.shape[1]
    if comm.rank != 0:
        points = np.zeros((0, gdim))
        cells = np.zeros((0, cells.shape[1]), dtype=np.int64)
    points = np.ascontiguousarray(points, dtype=np.float64)
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    if DOLFINX_VERSION < (0, 7):
        domain = ufl.Mesh(ufl.VectorElement("Lagrange", getattr(ufl, cell_name), 1))
    else:
        import basix.ufl

        domain = ufl.Mesh(basix.ufl.element("Lagrange", cell_name, 1, shape=(gdim,)))
    if DOLFINX_VERSION >= (0, 10):  # the coordinate element comes before the points
        return dolfinx.mesh.create_mesh(comm, cells, domain, points)
    return dolfinx.mesh.create_mesh(comm, cells, points, domain)


def read_xdmf_mesh(comm, path, grid_name: str = "Grid"):
    """Read a mesh (in parallel) from an XDMF file written by meshio (grid name "Grid")."""
    with dolfinx.io.XDMFFile(comm, str(path), "r") as xdmf:
        return xdmf.read_mesh(name=grid_name)


#: DOLFINx's ``fem.petsc.NonlinearProblem`` drives PETSc SNES itself from 0.10 on (before, it is
#: the problem ``nls.petsc.NewtonSolver`` solves, renamed ``NewtonSolverNonlinearProblem``).
NONLINEAR_PROBLEM_IS_SNES = DOLFINX_VERSION >= (0, 10)


def form_compilation_options(form_compiler_options: dict | None, jit_options: dict | None) -> dict:
    """Return the keyword arguments of ``dolfinx.fem.form`` for these options.

    They are ``form_compiler_params`` and ``jit_params`` up to 0.6, ``form_compiler_options`` and
    ``jit_options`` from 0.7 on.
    """
    new_names = DOLFINX_VERSION >= (0, 7)
    options = {}
    if form_compiler_options is not None:
        key = "form_compiler_options" if new_names else "form_compiler_params"
        options[key] = form_compiler_options
    if jit_options is not None:
        options["jit_options" if new_names else "jit_params"] = jit_options
    return options


#: Whether DOLFINx writes ADIOS2 VTX files (built with ADIOS2; Debian bookworm's 0.5.2 is not).
VTX_AVAILABLE = bool(getattr(dolfinx.common, "has_adios2", False)) and hasattr(
    dolfinx.io, "VTXWriter"
)


def vtx_writer(comm, path, functions):
    """Return a ``VTXWriter`` (BP4) of ``functions`` that writes the mesh once."""
    options = {}
    policy = getattr(dolfinx.io, "VTXMeshPolicy", None)
    if policy is not None:
        options["mesh_policy"] = policy.reuse
    return dolfinx.io.VTXWriter(comm, str(path), list(functions), engine="BP4", **options)


@contextlib.contextmanager
def petsc_errors_untold():
    """Keep PETSc from printing its tracebacks for the duration; errors are still raised.

    petsc4py up to 3.22 has PETSc's "ignore" handler; later ones dropped it, and their "python"
    handler raises without printing.
    """
    for handler in ("ignore", "python"):
        try:
            PETSc.Sys.pushErrorHandler(handler)
        except (PETSc.Error, ValueError):
            continue
        try:
            yield
        finally:
            PETSc.Sys.popErrorHandler()
        return
    yield
