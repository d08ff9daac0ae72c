"""Helpers of the constitutive-core tests (no DOLFINx).

Everything here is independent of the package under test except the small factories at the end:
random rotations, matrices with prescribed (signed) singular values, finite differences and
closed-form reference energies written straight from the formulas in docs/design.md.
"""

import functools
import inspect
import itertools

import numba
import numpy as np

import dolfinx_invertible as di

# Deliberately different order-one values so that a mu/lambda mix-up cannot go unnoticed.
MU = 0.8
LAM = 1.7
EPS_C1 = 0.4
EPS_C2 = 0.9

# Parametrised over the registries: a model or extension added there is tested everywhere.
MODEL_NAMES = tuple(model.__name__ for model in di.constitutive.models.MODELS)
#: Every extension, None for the plain model.
EXTENSION_NAMES = tuple(
    None if extension is None else extension.__name__
    for extension in di.constitutive.extensions.EXTENSIONS
)
#: The extensions with an energy (and None).
ENERGY_EXTENSION_NAMES = tuple(
    None if extension is None else extension.__name__
    for extension in di.constitutive.extensions.EXTENSIONS
    if extension is None or extension.has_energy
)
DIMS = (2, 3)


@functools.cache
def compiled_caller(function):
    """A compiled function that calls ``function`` with the same arguments, callable from Python.

    The package's inner functions are compiled for compiled callers only (no Python entry point,
    ``constitutive/compiled.py``), and its dispatch stubs resolve only while compiling; a test
    calls either through this. Python ``int`` arguments are compiled into the caller as
    constants, one caller per set of their values: an id or a dimension that the callee needs
    as a literal is one from the start. Passed as arguments, numba would type the caller again
    on every call before finding its literal version (a tenth of a second per call). NumPy
    integers stay run-time values.
    """
    names = inspect.getfullargspec(getattr(function, "py_func", function)).args

    def call(*arguments):
        constants = tuple(
            (name, value) for name, value in zip(names, arguments) if type(value) is int
        )
        passed = [value for value in arguments if type(value) is not int]
        return _caller_with_constants(function, tuple(names), constants)(*passed)

    return call


@functools.cache
def _caller_with_constants(function, names, constants):
    fixed = dict(constants)
    parameters = ", ".join(name for name in names if name not in fixed)
    namespace = {"_callee": function, **fixed}
    source = f"def call({parameters}):\n    return _callee({', '.join(names)})\n"
    exec(source, namespace)  # noqa: S102
    return numba.njit(namespace["call"])


# --------------------------------------------------------------------------------------------
# Linear algebra
# --------------------------------------------------------------------------------------------
def random_rotation(rng, d):
    """A Haar-distributed rotation (orthogonal, det +1) of size d x d."""
    q, r = np.linalg.qr(rng.standard_normal((d, d)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def random_rotations(rng, n, d):
    return np.array([random_rotation(rng, d) for _ in range(n)]).reshape(n, d, d)


def compose(sigma, R1, R2):
    """F = R1 diag(sigma) R2^T, batched over the leading axis."""
    return np.einsum("nij,nj,nkj->nik", R1, sigma, R2)


def matrices_with_sigma(rng, sigma):
    """Random F = R1 diag(sigma) R2^T for each row of sigma (signed values, shape (n, d))."""
    sigma = np.atleast_2d(np.asarray(sigma, dtype=float))
    n, d = sigma.shape
    return compose(sigma, random_rotations(rng, n, d), random_rotations(rng, n, d))


def signed_svd(F):
    """Reference signed SVD from LAPACK: F = U diag(s) V^T with U, V rotations.

    The sign fix goes on the last (smallest magnitude) singular value, as in the contract.
    """
    U, s, Vt = np.linalg.svd(F)
    V = np.swapaxes(Vt, -1, -2).copy()
    U = U.copy()
    for W in (U, V):
        neg = np.linalg.det(W) < 0
        W[neg, :, -1] *= -1.0
        s[neg, -1] *= -1.0
    return U, s, V


def sym_norm_rel(T):
    """Relative asymmetry |T - T^T| / |T| per sample."""
    num = np.linalg.norm(T - np.swapaxes(T, -1, -2), axis=(-2, -1))
    return num / np.maximum(np.linalg.norm(T, axis=(-2, -1)), np.finfo(float).tiny)


def jdet(sigma):
    return np.prod(sigma, axis=-1)


# --------------------------------------------------------------------------------------------
# Finite differences and comparisons
# --------------------------------------------------------------------------------------------
def fd_jacobian(fun, X, h):
    """Central differences of a batched function.

    X has shape (n, *s); fun maps (m, *s) -> (m, *o). Returns D of shape (n, prod(s), *o) with
    D[a, k] = d fun(X[a]) / d X[a].flat[k]. All 2 n prod(s) evaluations go in one batch.
    """
    X = np.asarray(X, dtype=float)
    n, shape = X.shape[0], X.shape[1:]
    m = int(np.prod(shape))
    E = np.eye(m).reshape((m, *shape))
    Xp = (X[:, None] + h * E[None]).reshape((n * m, *shape))
    Xm = (X[:, None] - h * E[None]).reshape((n * m, *shape))
    fp, fm = np.asarray(fun(Xp)), np.asarray(fun(Xm))
    D = (fp - fm) / (2.0 * h)
    return D.reshape((n, m, *D.shape[1:]))


def fd_stress(energy, F, h):
    """P_ij ~ d energy / d F_ij."""
    return fd_jacobian(energy, F, h).reshape(F.shape)


def fd_tangent(stress, F, h):
    """T[a, i*d+j, k*d+l] ~ d P_ij / d F_kl (the contract's layout)."""
    n, d = F.shape[0], F.shape[-1]
    D = fd_jacobian(stress, F, h).reshape(n, d * d, d * d)  # [a, kl, ij]
    return np.swapaxes(D, 1, 2)


def assert_rel_close(actual, expected, rtol, scale, what=""):
    """Per sample: |actual - expected| <= rtol * (|expected| + scale), Frobenius norms.

    `scale` is a characteristic magnitude (e.g. mu for stresses) so that quantities that happen to
    vanish are compared in absolute terms at that scale.
    """
    actual = np.asarray(actual, dtype=float)
    expected = np.asarray(expected, dtype=float)
    assert actual.shape == expected.shape, (what, actual.shape, expected.shape)
    n = expected.shape[0] if expected.ndim else 1
    a = actual.reshape(n, -1)
    e = expected.reshape(n, -1)
    assert np.all(np.isfinite(a)), f"{what}: non-finite values in samples {_bad(a)}"
    err = np.linalg.norm(a - e, axis=1)
    bound = rtol * (np.linalg.norm(e, axis=1) + scale)
    bad = np.flatnonzero(~(err <= bound))
    if bad.size:
        i = bad[np.argmax(err[bad] / bound[bad])]
        raise AssertionError(
            f"{what}: {bad.size}/{n} samples off; worst sample {i}: |diff| = {err[i]:.3e} > "
            f"{bound[i]:.3e}\n  expected {e[i]}\n  actual   {a[i]}"
        )


def _bad(a):
    return np.flatnonzero(~np.all(np.isfinite(a), axis=1))


# --------------------------------------------------------------------------------------------
# Singular value samples
# --------------------------------------------------------------------------------------------
def random_sigma(rng, n, d, low, high, inverted=False, min_gap=0.05, keep=None):
    """n rows of singular values, magnitudes in [low, high] sorted descending, pairwise gaps of at
    least min_gap (so also |sigma_i + sigma_j| >= min_gap when the last one is negated)."""
    rows = []
    while len(rows) < n:
        s = np.sort(rng.uniform(low, high, d))[::-1]
        if d > 1 and np.min(-np.diff(s)) < min_gap:
            continue
        if inverted:
            s[-1] = -s[-1]
        if keep is not None and not keep(s):
            continue
        rows.append(s)
    return np.array(rows)


def jitter(rng, base, reps, amount):
    """reps copies of every row of base, each multiplied by (1 + U(-amount, amount))."""
    base = np.atleast_2d(np.asarray(base, dtype=float))
    out = np.repeat(base, reps, axis=0)
    return out * (1.0 + rng.uniform(-amount, amount, out.shape))


# Explicit C1 regions (eps = 0.4): number of singular values below eps = 0, 1, 2, (3), with and
# without a negative one. Margins to eps, to each other and to sigma_i + sigma_j = 0 are >= 0.05,
# so a 1 % jitter plus a 1e-6 finite-difference step never crosses a kink.
C1_REGION_SIGMAS = {
    2: [(1.3, 0.7), (1.2, 0.2), (1.2, -0.2), (0.3, 0.15), (0.3, -0.15)],
    3: [
        (1.3, 1.0, 0.7),
        (1.2, 0.8, 0.2),
        (1.2, 0.8, -0.2),
        (1.5, 1.1, -0.3),
        (1.1, 0.3, 0.15),
        (1.1, 0.3, -0.15),
        (0.35, 0.25, 0.1),
        (0.35, 0.25, -0.1),
    ],
}

# C2 (eps = 0.9): both sides of J = eps (|J - eps| >= 0.04 before jitter), including strongly
# inverted points; again |sigma_i + sigma_j| and |sigma_i - sigma_j| >= 0.05.
C2_SIGMAS = {
    2: [(1.2, 0.9), (1.3, 0.75), (1.0, 0.85), (1.3, 0.4), (0.5, 0.2), (1.2, -0.3), (1.5, -1.2)],
    3: [
        (1.2, 1.0, 0.9),
        (1.4, 1.0, 0.7),
        (1.0, 0.95, 0.9),
        (1.3, 0.8, 0.5),
        (2.0, 0.3, 0.1),
        (1.2, 0.7, -0.3),
        (0.6, 0.4, -0.2),
        (1.5, 1.2, -0.9),
    ],
}


def sigma_cases(rng, model, ext, d, reps=3):
    """Well separated singular values suitable for finite differences, per extension."""
    if ext == "C1":
        regions = jitter(rng, C1_REGION_SIGMAS[d], 1, 0.01)
        away = lambda s: np.min(np.abs(s - EPS_C1)) > 0.03  # noqa: E731
        rand = [random_sigma(rng, 3 * reps, d, 0.05, 1.8, inv, keep=away) for inv in (0, 1)]
        return np.concatenate([regions, *rand])
    if ext in ("C2", "IFE"):
        return jitter(rng, C2_SIGMAS[d], reps, 0.003)
    pos = random_sigma(rng, 4 * reps, d, 0.5, 1.8)
    if model == "NeoHookean":
        return pos
    return np.concatenate([pos, random_sigma(rng, 4 * reps, d, 0.3, 1.8, inverted=True)])


def c2_root(sigma, eps):
    """Smallest s in (0, 1) with prod(1 + s (sigma_i - 1)) = eps, by np.roots + Newton polish."""
    a = np.asarray(sigma, dtype=float) - 1.0
    poly = np.poly1d([1.0])
    for ai in a:
        poly = poly * np.poly1d([ai, 1.0])
    poly = poly - eps
    roots = poly.roots
    real = roots[(np.abs(roots.imag) < 1e-8) & (roots.real > 0)].real
    s = float(np.min(real))
    dpoly = poly.deriv()
    for _ in range(3):
        s -= poly(s) / dpoly(s)
    assert 0.0 < s < 1.0
    return s


# --------------------------------------------------------------------------------------------
# Reference energies straight from the formulas (numpy, signed sigma of shape (n, d))
# --------------------------------------------------------------------------------------------
def reference_energy(name, sigma, mu=MU, lam=LAM):
    s = np.asarray(sigma, dtype=float)
    d = s.shape[-1]
    J = np.prod(s, axis=-1)
    sq = np.sum(s**2, axis=-1)
    if name == "NeoHookean":
        lnJ = np.log(J)
        return mu / 2 * (sq - d) - mu * lnJ + lam / 2 * lnJ**2
    if name == "Corotated":
        return mu * np.sum((s - 1) ** 2, axis=-1) + lam / 2 * np.sum(s - 1, axis=-1) ** 2
    if name == "FixedCorotated":
        return mu * np.sum((s - 1) ** 2, axis=-1) + lam / 2 * (J - 1) ** 2
    if name == "StableNeoHookean":
        return mu / 2 * (sq - d) - mu * (J - 1) + (lam + mu) / 2 * (J - 1) ** 2
    if name == "ARAP":
        return mu * np.sum((s - 1) ** 2, axis=-1)
    if name == "StVK":
        e = s**2 - 1
        return mu / 4 * np.sum(e**2, axis=-1) + lam / 8 * np.sum(e, axis=-1) ** 2
    raise KeyError(name)


def youngs_modulus(mu, lam):
    return mu * (3 * lam + 2 * mu) / (lam + mu)


def subsets(indices):
    idx = list(indices)
    sizes = range(len(idx) + 1)
    return itertools.chain.from_iterable(itertools.combinations(idx, r) for r in sizes)


# --------------------------------------------------------------------------------------------
# Factories for the package under test
# --------------------------------------------------------------------------------------------
def model_lam(name):
    return 0.0 if name == "ARAP" else LAM


def make_model(name, mu=MU, lam=LAM):
    cls = getattr(di, name)
    if name == "ARAP":
        return cls(mu=mu)
    return cls(mu=mu, lam=lam)


def make_extension(ext, **kwargs):
    if ext is None:
        return None
    kwargs.setdefault("eps", {"C1": EPS_C1, "C2": EPS_C2, "IFE": EPS_C2}[ext])
    return getattr(di, ext)(**kwargs)


def make_material(name, ext=None, **ext_kwargs):
    return di.Material(make_model(name), extension=make_extension(ext, **ext_kwargs))


def is_defined(name, ext, sigma):
    """Whether (model, extension) has an energy/stress at these signed singular values."""
    if name == "NeoHookean" and ext is None:
        return jdet(sigma) > 0
    return np.ones(np.shape(sigma)[:-1], dtype=bool)
