"""What the stages of one fit share (:class:`Engine`): the model being fitted, the views,
the weights and priors, and the rows a view gives. The joint solve of head and cameras is
``joint.py``.

Gauge (:meth:`Engine.gauge`): photos whose cameras are all free cannot tell how large the
head is or where it is, only how it looks; then the head's scale stays 1 and its
translation 0, and the cameras absorb both (the identity modes carry the head's size).
When every free camera is perspective the head's rotation is kept too: the world is the
head's frame and the cameras stand around it. One calibrated perspective camera (alone or
with a mirror) cannot tell the head's size from its distance either: the head's scale
stays 1 (the model's size), which also fixes the mirror's distance.
"""

import dataclasses

import numpy as np

from ..cameras.mirror import estimate_mirror
from ..io.contour import SPACING_PX
from ..io.landmark_counts import MIN_LANDMARKS_PER_VIEW
from ..memo import memo, memo_items
from ..model.linear_model import LinearModel
from ..model.stacked import StackedModel
from .contour_start import camera_from_outline
from .definition import GroupedImageRows, definition_sigmas, group_offsets
from .joint import Joint
from .outline import (
    CONTOUR_KEEP_SIGMAS,
    NORMAL_SPAN_PX,
    ContourRows,
    OutlineAlongRows,
    OutlinePointRows,
    body_vertices,
    outline_candidates,
    profile_normal_bound,
)
from .rows import ImageRows
from .shape_icp import ShapeProblem
from .views import FRONTAL_DEGREES, PROFILE_DEGREES, assign_roles

#: How far a sliding landmark may be from the head's outline and still be matched to it,
#: in contour thresholds: it stands for a place on the outline, and a head far from it
#: (the start of a fit) still has to be pulled there.
OUTLINE_POINT_REACH = 2.5


#: The key of a fitted model kept with its head model (``memo``; its slices kept with it).
FITTED_MODEL = "fitted model"

#: Bytes the cached vertex-subset slices of a model may hold (``Engine.slice``): a fit
#: uses a few dozen MB of them again and again; beyond this the least recent are let go.
SLICE_CACHE_BYTES = 192 << 20


def _is_subset_key(key):
    return isinstance(key, bytes) or (isinstance(key, tuple) and key[0] == "vm")


def forget_fit_subsets(model):
    """Let go of the vertex subsets the fits of ``model`` cached (``Engine.slice``,
    ``Engine.vertex_major``), keeping what every fit asks for (the skin's basis). For a
    batch between heads: another head seldom asks for the same subsets (its visible
    landmarks, its outline's candidates), so they would pile up to ``SLICE_CACHE_BYTES``
    in a worker, about 1 MB a head; made again, they cost a fit about 10 ms."""
    for key, lin in memo_items(model):
        if not (isinstance(key, tuple) and key[:1] == (FITTED_MODEL,)):
            continue
        cache = dict(memo_items(lin)).get("slices")
        for k in [k for k in list(cache or ()) if _is_subset_key(k)]:
            cache.pop(k, None)


def fitted_model(model, opts):
    """The model a fit of ``model`` with ``FitOptions`` ``opts`` changes: the first
    ``n_identity`` global modes, then the regional ones; kept with the model for the next
    fit of the same sizes (its vertex slices cached on it)."""
    def make():
        parts = []
        if opts.n_identity > 0:
            parts.append(model.identity.first(int(opts.n_identity)))
        if opts.n_regional > 0:
            parts.append(model.regional(int(opts.n_regional)))
        return StackedModel(parts)

    return memo(model, (FITTED_MODEL, int(opts.n_identity), int(opts.n_regional)), make)


def skin_basis32(lin, skin):
    """The basis of the fitted model ``lin`` over the vertices ``skin`` (S,) as float32
    (K, 3 S), cached with it (for the per-vertex uncertainty, where display precision is
    enough)."""
    slices = memo(lin, "slices", dict)
    key = ("f32",) + (np.asarray(skin, dtype=np.int64).tobytes(),)
    hit = slices.get(key)
    if hit is None:
        hit = np.concatenate([p.basis[:, skin].reshape(p.n_coeffs, -1).astype(np.float32)
                              for p in lin.parts])
        slices[key] = hit
    return hit


def _nbytes(value):
    return sum(a.nbytes for a in value) if isinstance(value, tuple) else value.nbytes


class Engine:
    """What the stages of one fit share: the model being fitted, the views, the weights.

    Parameters
    ----------
    lin : StackedModel
        The model the fit changes (global modes, possibly with regional ones after them).
    views : list of ViewData
    outline, outline_faces, outline_edges : ndarray
        Candidate vertices of the head's outline in an orthographic profile photo and their
        mesh (see ContourRows): what a view's contour rows use unless the stage gives the
        view candidates of its own (``outlines`` of :meth:`joint`).
    noise_px : float
        Landmark noise the weights assume (rows are weighted 1 / noise^2, so lambda2 = 1 is
        the Bayesian prior for standard-normal coefficients).
    lambda1, lambda2 : float
        Smoothness (per millimetre of region disagreement) and prior weights.
    prior : str
    contour_weight : float
    contour_threshold : float
        Largest pixel distance of a contour correspondence.
    """

    def __init__(self, lin, views, outline, outline_faces, outline_edges, noise_px, lambda1,
                 lambda2, prior, contour_weight, contour_threshold):
        self.lin = lin
        self.views = views
        self.outline = np.asarray(outline, dtype=np.int64)
        self.outline_faces = outline_faces
        self.outline_edges = outline_edges
        self.inv_var = 1.0 / noise_px**2
        self.lambda1 = 1000.0 * lambda1  # Gamma c is in metres; lambda1 is per millimetre
        self.prior = prior
        if prior == "identity":
            # shape_icp penalises stddev * c (metres): rescale so lambda2 = 1 has the same
            # overall strength as the eigen prior.
            sd = np.asarray(lin.stddev, dtype=np.float64)
            self.lambda2 = lambda2 / float(np.sqrt(np.mean(sd**2)))
        else:
            self.lambda2 = lambda2
        self.contour_weight = contour_weight
        self.contour_threshold = contour_threshold
        # Outline rows within this of the traced line are always kept (ContourRows): three
        # sigmas of the placement noise.
        self.contour_keep = CONTOUR_KEEP_SIGMAS * noise_px
        self._by_name = {v.name: v for v in views}
        # photo pixels per pixel of the outline's spacing and normals (options.pixel_scale)
        self.pixel_scale = 1.0
        # whether a front photo's outline landmarks slide (FitOptions.outline_landmarks)
        self.slide_outline = False
        # the head's profile line (HeadModel.profile_chain): where a photo with only a
        # traced outline starts its camera
        self.profile_chain = np.zeros(0, np.int64)
        # the vertices below the neck's base (outline.body_vertices): their outline rows
        # weigh each view's body_scale (None: no vertex is)
        self.body = None
        self.fixed_similarity = self.gauge(views)
        self._slices = memo(lin, "slices", dict)
        # Gamma enters the cost only as Gamma^T Gamma: a factor with one row per
        # coefficient gives the same cost for far fewer rows than three per border vertex.
        self.gamma = None
        if lin.gamma is not None and lambda1 > 0:
            self.gamma = self._slices.get("gamma")
            if self.gamma is None:
                g = np.asarray(lin.gamma, dtype=np.float64)
                evals, evecs = np.linalg.eigh(g.T @ g)
                keep = evals > 1e-12 * max(float(evals[-1]), 1e-300)
                self.gamma = np.sqrt(evals[keep])[:, None] * evecs[:, keep].T
                self._slices["gamma"] = self.gamma

    @classmethod
    def for_fit(cls, model, views, opts):
        """The engine of a fit of ``model`` to ``views`` with ``FitOptions`` ``opts``: the
        model it changes (:func:`fitted_model`), the profile's outline candidates, and the
        options' weights and ``pixel_scale``."""
        eng = cls(fitted_model(model, opts), views,
                  *outline_candidates(model, max_normal_x=profile_normal_bound(views)),
                  opts.noise_px, opts.lambda1, opts.lambda2, opts.prior, opts.contour_weight,
                  opts.contour_threshold_px)
        eng.pixel_scale = float(opts.pixel_scale or 1.0)
        eng.slide_outline = opts.outline_landmarks == "slide"
        eng.profile_chain = np.asarray(model.profile_chain, dtype=np.int64)
        eng.body = body_vertices(model)
        return eng

    # ------------------------------------------------------------------ views

    def view(self, name):
        """The ViewData called ``name``."""
        return self._by_name[name]

    def real_view(self, view):
        """The view whose camera ``view``'s camera is (itself unless a mirror view)."""
        return self._by_name[view.mirror_of] if view.mirror_of is not None else view

    def camera_moves(self, view):
        """Whether the fit moves the camera of ``view`` (a mirror view's: its real one)."""
        real = self.real_view(view)
        return bool(real.refit and real.camera is not None
                    and real.camera.min_refit_points > 0)

    def mirrors_of(self, view):
        """The mirror views whose camera is ``view``'s camera reflected."""
        return [u for u in self.views if u.mirror_of == view.name]

    def gauge(self, views):
        """The head's similarity parameters the views cannot determine, to keep fixed:

        - every camera free: ("scale", "translation"), plus "rotation" when every camera is
          perspective (an orthographic camera keeps its viewing direction, which fixes the
          head's turn; free perspective cameras turn with the head);
        - a calibrated orthographic camera, or two calibrated perspective ones, measure
          the head: nothing;
        - else (one calibrated perspective camera, with or without a mirror): ("scale",):
          size and distance trade off along the rays; the model's size decides.
        """
        views = list(views)
        fixed = [v for v in views if not self.camera_moves(v)]
        if not fixed:
            out = ("scale", "translation")
            if views and all(self.real_view(v).camera.perspective for v in views):
                out += ("rotation",)
            return out
        if any(not self.real_view(v).camera.perspective for v in fixed):
            return ()
        if sum(1 for v in fixed if v.mirror_of is None) >= 2:
            return ()
        return ("scale",)

    # ------------------------------------------------------------------ geometry

    def local(self, state, vertices=None):
        """Model-space positions mean + B c, (n, 3) (all vertices if ``vertices`` is None)."""
        if vertices is None:
            return self.lin.mean + sum(self.lin.displacements(state.coeffs))
        mean, basis = self.slice(vertices)
        return mean + np.tensordot(state.coeffs, basis, axes=1)

    def slice(self, vertices):
        """(mean (n, 3), basis (K, n, 3)) of a vertex subset, cached with the model:
        gathering a few hundred vertices from the (K, V, 3) basis costs more than the rest
        of a Gauss-Newton step."""
        v = np.ascontiguousarray(vertices, dtype=np.int64)
        return self._subset(v.tobytes(), lambda: self.lin.slice(v))

    def vertex_major(self, vertices):
        """The basis of a vertex subset vertex-major, (n, 3, K) C order, cached with its
        :meth:`slice` (the joint rounds gather their rows' modes from it)."""
        v = np.ascontiguousarray(vertices, dtype=np.int64)
        return self._subset(("vm", v.tobytes()), lambda: np.ascontiguousarray(
            self.slice(v)[1].transpose(1, 2, 0)))

    def _subset(self, key, make):
        """A cached vertex-subset array (:meth:`slice`, :meth:`vertex_major`), made when
        missing; the least recently used ones are forgotten beyond ``SLICE_CACHE_BYTES``
        (a fit's outline candidates differ from head to head: a batch would pile them up)."""
        cache = self._slices
        hit = cache.pop(key, None)
        made = hit is None
        if made:
            hit = make()
        cache[key] = hit  # the most recently used last
        if made:  # only a new one can take the cache past its budget
            subsets = [k for k in cache if _is_subset_key(k)]
            total = sum(_nbytes(cache[k]) for k in subsets)
            for k in subsets[:-1]:  # oldest first, never the one just asked for
                if total <= SLICE_CACHE_BYTES:
                    break
                total -= _nbytes(cache.pop(k))
        return hit

    def world(self, state, vertices=None):
        return state.scale * self.local(state, vertices) @ state.rotation.T + state.translation

    def copies_model(self, vertices):
        """A LinearModel over copies of ``vertices`` (row i = vertex ``vertices[i]``), with
        the compressed Gamma: what a shape-ICP over those vertices needs."""
        mean, basis = self.slice(vertices)
        return LinearModel(mean, basis, self.lin.stddev, self.lin.names, self.gamma)

    def problem(self, lin, rows, freeze=(), gauge=None, vertex_major=None):
        """A ShapeProblem with the fit's priors; ``gauge`` (default: the engine's, see
        :meth:`gauge`) are the head's similarity parameters kept fixed besides ``freeze``;
        ``vertex_major`` as ShapeProblem takes it (:meth:`vertex_major` of the copies)."""
        fix = self.fixed_similarity if gauge is None else tuple(gauge)
        return ShapeProblem(lin, rows, lambda1=self.lambda1, lambda2=self.lambda2,
                            prior=self.prior, freeze=tuple(freeze) + fix,
                            vertex_major=vertex_major)

    def prior_cost(self, coeffs):
        """lambda2^2 |Lambda c|^2 + lambda1^2 |Gamma c|^2 as the shape-ICP counts it."""
        c = np.asarray(coeffs, dtype=np.float64)
        if self.prior == "identity":
            cost = self.lambda2**2 * float(((self.lin.stddev * c) ** 2).sum())
        else:
            cost = self.lambda2**2 * float(c @ c)
        if self.gamma is not None:
            gc = self.gamma @ c
            cost += self.lambda1**2 * float(gc @ gc)
        return cost

    def effective_parameters(self, cov):
        """The number of coefficients the data, not the prior, decide: K - tr(P Sigma), with
        P the prior's precision as :meth:`prior_cost` counts it and ``cov`` (K, K) the
        posterior covariance of the coefficients."""
        k = cov.shape[0]
        if self.prior == "identity":
            prec = np.diag(self.lambda2**2 * np.asarray(self.lin.stddev[:k]) ** 2)
        else:
            prec = self.lambda2**2 * np.eye(k)
        if self.gamma is not None:
            prec = prec + self.lambda1**2 * (self.gamma.T @ self.gamma)[:k, :k]
        return float(k - np.trace(prec @ cov))

    def camera_prior_cost(self, state, views=None):
        """The priors of the free pinhole cameras (of ``views``' real cameras, default all):
        their focal lengths' ((log f - log f0) / sigma)^2, the cost ``PinholeCamera.refit``
        adds for points weighted as inverse pixel variances, and their directions'
        (``PinholeCamera.prior_cost``)."""
        total = 0.0
        seen = set()
        for v in self.views if views is None else views:
            real = self.real_view(v)
            if real.name in seen or not self.camera_moves(real) or self.lambda2 <= 0:
                continue
            seen.add(real.name)
            cam = state.cameras[real.name]
            total += cam.prior_cost(self.landmark_count(real))
        return float(total)

    def landmark_count(self, view):
        """Weighted landmarks a real camera is seen through: its own and its mirror
        views'."""
        return int(sum(np.count_nonzero(u.weights) for u in [view] + self.mirrors_of(view)))

    # ------------------------------------------------------------------ cameras

    def use(self, state):
        """Make ``state``'s cameras the views' current cameras."""
        for v in self.views:
            v.camera = state.cameras[v.name]

    def finish_views(self, state):
        """After the cameras are placed: which views look along the head's left-right axis
        (at the head's landmarks), which at the face (within FRONTAL_DEGREES) or along that
        axis (within PROFILE_DEGREES: a profile photo), and so the
        landmarks' roles in each (``views.assign_roles``; sliding only with
        ``FitOptions.outline_landmarks="slide"``)."""
        self.use(state)
        verts = np.concatenate([v.vertices for v in self.views])
        centre = self.world(state, verts).mean(axis=0)
        axis = state.rotation[:, 0]
        forward = -state.rotation[:, 1]  # the face looks toward -Y
        for v in self.views:
            d = np.asarray(v.camera.toward_camera(centre[None, :]), dtype=np.float64)[0]
            length = np.linalg.norm(d)
            v.side = bool(abs(d @ axis) > 0.7 * length)
            frontal = d @ forward > np.cos(np.radians(FRONTAL_DEGREES)) * length
            profile = abs(d @ axis) > np.cos(np.radians(PROFILE_DEGREES)) * length
            assign_roles(v, frontal and self.slide_outline, profile)

    def _camera_points(self, state, view, extra):
        """(world points, pixels, weights) a real camera is refitted to: its landmarks,
        ``extra`` pairs, and its mirror views' landmarks and pairs with the points
        reflected in their planes (the real camera sees the reflection where the mirror
        image is)."""
        pts, px, w = [], [], []
        for u in [view] + self.mirrors_of(view):
            x = [self.world(state, u.vertices)]
            q, ww = [u.pixels], [u.fixed_weights]
            for ev, ep, ew in extra.get(u.name, ()):
                x.append(self.world(state, ev))
                q.append(ep)
                ww.append(ew)
            x = np.concatenate(x)
            if u is not view:
                x = state.planes[u.name].reflect_points(x)
            pts.append(x)
            px.append(np.vstack(q))
            w.append(np.concatenate(ww))
        return np.concatenate(pts), np.vstack(px), self.inv_var * np.concatenate(w)

    def refit_cameras(self, state, extra=None, views=None):
        """Every free camera (of ``views``, default all) refitted to the head of
        ``state``: its landmarks plus ``extra[view name]`` = list of (model vertices,
        pixels, weights) (e.g. contour correspondences), with weights read as inverse
        pixel variances (times 1 / noise^2) so a pinhole camera's focal prior weighs as it
        should. A real camera also fits its mirror views' points; then each mirror plane
        is refitted with its real camera kept. Updates ``state.cameras`` (and
        ``state.planes``) and the views; a camera that cannot be refitted raises a
        ValueError naming its view."""
        extra = extra or {}
        todo = list(self.views if views is None else views)
        names = {v.name for v in todo}
        for v in todo:
            if not v.refit or v.mirror_of is not None:
                continue
            x, q, w = self._camera_points(state, v, extra)
            if np.count_nonzero(w) < v.camera.min_refit_points:
                continue  # a profile with only its outline, and none of it matched here
            try:
                state.cameras[v.name] = v.camera.refit(x, q, w)
            except ValueError as e:
                raise ValueError(f"view {v.name!r}: {e}") from None
            names.update(u.name for u in self.mirrors_of(v))
        for u in self.views:
            if u.mirror_of is None or u.name not in names:
                continue
            real = state.cameras[u.mirror_of]
            x, q, w = [self.world(state, u.vertices)], [u.pixels], [u.weights]
            for ev, ep, ew in extra.get(u.name, ()):
                x.append(self.world(state, ev))
                q.append(ep)
                w.append(ew)
            plane = state.planes[u.name].refit(real, np.concatenate(x), np.vstack(q),
                                               np.concatenate(w))
            state.planes[u.name] = plane
            state.cameras[u.name] = real.mirrored(plane)
        self.use(state)

    def init_cameras(self, state, robust_steps=4):
        """Start each free camera from the head of ``state`` (the mean head): fitted to the
        landmark vertices' placed pixels, reweighted robustly (Cauchy) so one misplaced
        landmark does not tilt the start; a pinhole camera's pose only (its focal length
        fitted to the mean head would bend to the mean head's shape; the joint rounds fit
        it with the shape). Then each mirror view's plane from the landmarks seen both
        directly and in the mirror (:meth:`initial_plane`)."""
        for v in self.views:
            if not v.refit or v.mirror_of is not None:
                continue
            if self.outline_only(v):
                state.cameras[v.name] = camera_from_outline(
                    v.camera, v.contour, self.world(state, self.profile_chain))[0]
                continue
            x = self.world(state, v.vertices)
            w = self.inv_var * v.weights
            probe = v.camera.pose_only()
            cam = probe.refit(x, v.pixels, w)
            for _ in range(robust_steps):
                r = np.linalg.norm(cam.project(x) - v.pixels, axis=1)
                c = max(2.0 * float(np.median(r)), 1e-6)
                cam = probe.refit(x, v.pixels, w / (1.0 + (r / c) ** 2))
            if probe is not v.camera:
                cam = v.camera.replaced(rotation=cam.rotation, centre=cam.centre)
            state.cameras[v.name] = cam
        for v in self.views:
            if v.mirror_of is not None:
                state.planes[v.name] = self.initial_plane(state, v)
                state.cameras[v.name] = state.cameras[v.mirror_of].mirrored(
                    state.planes[v.name])
        self.use(state)

    @staticmethod
    def outline_only(view):
        """Whether ``view`` is an orthographic profile photo with a traced outline and
        fewer landmarks than a camera needs (``MIN_LANDMARKS_PER_VIEW``): its camera
        starts from the outline (``contour_start``)."""
        return view.contour is not None and view.side and not view.camera.perspective \
            and np.count_nonzero(view.weights) < MIN_LANDMARKS_PER_VIEW

    def initial_plane(self, state, view):
        """A mirror view's plane from its real camera (seed 001 §3.2.2,
        ``solver.mirror.estimate_mirror``): the normal from the viewing rays of the
        landmarks seen both directly and in the mirror (the file names both by the
        subject's true side, so pairs match by name), the distance from a length on the
        current head: the two paired landmarks farthest apart.

        Raises
        ------
        ValueError
            Fewer than 2 landmarks in both views, a real camera that is not perspective,
            or pairs that do not fix the normal (names the view).
        """
        real_view = self.view(view.mirror_of)
        where = f"view {view.name!r} (mirror of {real_view.name!r})"
        real = state.cameras[real_view.name]
        if not real.perspective:
            raise ValueError(f"{where}: the mirror needs a perspective camera in "
                             f"{real_view.name!r} (pinhole or DLT), got {real.kind}")
        direct = {n: i for i, n in enumerate(real_view.names) if real_view.weights[i] > 0}
        common = [(direct[n], j) for j, n in enumerate(view.names)
                  if n in direct and view.weights[j] > 0]
        if len(common) < 2:
            raise ValueError(f"{where}: {len(common)} landmark(s) seen both directly and in "
                             "the mirror; the mirror's plane needs at least 2")
        i_d = np.array([a for a, _ in common])
        i_m = np.array([b for _, b in common])
        x = self.world(state, real_view.vertices[i_d])
        d = np.linalg.norm(x[:, None] - x[None], axis=2)
        a, b = np.unravel_index(int(np.argmax(d)), d.shape)
        names = [real_view.names[i] for i in i_d]
        try:
            fit = estimate_mirror(real.as_dlt(), real_view.pixels[i_d], view.pixels[i_m],
                                  names, known_length=(names[a], names[b], float(d[a, b])))
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None
        return fit.plane

    def joint(self, views, front_weight=1.0, contour=True, landmarks=True, outlines=None,
              keep_distance=None):
        """A :class:`Joint` problem over the landmarks and contours of ``views``;
        ``outlines`` (view name -> (vertices, faces, edges)) are the outline candidates of
        the views that do not use the profile's (:meth:`outline_candidates`);
        ``keep_distance`` (pixels, default ``contour_keep``): contour rows within it are
        never trimmed (``ContourRows``)."""
        return Joint(self, views, front_weight, contour, landmarks, outlines, keep_distance)

    def outline_candidates(self, view, outlines=None):
        """(vertices (n,), faces (F, 3), edges (E, 4)) the contour rows of ``view`` choose
        the model's outline from: ``outlines[view.name]`` when given, else the engine's
        profile candidates."""
        own = None if outlines is None else outlines.get(view.name)
        if own is not None:
            return own
        return self.outline, self.outline_faces, self.outline_edges

    # ------------------------------------------------------------------ rows

    def landmark_rows(self, view, start, front_weight=1.0, slide=False):
        """Image rows of ``view``'s landmarks on copies ``start`` ... ``start + n - 1``,
        weighted 1 / noise^2 (and ``front_weight`` unless a profile photo), each definition
        group sharing an offset (``view.definition_m``); with ``slide`` those that slide
        (``view.slide``) weigh 0: :meth:`sliding_rows` fits them."""
        n = len(view.vertices)
        w = self.landmark_scale(view, front_weight) * (
            view.fixed_weights if slide else view.weights)
        if view.definition_m > 0.0:
            return GroupedImageRows(np.arange(start, start + n), view.pixels, view.camera,
                                    view.groups, definition_sigmas(view), weights=w,
                                    name=f"landmarks {view.name}")
        return ImageRows(np.arange(start, start + n), view.pixels, view.camera, weights=w,
                         name=f"landmarks {view.name}")

    def landmark_scale(self, view, front_weight=1.0):
        """What a landmark weight of ``view`` is multiplied by in its rows: 1 / noise^2,
        and ``front_weight`` unless a profile photo."""
        return (1.0 if view.side else front_weight) * self.inv_var

    def without_definition_offsets(self, state, local, residuals, front_weight=1.0):
        """The landmark residuals (view name -> ViewResidual) less the offsets their
        definition groups most likely share (``definition.group_offsets``; those matched
        to the outline and those left out as they were): what the placement noise is
        measured on (``noise.estimate_noise``); the parameters the offsets take up; and
        per view the offsets' size the residuals say (metres; views with no group of
        ``MIN_GROUP`` points left out)."""
        world = state.scale * local @ state.rotation.T + state.translation
        out, dof, sizes = dict(residuals), 0.0, {}
        for v in self.views:
            res = residuals.get(v.name)
            if res is None or not len(v.vertices) or v.definition_m == 0.0:
                continue
            cam = state.cameras[v.name]
            x = world[v.vertices]
            r = v.pixels - cam.project(x)
            jac = np.asarray(cam.jacobian(x), dtype=np.float64).reshape(-1, 2, 3)
            apart = set(res.outline) | set(res.unused)
            w = self.landmark_scale(v, front_weight) * np.where(
                [n in apart for n in v.names], 0.0, v.weights)
            e, taken, ratio = group_offsets(r, v.groups, w, jac, definition_sigmas(v),
                                            v.detected)
            dof += taken
            if ratio is not None:
                sizes[v.name] = ratio * v.definition_m
            pixels = np.where(w > 0, np.linalg.norm(r - e, axis=1), res.pixels)
            out[v.name] = dataclasses.replace(res, pixels=pixels)
        return out, dof, sizes

    def sliding_rows(self, view, start, outlines=None, front_weight=1.0):
        """Rows of ``view``'s sliding landmarks (``view.slide``), weighted as
        :meth:`landmark_rows` weighs landmarks: across the head's outline, on copies of its
        outline candidates from ``start`` (:meth:`outline_candidates`), then along it, on
        copies of their own vertices after those (with ``view.along_weights``).

        Returns
        -------
        rows : list
            [OutlinePointRows, OutlineAlongRows]
        copies : ndarray
            The model vertices of the copies from ``start``, in order.
        idx : ndarray
            The landmarks' indices in the view.
        """
        cand, faces, edges = self.outline_candidates(view, outlines)
        idx = np.flatnonzero(view.slide)
        scale = self.landmark_scale(view, front_weight)
        across = OutlinePointRows(np.arange(start, start + len(cand)), view.pixels[idx],
                                  view.camera, scale * view.weights[idx], faces, edges,
                                  max_distance=OUTLINE_POINT_REACH * self.contour_threshold,
                                  name=f"outline points {view.name}")
        at = start + len(cand)
        along = OutlineAlongRows(np.arange(at, at + len(idx)), view.pixels[idx], view.camera,
                                 scale * view.along_weights[idx], across,
                                 name=f"outline along {view.name}")
        return [across, along], np.concatenate([cand, view.vertices[idx]]), idx

    def contour_rows(self, view, start, outlines=None, keep_distance=None):
        """Rows of ``view``'s traced outline on copies of its outline candidates from
        ``start`` (:meth:`outline_candidates`), with the engine's weights and cut-offs;
        ``keep_distance`` (pixels, default ``contour_keep``): rows within it are never
        trimmed. Returns (rows, candidate vertices)."""
        cand, faces, edges = self.outline_candidates(view, outlines)
        rows = ContourRows(np.arange(start, start + len(cand)), view.contour, view.camera,
                           weights=self.contour_weight * self.inv_var * view.contour_scale,
                           faces=faces,
                           edges=edges, max_distance=self.contour_threshold,
                           keep_distance=self.contour_keep if keep_distance is None
                           else keep_distance, spacing_px=SPACING_PX * self.pixel_scale,
                           normal_span_px=NORMAL_SPAN_PX * self.pixel_scale,
                           body=None if self.body is None else self.body[cand],
                           body_scale=view.body_scale, name=f"contour {view.name}")
        return rows, cand

    def landmark_targets(self, state):
        """3-D targets of the landmark vertices: each vertex moved, within the image plane
        of every photo that shows it, onto its placed pixels (least squares over the photos
        through their cameras' Jacobians; a direction no photo sees keeps the model's
        value: the depth of a front-only landmark).

        Returns
        -------
        vertices : ndarray, shape (n,)
            Unique landmark vertices.
        current : ndarray, shape (n, 3)
            Their world positions now.
        targets : ndarray, shape (n, 3)
        """
        views = self.views
        allv = np.concatenate([v.vertices[v.fixed_weights > 0] for v in views])
        uniq, inv = np.unique(allv, return_inverse=True)
        x = self.world(state, uniq)
        a = np.zeros((len(uniq), 3, 3))
        b = np.zeros((len(uniq), 3))
        start = 0
        for v in views:
            use = v.fixed_weights > 0
            n = int(use.sum())
            if n == 0:
                continue
            idx = inv[start:start + n]
            start += n
            cam = state.cameras[v.name]
            xi = x[idx]
            jac = np.asarray(cam.jacobian(xi), dtype=np.float64).reshape(n, 2, 3)
            r = v.pixels[use] - cam.project(xi)
            w = v.weights[use]
            np.add.at(a, idx, w[:, None, None] * np.einsum("nki,nkj->nij", jac, jac))
            np.add.at(b, idx, w[:, None] * np.einsum("nki,nk->ni", jac, r))
        eps = 1e-9 * np.trace(a, axis1=1, axis2=2)[:, None, None] * np.eye(3) \
            + 1e-12 * np.eye(3)
        delta = np.linalg.solve(a + eps, b[..., None])[..., 0]
        return uniq, x, x + delta

    # ------------------------------------------------------------------ errors

    def reprojection(self, state, views=None):
        """Per view: the residuals (pixels) of the landmarks tied to their vertices
        (weight above 0, not sliding)."""
        out = {}
        for v in self.views if views is None else views:
            use = v.fixed_weights > 0
            px = state.cameras[v.name].project(self.world(state, v.vertices[use]))
            out[v.name] = np.linalg.norm(px - v.pixels[use], axis=1)
        return out

