"""The joint solve: image rows of some views solved for the head and the cameras in one
Gauss-Newton step (:class:`Joint`).

Each photo has its own camera; its free parameters enter the step as extra modes of the
shape-ICP, one block per camera, as the camera kind gives them
(``Camera.parameter_modes``): an orthographic camera (and any kind without modes of its
own) the 2-D similarity of the photo, refitted exactly by ``Camera.refit`` after the step;
a pinhole camera its rotation, centre and log focal length, moved exactly
(``Camera.stepped``; its rotation and centre lifted as the rigid motions they are,
``Camera.parameter_motions``, so rows on depth see them), a focal prior (EXIF) entering
the step as the prior of its mode; a DLT the 11 directions of its matrix, refitted after
the step. A mirror view (one camera and a flat mirror, seed 001 ch. 3) has no camera of
its own: it is the real camera reflected in the mirror plane (``Camera.mirrored``), so its
rows move with the real camera's parameters and with three of the plane's (the tilt of
its normal, its offset: ``MirrorPlane.fields``).
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..cameras.base import unit_scale
from ..errors import rms
from ..geometry import rotation_from_vector
from ..model.linear_model import LinearModel
from .depth import depth_rows
from .outline import ContourRows, body_weights
from .shape_icp import ShapeProblem
from .views import ViewData

# Pixels one unit of a camera mode's coefficient moves the photo (see Joint): large, so
# the shape prior the shape-ICP puts on every coefficient hardly restrains the cameras
# (a 10 px correction costs 0.01), yet it settles the split where a calibrated camera
# leaves the head's position and a refitted camera's offset equally free.
MODE_PIXELS = 100.0


# Fractions of a joint step tried when the whole step raises the cost (perspective cameras).
DAMPING = (0.5, 0.25, 0.1)



def _head_key(state):
    """What a head's world positions depend on: the similarity and the coefficients."""
    return (float(state.scale), state.rotation.tobytes(), state.translation.tobytes(),
            state.coeffs.tobytes())


@dataclass
class _Block:
    """Free parameters of one camera ("camera": the real camera of ``view``, seen by the
    ``users`` views: itself and its mirror views) or of a mirror plane ("plane": of the
    mirror view ``view``)."""

    kind: str
    view: ViewData
    users: list


@dataclass
class _Prepared:
    problem: ShapeProblem
    model: LinearModel
    k: int
    rotation: np.ndarray
    freeze: tuple
    cameras_only: bool
    layout: list  # per block: (block, mode kind, number of modes, units, start, prior)
    start: np.ndarray  # coefficients of the camera modes at the linearisation point
    reusable: bool
    frozen: tuple  # everything frozen (with the gauge)


class Joint:
    """Image rows of some views solved jointly for the head and the cameras.

    The shape-ICP knows one similarity and linear modes. To let it move the cameras in the
    same Gauss-Newton step as the head, every group of rows gets its own copies of the
    model vertices it uses, and each free camera (and mirror plane) gets extra modes that
    move only the copies it sees: the pixel fields of its parameters (see the module
    docstring), lifted to 3-D through each copy's camera Jacobian (pseudo-inverse), so a
    mode's coefficient moves those projections exactly as the parameter would, to first
    order. The step is then a joint Gauss-Newton step, so the fit converges in a few
    rounds where alternating "head, then cameras" crawls along every motion that a camera
    and the head share. After each step the cameras and planes are moved by their modes'
    coefficients (or refitted to what the step predicted) and the modes reset: they are
    re-linearised every round.

    A pinhole camera's focal prior is the prior of its focal mode: one unit of that mode
    is ``sigma * lambda2`` in log f, and its coefficient starts at the camera's distance
    from the prior, so the shape-ICP's ``lambda2^2 c^2`` is exactly the prior's cost.
    """

    def __init__(self, eng, views, front_weight=1.0, contour=True, landmarks=True,
                 outlines=None, keep_distance=None):
        self.eng = eng
        self.views = list(views)
        # view name -> (vertices, faces, edges): candidates found for this problem's head
        self.outlines = dict(outlines or {})
        self.groups = []  # (view, kind, rows)
        # view name -> indices of its landmarks fitted to the head's outline (the sliding
        # ones of a view with outline candidates; without, they stay on their vertices)
        self.sliding = {}
        orig = []
        off = 0
        for v in self.views:
            slide = landmarks and bool(v.slide.any()) and v.name in self.outlines
            if landmarks and len(v.vertices):
                rows = eng.landmark_rows(v, off, front_weight, slide=slide)
                self.groups.append((v, "landmarks", rows))
                depth = depth_rows(v, off, eng.views)  # on the same copies
                if depth is not None:
                    self.groups.append((v, "depth", depth))
                orig.append(v.vertices)
                off += len(v.vertices)
            if slide:
                (across, along), copies, idx = eng.sliding_rows(v, off, self.outlines,
                                                                front_weight)
                self.groups += [(v, "outline points", across), (v, "outline along", along)]
                self.sliding[v.name] = idx
                orig.append(copies)
                off += len(copies)
            if contour and v.contour is not None:
                rows, cand = eng.contour_rows(v, off, self.outlines, keep_distance)
                self.groups.append((v, "contour", rows))
                orig.append(cand)
                off += len(cand)
        if not self.groups:
            raise ValueError("views: no landmarks or contour to fit")
        self._prep = None
        self._fit = None
        self._world = None  # (state key, world positions of the copies) last computed
        self.orig = np.concatenate(orig)
        self.rows = [g[2] for g in self.groups]
        self.mean, self.basis = eng.slice(self.orig)
        self.view_idx, self.view_lm = {}, {}
        for v, kind, rows in self.groups:
            if kind == "depth":  # the landmarks' copies again
                continue
            self.view_idx.setdefault(v.name, []).append(rows.vertices)
            if kind == "landmarks":
                self.view_lm[v.name] = rows.vertices
        self.view_idx = {k: np.concatenate(i) for k, i in self.view_idx.items()}
        self.members = [v for v in self.views if v.name in self.view_idx]
        # Gauge: the head's similarity parameters these views cannot determine.
        self.gauge = eng.gauge(self.members)
        self.blocks = []
        for v in eng.views:
            if v.mirror_of is not None or not eng.camera_moves(v):
                continue
            users = [u for u in self.members if u is v or u.mirror_of == v.name]
            if users:
                self.blocks.append(_Block("camera", v, users))
        self.blocks += [_Block("plane", u, [u]) for u in self.members
                        if u.mirror_of is not None]

    def vertex_major(self):
        """The copies' basis vertex-major, (n, 3, K) (``Engine.vertex_major``): every
        problem of this joint gathers its rows' modes from it
        (``ShapeProblem(vertex_major=)``)."""
        return self.eng.vertex_major(self.orig)

    def sync(self, state):
        self.eng.use(state)
        for v, _, rows in self.groups:
            rows.set_camera(state.cameras[v.name])

    def world(self, state):
        """World positions of the copies, (n, 3) (read only: the last head's are kept, a
        step's cost and the next linearisation ask for the same)."""
        key = _head_key(state)
        if self._world is not None and self._world[0] == key:
            return self._world[1]
        local = self.mean + np.tensordot(state.coeffs, self.basis, axes=1)
        return self._keep_world(key, state.scale * local @ state.rotation.T
                                + state.translation)

    def _keep_world(self, key, x):
        x.flags.writeable = False
        self._world = (key, x)
        return x

    def cost(self, state):
        """Weighted squared pixel residuals (correspondences refreshed) plus priors (shape
        and focal length)."""
        self.sync(state)
        x = self.world(state)
        total = 0.0
        for _, _, rows in self.groups:
            xs = x[rows.vertices]
            rows.update(xs)
            blocks = rows.block(xs, jacobian=False)
            blocks = blocks if isinstance(blocks, list | tuple) else [blocks]
            total += sum(float(b.sq) for b in blocks)
            if isinstance(rows, ContourRows):
                total += rows.unmatched_cost()
        return total + self.eng.prior_cost(state.coeffs) + self.camera_prior_cost(state)

    def camera_prior_cost(self, state):
        """The focal priors of the cameras this problem moves."""
        return self.eng.camera_prior_cost(state, [b.view for b in self.blocks
                                                  if b.kind == "camera"])

    def contour_pairs(self, state, kinds=("contour", "outline points")):
        """view name -> [(model vertices, target pixels, weights)] of the current rows of
        the traced outlines and the sliding landmarks (``kinds``), for the camera refit
        (weights relative to 1 / noise^2)."""
        out = {}
        x = None
        for v, kind, rows in self.groups:
            if kind not in kinds or len(rows.selected) == 0:
                continue
            if x is None:
                x = self.world(state)
            sel, px = rows.pairs(x[rows.vertices])
            w = self.eng.contour_weight * v.contour_scale \
                * body_weights(rows.body_rows, v.body_scale) \
                if kind == "contour" else rows.row_weights / self.eng.inv_var
            out.setdefault(v.name, []).append((self.orig[rows.vertices[sel]], px, w))
        return out

    def outline_matches(self, state):
        """Per view with sliding landmarks, where each met the head's outline at ``state``:
        view name -> (landmark indices in the view (k,), signed pixel distances across the
        outline (k,), the nearer model vertex of each one's silhouette point (k,), and the
        pixel offset along the outline from that vertex's projection (k, 2)). The offset
        lets the drag refit hold a landmark to that vertex without pulling along the
        outline."""
        out = {}
        for v, rows, xs in self._current(state, "outline points"):
            r = rows.residuals(xs)
            sel = rows.selected
            gap = rows.targets - v.camera.project(xs[sel])
            along = gap - np.einsum("ij,ij->i", gap, rows.row_normals)[:, None] \
                * rows.row_normals
            out[v.name] = (self.sliding[v.name][rows.points], r,
                           self.orig[rows.vertices[sel]], along)
        return out

    def along_residuals(self, state):
        """view name -> (names, pixel residuals along the outline) of the sliding landmarks
        that met the head's outline at ``state``."""
        out = {}
        for v, rows, xs in self._current(state, "outline along"):
            pts = rows.outline.points
            r = rows.residuals(xs)[pts, 0]
            out[v.name] = ([v.names[i] for i in self.sliding[v.name][pts]], r)
        return out

    def refit(self, state):
        """Refit every free camera and mirror plane to the head (landmarks + contour
        pairs)."""
        self.sync(state)
        self.eng.refit_cameras(state, self.contour_pairs(state))
        self.sync(state)

    def contour_residuals(self, state):
        """view name -> (pixel distances across the outline of the contour rows at
        ``state`` (k,), whether each row meets the silhouette below the neck's base (k,)
        bool); correspondences refreshed."""
        return {v.name: (np.abs(rows.residuals(xs)), rows.body_rows)
                for v, rows, xs in self._current(state, "contour")}

    def _current(self, state, kind):
        """(view, rows, world positions of their copies) of each group of ``kind`` at
        ``state``, correspondences refreshed."""
        self.sync(state)
        x = self.world(state)
        for v, k, rows in self.groups:
            if k == kind:
                xs = x[rows.vertices]
                rows.update(xs)
                yield v, rows, xs

    def reprojection_rms(self, state):
        """RMS of every landmark and contour-correspondence pixel residual at ``state``
        (a sliding landmark's across the outline)."""
        parts = list(self.eng.reprojection(state).values())
        parts += [r for r, _ in self.contour_residuals(state).values()]
        parts += [m[1] for m in self.outline_matches(state).values()]
        return rms(np.concatenate(parts))

    # ------------------------------------------------------------------ camera modes

    def _block_fields(self, blk, state, x):
        """Pixel fields of one block over the copies it moves.

        Returns (mode kind, copy indices (m,), fields (P, m, 2) per natural unit, units
        (P,) natural units per coefficient, start (P,) coefficients now, prior (P,) bool:
        modes whose shape-ICP prior is a real prior, not a negligible one)."""
        eng = self.eng
        v = blk.view
        if blk.kind == "plane":
            idx = self.view_idx[v.name]
            f = state.planes[v.name].fields(state.cameras[v.mirror_of], x[idx])
            return ("plane", idx, f, *unit_scale(f, MODE_PIXELS), np.zeros(3, bool))
        cam = state.cameras[v.name]
        idx, pts = [], []
        for u in blk.users:
            i = self.view_idx[u.name]
            idx.append(i)
            pts.append(x[i] if u is v else state.planes[u.name].reflect_points(x[i]))
        idx, pts = np.concatenate(idx), np.concatenate(pts)
        centre = x[self.view_lm.get(v.name, self.view_idx[v.name])]
        return ("camera", idx, *cam.parameter_modes(pts, centre, eng.landmark_count(v),
                                                    eng.lambda2, MODE_PIXELS))

    def model(self, state):
        """The copies' linear model at ``state``: the fitted modes, then the camera and
        plane modes (see the class docstring); with the layout of the extra modes and their
        start coefficients."""
        eng = self.eng
        lin = eng.lin
        if not self.blocks:
            return (LinearModel(self.mean, self.basis, lin.stddev, lin.names, eng.gamma), [],
                    np.zeros(0))
        mean, extra_b, layout, start, sd = self._extra_modes(state)
        n_extra = extra_b.shape[0]
        gamma = None
        if eng.gamma is not None:
            gamma = np.hstack([eng.gamma, np.zeros((eng.gamma.shape[0], n_extra))])
        names = tuple(lin.names) + tuple(f"camera {i}" for i in range(n_extra))
        # own arrays: replace_modes writes into them
        model = LinearModel(np.array(mean), np.concatenate([self.basis, extra_b]),
                            np.concatenate([lin.stddev, sd]), names, gamma)
        return model, layout, start

    def _extra_modes(self, state):
        """(mean of the copies with the prior modes' start folded out (n, 3), the camera and
        plane modes (P, n, 3) in the model frame, layout, start coefficients (P,),
        stddev (P,))."""
        x = self.world(state)
        n = len(x)
        # each copy's camera Jacobian, pseudo-inverted (J^T (J J^T)^-1, the 2x2 inverse
        # written out) in the model frame (x = s R m + t, so pixels move by J s R per
        # unit of m): pixel fields -> model displacement; pinv[0] takes the u part
        to_model = state.rotation / state.scale  # world displacement -> model, rows
        pinv = np.zeros((2, n, 3))
        for v in self.members:
            idx = self.view_idx[v.name]
            jac = np.asarray(state.cameras[v.name].jacobian(x[idx]),
                             dtype=np.float64).reshape(len(idx), 2, 3) \
                @ (state.scale * state.rotation)
            ju, jv = jac[:, 0], jac[:, 1]
            a = np.einsum("ij,ij->i", ju, ju)[:, None]
            b = np.einsum("ij,ij->i", ju, jv)[:, None]
            d = np.einsum("ij,ij->i", jv, jv)[:, None]
            det = a * d - b * b
            pinv[0, idx] = (ju * d - jv * b) / det
            pinv[1, idx] = (jv * a - ju * b) / det
        modes, layout, starts, sds = [], [], [], []
        mean = self.mean
        for blk in self.blocks:
            kind, idx, f, units, start, has_prior = self._block_fields(blk, state, x)
            f = f * units[:, None, None]
            m = np.zeros((len(f), n, 3))
            m[:, idx] = f[:, :, 0:1] * pinv[0, idx] + f[:, :, 1:2] * pinv[1, idx]
            rigid = self._motions(blk, state, x[idx])
            if rigid is not None:  # the same projections, the depth moved too
                m[:len(rigid), idx] = (rigid * units[:len(rigid), None, None]) @ to_model
            if start.any():
                mean = mean - np.tensordot(start, m, axes=1)
            modes.append(m)
            layout.append((blk, kind, len(f), units, start, has_prior))
            starts.append(start)
            # a prior mode keeps its prior under prior="identity" (which weighs by stddev)
            sds.append(np.where(has_prior, 1.0, 1e-9))
        return (mean, np.concatenate(modes), layout, np.concatenate(starts),
                np.concatenate(sds))

    @staticmethod
    def _motions(blk, state, points):
        """The world motions of a camera block's modes (``Camera.parameter_motions``) at
        its copies ``points``, or None: a plane, a camera with mirror views (their copies
        are reflected) or without such motions."""
        if blk.kind != "camera" or blk.users != [blk.view]:
            return None
        return state.cameras[blk.view.name].parameter_motions(points)

    def prepare(self, state, freeze=(), cameras_only=False, previous=None):
        """The shape-ICP problem over the copies with the camera modes linearised at
        ``state`` (reused while the head turns little if every camera is orthographic:
        building it copies the basis). A ``previous`` problem of the same layout is
        re-linearised in place (``ShapeProblem.replace_modes``) instead of rebuilt."""
        k = len(state.coeffs)
        if cameras_only:
            freeze = tuple(freeze) + ("rotation",)
        frozen = tuple(freeze) + tuple(self.gauge)
        if previous is not None and previous.frozen == frozen and self.blocks and \
                previous.cameras_only == cameras_only:
            mean, extra_b, layout, start, sd = self._extra_modes(state)
            same = len(layout) == len(previous.layout) and all(
                a[0] is b[0] and a[1] == b[1] and a[2] == b[2]
                for a, b in zip(layout, previous.layout, strict=True))
            if same and np.array_equal(sd, previous.model.stddev[k:]):
                previous.problem.replace_modes(k, extra_b, mean)
                return replace(previous, rotation=state.rotation.copy(), layout=layout,
                               start=start)
        model, layout, start = self.model(state)
        active = np.arange(k, model.n_coeffs) if cameras_only else None
        problem = ShapeProblem(model, self.rows, lambda1=self.eng.lambda1,
                               lambda2=self.eng.lambda2, prior=self.eng.prior,
                               freeze=frozen, active=active,
                               vertex_major=None if cameras_only else self.vertex_major())
        reusable = all(kind == "camera" and not state.cameras[b.view.name].perspective
                       for b, kind, *_ in layout)
        return _Prepared(problem, model, k, state.rotation.copy(), tuple(freeze),
                         cameras_only, layout, start, reusable, frozen)

    def _solve(self, prep, state, iterations):
        start = np.zeros(prep.model.n_coeffs)
        start[:prep.k] = state.coeffs
        start[prep.k:] = prep.start
        self.sync(state)
        return prep.problem.solve(scale=state.scale, rotation=state.rotation,
                                  translation=state.translation, coeffs=start,
                                  max_iterations=iterations, tolerance=0.0, sigma=1.0,
                                  final_system=False)

    def step(self, state, freeze=(), inner=2, cameras_only=False, prep=None):
        """One joint Gauss-Newton round (``inner`` shape-ICP steps), then the cameras.

        The step moves each free camera through its modes. A pinhole camera and a mirror
        plane take the step's parameter change directly; any other camera is refitted to
        what the step predicted: the new head's copies seen where the old camera saw them
        displaced by the modes (for an orthographic camera exactly the similarity the step
        chose; any kind gets its closest match), so camera and head stay one consistent
        Gauss-Newton step. Mirror cameras follow their real camera and plane. Free cameras
        of views outside this problem are refitted to their landmarks.

        ``prep`` (from :meth:`prepare`) is reused when given and reusable; it is rebuilt
        when the head has turned by more than about 3 degrees since (its camera modes
        would be stale), and always for perspective cameras and mirrors (their modes
        carry the camera's parameters).
        """
        if prep is None or not prep.reusable or prep.freeze != tuple(freeze) or \
                prep.cameras_only != cameras_only or \
                np.abs(state.rotation - prep.rotation).max() > 0.05:
            prep = self.prepare(state, freeze, cameras_only,
                                previous=None if prep is None or prep.reusable else prep)
        self._fit = self._solve(prep, state, inner)
        self._prep = prep
        return self.apply(state, 1.0)

    def apply(self, state, alpha):
        """The state after a fraction ``alpha`` of the last :meth:`step`'s change (from
        ``state``, the state that step started from): 1 the whole step; less when the
        whole step overshoots (a perspective camera's modes are linear in its parameters,
        its projection is not)."""
        prep, fit = self._prep, self._fit
        k, model = prep.k, prep.model
        new = state.copy()
        if alpha == 1.0:
            new.rotation, new.coeffs = fit.rotation, fit.coeffs[:k].copy()
            new.scale, new.translation = fit.scale, fit.translation
        else:
            turn = Rotation.from_matrix(fit.rotation @ state.rotation.T).as_rotvec()
            new.rotation = rotation_from_vector(alpha * turn) @ state.rotation
            new.coeffs = state.coeffs + alpha * (fit.coeffs[:k] - state.coeffs)
            new.scale = state.scale * (fit.scale / state.scale) ** alpha
            new.translation = state.translation + alpha * (fit.translation - state.translation)
        full = head = None
        col = k
        moved = set()
        for blk, kind, p, units, start, _ in prep.layout:
            delta = alpha * (fit.coeffs[col:col + p] - start) * units
            col += p
            v = blk.view
            if kind == "plane":
                new.planes[v.name] = state.planes[v.name].moved(delta)
                continue
            old = state.cameras[v.name]
            moved.add(v.name)
            stepped = old.stepped(delta)
            if stepped is not None:
                new.cameras[v.name] = stepped
                continue
            if full is None:
                # the model is the copies' basis plus the camera modes (``model``): the
                # head read once, the modes' part added (its mean folds their start out)
                head = self.mean + np.tensordot(new.coeffs, self.basis, axes=1)
                cam = prep.start + alpha * (fit.coeffs[k:] - prep.start)
                full = head + (model.mean - self.mean) \
                    + np.tensordot(cam, model.basis[k:], axes=1)
                full = new.scale * full @ new.rotation.T + new.translation
                # the new head's world positions, as :meth:`world` computes them
                head = self._keep_world(_head_key(new), new.scale * head @ new.rotation.T
                                        + new.translation)
            pts, px = [], []
            for u in blk.users:
                i = self.view_idx[u.name]
                h = head[i] if u is v else state.planes[u.name].reflect_points(head[i])
                pts.append(h)
                px.append(state.cameras[u.name].project(full[i]))
            try:
                new.cameras[v.name] = old.refit(np.concatenate(pts), np.vstack(px))
            except ValueError:  # too few copies for this kind: keep the camera this round
                new.cameras[v.name] = old
        for u in self.eng.views:
            if u.mirror_of is not None and u.name in new.planes:
                new.cameras[u.name] = new.cameras[u.mirror_of].mirrored(new.planes[u.name])
        inside = {v.name for v in self.members} | moved
        outside = [v for v in self.eng.views if v.name not in inside and v.mirror_of is None]
        if outside:
            self.eng.refit_cameras(new, views=outside)
        self.sync(new)
        return new

    def run(self, state, freeze=(), max_outer=20, inner=2, tolerance=1e-4,
            cameras_only=False, patience=2):
        """Rounds of :meth:`step` until the cost changes by less than ``tolerance``
        (relative) or has not reached a new low for ``patience`` rounds; returns the state
        of the lowest cost and the cost history.

        The contour's rows are a choice (which vertices form the outline), so near the end
        the choice can flip back and forth between two sets and the cost with it; the
        lowest one is kept. A step of perspective cameras that raises the cost is cut
        back (:meth:`apply`, fractions DAMPING) before it counts.
        """
        best_cost = self.cost(state)
        best = state
        history = [best_cost]
        since = 0
        if self._prep is not None and self._prep.reusable:
            self._prep = None  # (a perspective problem is re-linearised in place instead)
        for _ in range(max(int(max_outer), 1)):
            start = state
            state = self.step(start, freeze, inner, cameras_only, self._prep)
            cost = self.cost(state)
            if cost > history[-1] and not self._prep.reusable:
                # a perspective step that overshot: take part of it
                for alpha in DAMPING:
                    trial = self.apply(start, alpha)
                    c = self.cost(trial)
                    if c < cost:
                        state, cost = trial, c
                    if c <= history[-1]:
                        break
            history.append(cost)
            if cost < best_cost:
                since = 0 if cost < best_cost * (1.0 - tolerance) else since + 1
                best, best_cost = state, cost
            else:
                since += 1
            if abs(history[-2] - history[-1]) <= tolerance * history[-2] or since >= patience:
                break
        self.sync(best)
        self.cost(best)  # leave the correspondences at the returned state
        return best, history

    def settle(self, state, max_rounds=10, tolerance=1e-4, **run_kw):
        """Self-calibration: alternate a full re-calibration of every free camera and
        mirror plane (``Camera.refit`` on the landmarks and contour pairs, with all of its
        parameters and priors: a pinhole camera's principal point and k1 when free, its
        focal range) and joint rounds (:meth:`run`), until the re-calibration lowers the
        cost by less than ``tolerance`` (relative): cameras and shape agree. At most
        ``max_rounds`` re-calibrations. Returns (state, cost history of the joint rounds
        appended, re-calibrations made)."""
        cost = self.cost(state)
        history = []
        rounds = 0
        for _ in range(max(int(max_rounds), 0)):
            trial = state.copy()
            try:
                self.refit(trial)
            except ValueError:  # a camera cannot be refitted alone: the joint rounds rule
                break
            rounds += 1
            c = self.cost(trial)
            if not c < cost * (1.0 - tolerance):
                break
            state, hist = self.run(trial, tolerance=tolerance, **run_kw)
            history += hist
            cost = self.cost(state)
        self.sync(state)
        self.cost(state)
        return state, history, rounds

    def covariance(self, state):
        """Posterior covariance (K, K) of the fitted coefficients at ``state``: the inverse
        of the normal matrix with pose and camera modes free (marginalised), rows weighted
        1 / noise^2 so sigma = 1."""
        last = self._prep
        prep = self.prepare(state, previous=None if last is None or last.reusable else last)
        fit = self._solve(prep, state, 0)
        return fit.coeff_covariance[:prep.k, :prep.k]

