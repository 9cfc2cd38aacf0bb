"""Shape-ICP: Gauss-Newton fit of a similarity and linear-model coefficients (thesis §4.3).

A model vertex i sits in the world at

    x_i = s R (mu_i + B_i c) + t                                       (thesis eq. 20, 22)

with scale s, rotation R, coefficients c (standard-normal units) and translation t. One
Gauss-Newton step linearises every residual around the current parameters (eq. 37-39):

    dx_i = p~_i ds  +  dtheta x p~_i  +  s R B_i dc  +  dt,      p~_i = s R (mu_i + B_i c)

and updates ``s <- (1 + ds) s``, ``R <- rot(dtheta) R``, ``c <- c + dc``, ``t <- t + dt``
(eq. 44-45). The cost adds the smoothness rows lambda1 * Gamma (eq. 40-41) and the
deformation prior lambda2 * Lambda (eq. 42) to the data (eq. 43):

    E = sum_rows w r^2 + lambda1^2 |Gamma c|^2 + lambda2^2 |Lambda c|^2

Data come in groups of rows (``rows.py``) that a caller composes freely in one solve.

The solver forms the normal equations ``(J^T W J + priors) d = J^T W r`` of the 7 + K
parameters directly (never the Jacobian of a 3-D registration, 33k rows by 7 + K columns),
Jacobi-scales them and solves by Cholesky; a near-singular system is reported with the
parameters it cannot determine. Why the assembly looks the way it does:

- rows whose weight is the same for the three coordinates of a vertex ("isotropic", full
  3-D targets) contribute ``s^2 sum_i w_i B_i^T B_i`` to the shape block, independent of R
  and of the targets, so that Gram matrix is cached and only corrected for the vertices
  whose weight changed (ICP outliers); their other terms need one pass over the basis;
- other rows (masked, image, point-to-plane) are contracted with the basis seen from the
  model frame (``s R B_i`` row = ``(s R^T g)^T B_i``) and multiplied as one symmetric
  product;
- a group only slices the basis of its own vertices, so what a landmark solve costs
  depends on its few hundred vertices, not on the size of the model.
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_solve

from ..errors import as_points
from ..geometry import check_rotation, orthonormalize, rotation_from_vector, skew
from .rows import IsotropicRows, Rows

SIMILARITY_PARAMS = ("scale", "rotation x", "rotation y", "rotation z",
                     "translation x", "translation y", "translation z")
_GROUPS = {"scale": [0], "rotation": [1, 2, 3], "translation": [4, 5, 6]}
FREEZABLE = ("scale", "rotation", "translation", "shape")
_RCOND = 1e-12  # smallest accepted eigenvalue ratio of the Jacobi-scaled normal matrix
# Gathers a group serves straight from its basis before it makes the vertex-major copy,
# which only pays off for a group gathered from many times.
_DIRECT_GATHERS = 16


# --------------------------------------------------------------------------- result


@dataclass
class ShapeFit:
    """Outcome of a shape-ICP solve.

    World vertices are ``scale * (mean + basis . coeffs) @ rotation.T + translation``.

    Attributes
    ----------
    scale : float
    rotation : ndarray, shape (3, 3)
        Proper rotation, model -> world.
    translation : ndarray, shape (3,), metres
    coeffs : ndarray, shape (K,)
        All model coefficients (standard deviations); inactive ones keep their start value.
    error_history : list of float
        Error of eq. 46 (weighted mean squared residual per point, in the rows' units
        squared) before each step and at the end; ``error_history[-1]`` is the final one.
    iterations : int
        Gauss-Newton steps taken.
    converged : bool
        The relative change of the error fell below the tolerance (or no step could lower
        the cost any more) before ``max_iterations``.
    free : tuple of str
        Names of the free parameters, the order of ``normal_matrix`` and ``covariance``.
    normal_matrix : ndarray, shape (P, P)
        ``J^T W J`` plus prior terms at the final parameters, in step units (scale as a
        relative change, rotation in radians, translation in metres, coefficients).
    sigma : float
        Residual noise level used for the covariance (given, or estimated from the fit).
    active : ndarray of int, shape (Ka,)
        Indices of the coefficients the fit could change (empty when shape was frozen).
    info : dict
        Per group: name, rows used, error; cost; solve details.

    The posterior covariances are computed on access: ``covariance`` (P, P) is
    ``sigma^2 * inverse(normal_matrix)`` and ``coeff_covariance`` (Ka, Ka) its block for
    the active coefficients (None when the shape was frozen).
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    coeffs: np.ndarray
    error_history: list
    iterations: int
    converged: bool
    free: tuple
    normal_matrix: np.ndarray
    sigma: float
    active: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def covariance(self):
        """Posterior covariance of the free parameters, shape (P, P)."""
        n = self.normal_matrix
        d = np.sqrt(np.diag(n))
        inv = np.linalg.inv(n / d[:, None] / d[None, :]) / d[:, None] / d[None, :]
        return self.sigma**2 * 0.5 * (inv + inv.T)

    @property
    def coeff_covariance(self):
        """Posterior covariance of the active coefficients, shape (Ka, Ka), or None."""
        ka = len(self.active)
        if ka == 0:
            return None
        return self.covariance[-ka:, -ka:]

    @property
    def error(self):
        """Final error of eq. 46."""
        return self.error_history[-1]

    def transform(self, points):
        """Apply the fitted similarity to model-space points: (n, 3) -> (n, 3)."""
        x = as_points(points, "points")
        return self.scale * x @ self.rotation.T + self.translation

    def local_vertices(self, model):
        """Model-space vertices ``mean + basis . coeffs``, shape (V, 3)."""
        return model.instance(self.coeffs)

    def world_vertices(self, model):
        """World-space vertices, shape (V, 3)."""
        return self.transform(self.local_vertices(model))



class _Prepared:
    """Per-group model slices, reused across iterations and solves."""

    def __init__(self, rows, model, active, full_active, vertex_major=None):
        self.rows = rows
        self.model = model
        v = rows.vertices
        n_model = model.mean.shape[0]
        if v.min() < 0 or v.max() >= n_model:
            bad = int(v[(v < 0) | (v >= n_model)][0])
            raise ValueError(f"{rows.name}: vertex index {bad} out of range 0..{n_model - 1}")
        self.whole = len(v) == n_model and np.array_equal(v, np.arange(n_model))
        self.mean = model.mean if self.whole else model.mean[v]
        run = len(v) > 1 and v[-1] - v[0] == len(v) - 1 and bool(np.all(np.diff(v) == 1))
        self._source = None  # (contiguous basis, first vertex) when self.basis is a view
        if len(active) == 0:  # shape frozen: positions need no basis slice per iteration
            b = np.zeros((0, len(v), 3))
        elif self.whole:  # no fancy-index copy when a group covers the whole model
            b = model.basis if full_active else model.basis[active]
        elif run and full_active and model.basis.dtype == np.float64 \
                and model.basis.flags.c_contiguous:
            # consecutive vertices (the fit's copies of each group): a view with strided
            # rows, no copy (gathers go to the whole basis, which is contiguous)
            b = model.basis[:, v[0]:v[0] + len(v)]
            self._source = (model.basis, int(v[0]))
        else:  # take: one C-ordered copy (basis[:, v] gives another layout, copied twice)
            b = np.take(model.basis, v, axis=1)
            b = b if full_active else b[active]
        if b.ndim != 3 or b.strides[1:] != (24, 8) or b.dtype != np.float64:
            b = np.ascontiguousarray(b, dtype=np.float64)
        self.basis = b  # (Ka, n, 3), each mode's rows contiguous
        self.b2 = self.basis.reshape(self.basis.shape[0], 3 * len(v))  # (Ka, 3n), a view
        inactive = np.ones(model.basis.shape[0], bool)
        inactive[active] = False
        self.inactive_idx = np.flatnonzero(inactive)
        self.base = self.mean
        self._basis_vm = None
        # the first modes of the whole basis vertex-major (V, 3, Kv), kept by the caller
        # across problems: a group of consecutive copies gathers those modes from it
        self._prefix = vertex_major if self._source is not None else None
        self._gathers = 0
        self.volatile = False
        self._gram_alpha = None
        self._gram = None
        self._gram_updates = 0

    def basis_vm(self):
        """The basis vertex-major, shape (n, 3, Ka), made on first use (row gathers)."""
        if self._basis_vm is None:
            self._basis_vm = np.ascontiguousarray(self.basis.transpose(1, 2, 0))
        return self._basis_vm

    def gather(self, idx):
        """The basis at vertices ``idx`` as (m, 3, Ka). From the vertex-major copy once a
        group has been gathered from a few times (it pays off over many solves, but is
        costly to make); straight from the basis before that, and always once modes are
        replaced between solves (``ShapeProblem.replace_modes``), as re-making that copy
        every round would cost more than the gathers it saves."""
        self._gathers += 1
        if self._prefix is not None:
            basis, first = self._source
            at = idx + first
            head = self._prefix[at]  # (m, 3, Kv), each vertex's modes contiguous
            if head.shape[2] == basis.shape[0]:
                return head
            tail = np.take(basis[head.shape[2]:], at, axis=1).transpose(1, 2, 0)
            return np.concatenate([head, tail], axis=2)
        if self.volatile or (self._basis_vm is None and self._gathers <= _DIRECT_GATHERS):
            if self._source is not None:  # (a take from a strided view is 3x slower)
                basis, first = self._source
                return np.take(basis, idx + first, axis=1).transpose(1, 2, 0)
            return np.take(self.basis, idx, axis=1).transpose(1, 2, 0)
        return self.basis_vm()[idx]

    def set_inactive(self, coeffs):
        """Fold the fixed (inactive) coefficients into the base shape, slicing only the
        basis rows of the non-zero ones."""
        idx = self.inactive_idx[coeffs[self.inactive_idx] != 0]
        if len(idx) == 0:
            self.base = self.mean
            return
        b = self.model.basis[idx]
        if not self.whole:
            b = np.take(b, self.rows.vertices, axis=1)
        self.base = self.mean + np.tensordot(coeffs[idx], b, axes=1)

    def gram(self, alpha):
        """``sum_i alpha_i B_i^T B_i`` (Ka, Ka), updated from the last one when few weights
        changed (outliers in ICP) instead of a full 3n x Ka^2 product."""
        n = len(alpha)
        if self._gram is not None and self._gram_updates < 50:
            diff = alpha - self._gram_alpha
            nz = np.flatnonzero(diff)
            if len(nz) == 0:
                return self._gram
            if len(nz) < n // 4:
                cols = (3 * nz[:, None] + np.arange(3)).ravel()
                bs = self.b2[:, cols]
                self._gram = self._gram + (bs * np.repeat(diff[nz], 3)) @ bs.T
                self._gram_alpha = alpha.copy()
                self._gram_updates += 1
                return self._gram
        root = self.b2 * np.repeat(np.sqrt(alpha), 3)
        self._gram = root @ root.T  # symmetric product: BLAS syrk, half the work of a gemm
        self._gram_alpha = alpha.copy()
        self._gram_updates = 0
        return self._gram


@dataclass
class _System:
    n: np.ndarray  # (7+Ka, 7+Ka)
    b: np.ndarray  # (7+Ka,)
    sq: float  # data cost
    prior: float  # prior cost
    wsum: float
    nrows: int
    groups: list

    @property
    def error(self):
        return self.sq / self.wsum if self.wsum > 0 else 0.0


def _similarity_jacobian(pt):
    """d x / d(ds, dtheta, dt) at the points ``pt`` (..., 3) (eq. 39), shape (..., 3, 7)."""
    sj = np.zeros(pt.shape + (7,))
    sj[..., 0] = pt
    sj[..., 1:4] = -skew(pt)  # dtheta x p~ = -[p~]_x dtheta
    sj[..., 0, 4] = sj[..., 1, 5] = sj[..., 2, 6] = 1.0
    return sj


# --------------------------------------------------------------------------- solver


class ShapeProblem:
    """A shape-ICP problem: a model, groups of rows, priors and what is free.

    Build it once and call :meth:`solve` repeatedly (e.g. after changing a group's targets
    with ``set_targets``/``set_pixels``): the model slices and Gram matrices are cached.

    Parameters
    ----------
    model : LinearModel
        ``mean (V, 3)``, ``basis (K, V, 3)``, ``stddev (K,)``, ``gamma (G, K)`` or None.
    rows : Rows or sequence of Rows
        Groups of residual rows, composed in one cost.
    lambda1 : float
        Weight of the smoothness rows ``lambda1 * Gamma`` (eq. 40-41); ignored when the
        model has no ``gamma``.
    lambda2 : float
        Weight of the deformation prior ``lambda2 * Lambda`` (eq. 42).
    prior : {"eigen", "identity"}
        Lambda: "eigen" penalises ``c`` (Mahalanobis distance, c in standard deviations);
        "identity" is the thesis' ``w I`` on raw unit-eigenvector coefficients, i.e. it
        penalises ``stddev * c`` (metres).
    freeze : iterable of str
        Parameters to keep at their start values: any of "scale", "rotation",
        "translation", "shape" (shape frozen = the similarity-only ICP).
    active : array_like of int, optional
        Indices of the coefficients that may change (default: all).
    n_coeffs : int, optional
        Shorthand for ``active = range(n_coeffs)``.
    vertex_major : ndarray, shape (V, 3, Kv), optional
        The model's first Kv modes vertex-major (``basis[:Kv].transpose(1, 2, 0)``, C
        order), when the caller keeps them across problems on the same basis (the fit's
        joint rounds): rows on a few of many vertices gather their modes from it, a
        contiguous block per vertex, instead of one strided read per mode. Used when every
        coefficient is active.
    """

    def __init__(self, model, rows, lambda1=0.0, lambda2=0.0, prior="eigen", freeze=(),
                 active=None, n_coeffs=None, vertex_major=None):
        mean = np.asarray(getattr(model, "mean", None))
        basis = getattr(model, "basis", None)
        if mean.ndim != 2 or mean.shape[1] != 3 or basis is None \
                or np.ndim(basis) != 3 or basis.shape[1:] != mean.shape:
            raise ValueError("model: expected a LinearModel with mean (V, 3) and basis "
                             "(K, V, 3)")
        self.model = model
        k = basis.shape[0]
        if isinstance(rows, Rows):
            rows = [rows]
        rows = list(rows)
        if not rows:
            raise ValueError("rows: at least one group of rows is needed")
        for r in rows:
            if not isinstance(r, Rows):
                raise ValueError(f"rows: expected Rows objects, got {type(r).__name__}")
        freeze = frozenset((freeze,) if isinstance(freeze, str) else freeze)
        unknown = freeze - set(FREEZABLE)
        if unknown:
            raise ValueError(f"freeze: unknown parameter(s) {sorted(unknown)}; "
                             f"known: {', '.join(FREEZABLE)}")
        for name, lam in (("lambda1", lambda1), ("lambda2", lambda2)):
            if not np.isfinite(lam) or lam < 0:
                raise ValueError(f"{name}: must be finite and >= 0, got {lam!r}")
        if prior not in ("eigen", "identity"):
            raise ValueError(f"prior: must be 'eigen' or 'identity', got {prior!r}")
        if active is not None and n_coeffs is not None:
            raise ValueError("active and n_coeffs: give at most one")
        if n_coeffs is not None:
            if not 0 <= int(n_coeffs) <= k:
                raise ValueError(f"n_coeffs: must be in 0..{k}, got {n_coeffs}")
            active = np.arange(int(n_coeffs))
        elif active is None:
            active = np.arange(k)
        else:
            active = np.asarray(active)
            if active.ndim != 1 or not np.issubdtype(active.dtype, np.integer) or (
                    active.size and (active.min() < 0 or active.max() >= k)) or \
                    len(np.unique(active)) != len(active):
                raise ValueError(f"active: expected unique coefficient indices in 0..{k - 1}")
        self.active = np.asarray(active, dtype=np.intp)
        if "shape" in freeze:
            self.active = np.zeros(0, dtype=np.intp)
        if len(self.active) == 0:
            freeze = freeze | {"shape"}
        self.freeze = freeze
        self.lambda1 = float(lambda1)
        self.lambda2 = float(lambda2)
        self.prior = prior
        full_active = len(self.active) == k and np.array_equal(self.active, np.arange(k))
        if vertex_major is not None:
            vertex_major = np.asarray(vertex_major)
            if vertex_major.ndim != 3 or vertex_major.shape[:2] != mean.shape or \
                    vertex_major.shape[2] > k or not vertex_major.flags.c_contiguous:
                raise ValueError(f"vertex_major: expected a C-ordered (V, 3, Kv) array with "
                                 f"V = {mean.shape[0]}, Kv <= {k}, got {vertex_major.shape}")
        self._vertex_major = vertex_major if full_active else None
        self.groups = [_Prepared(r, model, self.active, full_active, self._vertex_major)
                       for r in rows]
        ka = len(self.active)
        self.shape_free = "shape" not in freeze
        sim = [i for g, idx in _GROUPS.items() if g not in freeze for i in idx]
        self.free = np.array(sim + ([7 + j for j in range(ka)] if self.shape_free else []),
                             dtype=np.intp)
        if len(self.free) == 0:
            raise ValueError("freeze: every parameter is frozen; nothing to fit")
        names = tuple(model.names) if len(getattr(model, "names", ())) == k else \
            tuple(f"coefficient {i}" for i in range(k))
        self.param_names = SIMILARITY_PARAMS + tuple(names[i] for i in self.active)
        sd = np.asarray(model.stddev, dtype=np.float64)
        if sd.shape != (k,):
            raise ValueError(f"model: stddev must have shape ({k},), got {sd.shape}")
        self._sd = sd
        self.anneal = 0.0
        self._cache = None
        self._pos = None
        self.set_priors()

    def replace_modes(self, start, basis, mean=None):
        """Replace the model's modes ``start..start + P`` (and optionally its mean) between
        solves, in place: the cached slices of every group are refreshed for those modes
        only, so a caller that re-linearises a few modes every round (the fit's camera
        modes) does not rebuild the problem and re-slice the whole basis.

        Parameters
        ----------
        start : int
            First mode replaced.
        basis : array_like, shape (P, V, 3)
        mean : array_like, shape (V, 3), optional

        Raises
        ------
        ValueError
            Shapes that do not match the model, modes beyond its end, or a model whose
            arrays cannot be written.
        """
        b = np.asarray(basis, dtype=np.float64)
        k, n_vert = self.model.basis.shape[:2]
        start = int(start)
        if b.ndim != 3 or b.shape[1:] != (n_vert, 3) or not 0 <= start <= k - b.shape[0]:
            raise ValueError(f"basis: expected shape (P, {n_vert}, 3) for modes {start}.. "
                             f"of {k}, got {b.shape}")
        if not self.model.basis.flags.writeable:
            raise ValueError("model: its basis is read-only; build a new ShapeProblem")
        self.model.basis[start:start + len(b)] = b
        if mean is not None:
            m = np.asarray(mean, dtype=np.float64)
            if m.shape != (n_vert, 3):
                raise ValueError(f"mean: expected shape ({n_vert}, 3), got {m.shape}")
            self.model.mean[...] = m
        if self._vertex_major is not None and start < self._vertex_major.shape[2]:
            self._vertex_major = None  # its modes replaced: gather them as the others
            for pg in self.groups:
                pg._prefix = None
        # rows of the active coefficients that were replaced, and where they sit
        at = np.flatnonzero((self.active >= start) & (self.active < start + len(b)))
        src = self.active[at] - start
        every = np.array_equal(src, np.arange(len(b)))
        for pg in self.groups:
            v = pg.rows.vertices
            if len(at):
                rows = b if pg.whole else np.take(b, v, axis=1)
                rows = rows if every else rows[src]
                pg.basis[at] = rows
                pg._basis_vm = None
                pg.volatile = True
                pg._gram = None
            if mean is not None:
                pg.mean = self.model.mean if pg.whole else self.model.mean[v]
                pg.base = pg.mean
        self._cache = None
        self._pos = None

    def set_priors(self, lambda1=None, lambda2=None, anneal=None):
        """Change the prior weights between solves (the cached model slices stay valid).

        ``anneal`` adds ``anneal^2 |c|^2`` on top of the chosen prior: a stiffness that
        ``register`` lowers step by step so the shape follows the data gradually instead of
        bending into the first wrong correspondences.
        """
        k = self.model.basis.shape[0]
        for name, lam in (("lambda1", lambda1), ("lambda2", lambda2), ("anneal", anneal)):
            if lam is not None and (not np.isfinite(lam) or lam < 0):
                raise ValueError(f"{name}: must be finite and >= 0, got {lam!r}")
        if lambda1 is not None:
            self.lambda1 = float(lambda1)
        if lambda2 is not None:
            self.lambda2 = float(lambda2)
        if anneal is not None:
            self.anneal = float(anneal)
        gamma = getattr(self.model, "gamma", None)
        self.gamma = None
        if gamma is not None and self.lambda1 > 0:
            gamma = np.asarray(gamma, dtype=np.float64)
            if gamma.ndim != 2 or gamma.shape[1] != k:
                raise ValueError(f"model: gamma must have shape (G, {k}), got {gamma.shape}")
            self.gamma = gamma
            # Gamma enters only through Gamma^T Gamma (K x K): precomputed once, so a
            # solve never touches Gamma's thousands of rows again.
            gtg_full = gamma.T @ gamma
            self._gtg_full = self.lambda1**2 * gtg_full
            self._gtg_rows = self._gtg_full[self.active]  # (Ka, K)
            self._gtg = self._gtg_rows[:, self.active]
        weight = self._sd**2 if self.prior == "identity" else np.ones(k)
        self._lam_all = self.lambda2**2 * weight + self.anneal**2
        self._lam = self._lam_all[self.active]
        ka = len(self.active)
        self._prior_rows = (ka if (self.lambda2 > 0 or self.anneal > 0) else 0) + \
            (self.gamma.shape[0] if self.gamma is not None else 0)

    # ---------------------------------------------------------------- assembly

    def _prior_cost(self, c):
        cost = float(self._lam_all @ c**2)
        if self.gamma is not None:
            cost += float(c @ self._gtg_full @ c)
        return cost

    def _build(self, state, update, jacobian=True):
        s, rot, t, c = state
        ka = len(self.active)
        ca = c[self.active]
        p = 7 + ka
        n_mat = np.zeros((p, p))
        b = np.zeros(p)
        sq = wsum = 0.0
        nrows = 0
        info = []
        shape = self.shape_free and jacobian
        if self._pos is not None and self._pos[0] is state:
            pts = self._pos[1]  # the accepted trial of the last step computed them already
        else:
            pts = []
            for pg in self.groups:
                m = pg.base + (pg.b2.T @ ca).reshape(-1, 3) if ka else pg.base
                pts.append(s * m @ rot.T)  # p~ of eq. 38 (no translation)
            self._pos = (state, pts)
        for pg, pt in zip(self.groups, pts, strict=True):
            x = pt + t
            if update:
                pg.rows.update(x)
            blocks = pg.rows.block(x, jacobian)
            if not isinstance(blocks, list | tuple):
                blocks = [blocks]
            g_sq = sum(bl.sq for bl in blocks)
            g_w = sum(bl.wsum for bl in blocks)
            g_rows = sum(bl.nrows for bl in blocks)
            sq += g_sq
            wsum += g_w
            nrows += g_rows
            info.append({"name": pg.rows.name, "rows": g_rows,
                         "error": g_sq / g_w if g_w > 0 else 0.0})
            if not jacobian:
                continue
            for blk in blocks:
                if isinstance(blk, IsotropicRows):
                    self._add_iso(n_mat, b, blk, _similarity_jacobian(pt), pg, s, rot, shape)
                else:  # (its rows' vertices only: an outline's are a few of its candidates)
                    self._add_general(n_mat, b, blk, pt, pg, s, rot, shape)
        if jacobian:
            n_mat[:7, 7:] = n_mat[7:, :7].T
        return _System(n_mat, b, sq, self._prior_cost(c), wsum, nrows, info)

    def _with_priors(self, sys, c):
        """The system plus the prior rows (eq. 43) at coefficients ``c``."""
        n_mat, b = sys.n.copy(), sys.b.copy()
        if self.shape_free:
            n_mat[7:, 7:] += np.diag(self._lam)
            b[7:] -= self._lam * c[self.active]
            if self.gamma is not None:
                n_mat[7:, 7:] += self._gtg
                b[7:] -= self._gtg_rows @ c
        return _System(n_mat, b, sys.sq, self._prior_cost(c), sys.wsum, sys.nrows, sys.groups)

    def _key(self, state):
        s, rot, t, c = state
        versions = [getattr(pg.rows, "_version", 0) for pg in self.groups]
        return np.concatenate([[s], rot.ravel(), t, c, versions])

    def _build_cached(self, state):
        """Data system at ``state`` with fresh correspondences; reuses the previous solve's
        final build when a new solve starts where that one ended (annealing stages)."""
        key = self._key(state)
        if self._cache is not None and np.array_equal(self._cache[0], key):
            sys = self._cache[1]
        else:
            sys = self._build(state, update=True)
        self._cache = (key, sys)
        return self._with_priors(sys, state[3])

    @staticmethod
    def _add_iso(n_mat, b, blk, sj, pg, s, rot, shape):
        a = blk.alpha
        sw = sj * a[:, None, None]
        sw2 = sw.reshape(-1, 7)
        n_mat[:7, :7] += sw2.T @ sj.reshape(-1, 7)
        b[:7] += sw2.T @ blk.resid.reshape(-1)
        if shape:
            # Model-frame rows: (s R B)^T y = s B^T R^T y. One pass over the basis for the
            # cross terms and the right-hand side together: columns 0-6 are R^T (a S_v),
            # column 7 is R^T (a r_v).
            nv = len(a)
            q = np.empty((nv, 3, 8))
            q[:, :, :7] = np.tensordot(sw, rot, axes=([1], [0])).transpose(0, 2, 1)
            q[:, :, 7] = (blk.resid * a[:, None]) @ rot
            prod = pg.b2 @ q.reshape(-1, 8)
            n_mat[7:, :7] += s * prod[:, :7]
            b[7:] += s * prod[:, 7]
            n_mat[7:, 7:] += (s * s) * pg.gram(a)

    @staticmethod
    def _add_general(n_mat, b, blk, pt, pg, s, rot, shape):
        mix = blk.mix
        if blk.idx is None:  # one row per vertex, in order (e.g. point-to-plane)
            keep = np.flatnonzero(blk.w > 0)
            dense = len(keep) > 0.5 * len(blk.w)
            if dense:
                keep = slice(None)
            idx = keep
        else:
            keep = blk.w > 0
            if mix is not None:
                keep |= (mix != 0).any(axis=0)
            idx = blk.idx[keep]
            dense = False
        g, r, w = blk.g[keep], blk.r[keep], blk.w[keep]
        if mix is not None:  # rows combined from the block's: no gather of their own
            mix, mr, mw = mix[:, keep], blk.mix_r, blk.mix_w
        at = _similarity_jacobian(pt[idx])
        if g.ndim == 2:  # one vertex per row: the case c = 1 of rows on c vertices
            g, at = g[:, None], at[:, None]
        a_s = np.einsum("mci,mcij->mj", g, at)  # a row's vertices' terms summed
        a_sw = a_s * w[:, None]
        n_mat[:7, :7] += a_sw.T @ a_s
        b[:7] += a_sw.T @ r
        if mix is not None:
            x_s = mix @ a_s
            x_sw = x_s * mw[:, None]
            n_mat[:7, :7] += x_sw.T @ x_s
            b[:7] += x_sw.T @ mr
        if shape:
            h = s * g @ rot  # row of s R B_i seen from the model frame, (m, c, 3)
            if dense:  # all vertices, one each: contract the (Ka, n, 3) basis in place
                a_c = np.einsum("kmi,mi->km", pg.basis, h[:, 0])  # (Ka, m)
                sr = a_c * np.sqrt(w)
                n_mat[7:, 7:] += sr @ sr.T  # A^T W A as one symmetric product (syrk)
                prod = (a_c * w) @ np.column_stack([a_s, r])
                a_c = a_c.T
            else:  # few rows: gather contiguous (3, Ka) blocks per row and vertex
                m, c = g.shape[:2]
                basis = pg.gather(np.reshape(idx, -1))
                basis = basis.reshape(m, c, 3, basis.shape[-1])
                # (m, Ka): each row's few vertices' modes, one batched product
                a_c = np.matmul(h.reshape(m, 1, 3 * c),
                                basis.reshape(m, 3 * c, basis.shape[-1]))[:, 0]
                sr = a_c * np.sqrt(w)[:, None]
                n_mat[7:, 7:] += sr.T @ sr
                prod = (a_c * w[:, None]).T @ np.column_stack([a_s, r])
            if mix is not None:
                x_c = mix @ a_c  # (q, Ka)
                sx = x_c * np.sqrt(np.abs(mw))[:, None]  # symmetric products by sign
                neg = mw < 0
                n_mat[7:, 7:] += sx[~neg].T @ sx[~neg] - sx[neg].T @ sx[neg]
                prod += (x_c * mw[:, None]).T @ np.column_stack([x_s, mr])
            n_mat[7:, :7] += prod[:, :7]
            b[7:] += prod[:, 7]

    def _factor(self, sys):
        """Cholesky factor of the Jacobi-scaled normal matrix of the free parameters, or a
        ValueError naming the parameters nothing constrains."""
        nf = sys.n[np.ix_(self.free, self.free)]
        d = np.sqrt(np.clip(np.diag(nf), 0.0, None))
        names = [self.param_names[i] for i in self.free]
        zero = d <= 1e-300
        if zero.any():
            which = ", ".join(repr(names[i]) for i in np.flatnonzero(zero)[:6])
            raise ValueError(f"singular system: no row constrains {which}; add rows, freeze "
                             "them or use lambda2 > 0")
        ns = nf / d[:, None] / d[None, :]
        ok = True
        try:
            low = np.linalg.cholesky(ns)
            diag = np.diag(low)
            ok = (diag.min() / diag.max()) ** 2 > 1e4 * _RCOND  # else check by eigenvalues
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            evals, evecs = np.linalg.eigh(ns)
            if evals[0] > _RCOND * evals[-1]:  # the cheap test was too pessimistic
                low = np.linalg.cholesky(ns)
            else:
                v = np.abs(evecs[:, 0])
                which = ", ".join(repr(names[i]) for i in np.argsort(-v)[:4]
                                  if v[i] > 0.25 * v.max())
                raise ValueError(f"singular system: the rows do not determine {which} "
                                 f"(condition {evals[-1] / max(evals[0], 1e-300):.1e}); add "
                                 "rows, freeze parameters or use lambda1/lambda2 > 0")
        return low, d, nf

    @staticmethod
    def _chol_solve(low, rhs):
        return cho_solve((low, True), rhs, check_finite=False)

    def _apply(self, state, full, frac):
        s, rot, t, c = state
        step = frac * full
        ds = step[0]
        s_new = s * max(1.0 + ds, 0.5)  # a factor <= 0 would flip the head; cap the step
        r_new = orthonormalize(rotation_from_vector(step[1:4]) @ rot)
        t_new = t + step[4:7]
        c_new = c.copy()
        c_new[self.active] += step[7:]
        return (s_new, r_new, t_new, c_new)

    # ---------------------------------------------------------------- solve

    def solve(self, scale=1.0, rotation=None, translation=None, coeffs=None,
              max_iterations=30, tolerance=1e-6, sigma=None, final_system=True):
        """Run Gauss-Newton from the given start.

        Parameters
        ----------
        scale : float
        rotation : ndarray, shape (3, 3), optional (default identity)
        translation : ndarray, shape (3,), optional (default zero)
        coeffs : ndarray, shape (K,), optional (default zero)
        max_iterations : int
            Most Gauss-Newton steps (1 = one linear solve, the fast refit path; 0 only
            evaluates the error and the covariance at the start).
        tolerance : float
            Stop when the error of eq. 46 changes by less than this fraction.
        sigma : float, optional
            Residual noise level for the covariance; default: estimated as
            ``sqrt(weighted SSR / (rows - free parameters))``.
        final_system : bool
            False: after the last of ``max_iterations`` steps, stop without linearising
            at the new parameters (one build of the system fewer, for a caller that
            only takes the parameters): ``normal_matrix`` is then the last step's, and
            the last error, ``info`` and ``sigma`` come from the step's cost evaluation
            (correspondences not refreshed).

        Returns
        -------
        ShapeFit
        """
        k = self.model.basis.shape[0]
        s = float(scale)
        if not np.isfinite(s) or s <= 0:
            raise ValueError(f"scale: must be finite and > 0, got {scale!r}")
        rot = np.eye(3) if rotation is None else check_rotation(rotation)
        t = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise ValueError(f"translation: expected 3 finite numbers, got shape {t.shape}")
        c = np.zeros(k) if coeffs is None else np.array(coeffs, dtype=np.float64)
        if c.shape != (k,) or not np.isfinite(c).all():
            raise ValueError(f"coeffs: expected {k} finite numbers, got shape {c.shape}")
        if int(max_iterations) < 0:
            raise ValueError(f"max_iterations: must be >= 0, got {max_iterations}")
        if not tolerance >= 0:
            raise ValueError(f"tolerance: must be >= 0, got {tolerance!r}")
        if sigma is not None and not (np.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"sigma: must be finite and >= 0, got {sigma!r}")
        for pg in self.groups:
            pg.set_inactive(c)
        state = (s, rot, t, c)
        history = []
        converged = False
        steps = 0
        n_free = len(self.free)
        while True:
            sys = self._build_cached(state)
            history.append(sys.error)
            if steps == 0 and sys.nrows + (self._prior_rows if self.shape_free else 0) < n_free:
                detail = ", ".join(f"{g['name']}: {g['rows']}" for g in sys.groups)
                raise ValueError(f"too few observations: {sys.nrows} residual rows ({detail}) "
                                 f"for {n_free} free parameters; add points, freeze "
                                 "parameters, use fewer coefficients or lambda2 > 0")
            if len(history) >= 2:
                prev = history[-2]
                if abs(prev - history[-1]) <= tolerance * max(prev, 1e-300):
                    converged = True
            if history[-1] == 0.0:
                converged = True
            low, d, nf = self._factor(sys)
            if converged or steps >= int(max_iterations):
                break
            rhs = sys.b[self.free] / d
            delta = self._chol_solve(low, rhs) / d
            full = np.zeros(len(sys.b))
            full[self.free] = delta
            cost0 = sys.sq + sys.prior
            accepted = None
            frac = 1.0
            for _ in range(8):
                cand = self._apply(state, full, frac)
                try:
                    trial = self._build(cand, update=False, jacobian=False)
                except ValueError:  # e.g. a vertex stepped behind a perspective camera
                    frac *= 0.5
                    continue
                if trial.sq + trial.prior <= cost0 * (1 + 1e-12) + 1e-300:
                    accepted = cand
                    break
                frac *= 0.5
            if accepted is None:  # no step lowers the cost: a (numerical) minimum
                converged = True
                break
            state = accepted
            steps += 1
            if not final_system and steps >= int(max_iterations):
                sys = trial
                history.append(sys.error)
                break
        s, rot, t, c = state
        dof = sys.nrows + (self._prior_rows if self.shape_free else 0) - n_free
        sig = float(np.sqrt(sys.sq / max(dof, 1))) if sigma is None else float(sigma)
        return ShapeFit(
            scale=s, rotation=rot, translation=t, coeffs=c, error_history=history,
            iterations=steps, converged=converged,
            free=tuple(self.param_names[i] for i in self.free), normal_matrix=nf,
            sigma=sig, active=self.active.copy(),
            info={"groups": sys.groups, "cost": sys.sq + sys.prior, "data_cost": sys.sq,
                  "prior_cost": sys.prior, "rows": sys.nrows},
        )


def shape_icp(model, rows, *, scale=1.0, rotation=None, translation=None, coeffs=None,
              lambda1=0.0, lambda2=0.0, prior="eigen", freeze=(), active=None, n_coeffs=None,
              max_iterations=30, tolerance=1e-6, sigma=None):
    """Fit a similarity and model coefficients to groups of rows (thesis §4.3).

    A one-call form of ``ShapeProblem(model, rows, ...).solve(...)``; see those for the
    parameters. Returns a :class:`ShapeFit`.

    Raises
    ------
    ValueError
        Wrong shapes or NaN in rows or start values, vertex indices out of range, fewer
        residual rows than free parameters, or a singular system (names the parameters no
        row determines).
    """
    problem = ShapeProblem(model, rows, lambda1=lambda1, lambda2=lambda2, prior=prior,
                           freeze=freeze, active=active, n_coeffs=n_coeffs)
    return problem.solve(scale=scale, rotation=rotation, translation=translation,
                         coeffs=coeffs, max_iterations=max_iterations, tolerance=tolerance,
                         sigma=sigma)

