"""Per-vertex shape factors: a body as a linear function of its feature sizes.

The seed's individual body modelling for garment CAD: from example bodies with
one topology (vertex-to-vertex correspondence) and known feature sizes (bust,
waist, hip girths ...), learn each vertex's *shape factor* ``r`` - the
least-squares slope of its position against the sizes - and shape a new body
by moving a reference body along those slopes.

With ``m`` examples and ``k`` features, every vertex coordinate is regressed on
the feature vector with an intercept (multivariate least squares)::

    v_ji ~ vbar_i + sum_k (g_jk - gbar_k) r_ki

and a body of sizes ``g_des`` is ``v = v_ref + sum_k (g_des_k - g_ref_k) r_k``
where ``(v_ref, g_ref)`` is a reference body, by default the examples' mean
``(vbar, gbar)`` (which the fitted plane passes through). The fit residual per
vertex tells how linear the body is in the features there.

This module needs no measurer to fit or shape; only :func:`examples_from_model`
(which builds examples from the hm08 blend shapes) measures bodies.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vfit_engine.body.model import N_BODY, Macro, gender_value
from vfit_engine.body.morph import CHANNELS
from vfit_engine.errors import InputError


@dataclass
class ShapeFactors:
    """A fitted linear shape model.

    Attributes
    ----------
    features : tuple of str, length k
        Feature names, in the order of ``g_ref`` and ``r``.
    v_ref : (n, 3) float64, m
        Reference body.
    g_ref : (k,) float64, m
        Feature sizes of the reference body.
    r : (k, n, 3) float64, m per m
        Shape factors: the displacement of each vertex per metre of each feature.
    residual_rms : (n,) float64, m
        Per vertex, the RMS over the examples of the 3-D distance between the
        example's vertex and the least-squares fit (0 where the examples are
        exactly linear in the features).
    """

    features: tuple
    v_ref: np.ndarray
    g_ref: np.ndarray
    r: np.ndarray
    residual_rms: np.ndarray

    @classmethod
    def fit(cls, examples_verts, features, names, reference=None) -> "ShapeFactors":
        """Fit shape factors to example bodies by least squares.

        Parameters
        ----------
        examples_verts : (m, n, 3) float64, m
            Example bodies in vertex correspondence.
        features : (m, k) float64, m
            Feature sizes of each example; needs ``m > k`` and features that are
            not collinear over the examples.
        names : sequence of str, length k
            Feature names.
        reference : (v_ref (n, 3), g_ref (k,) or dict name -> m), optional
            The body that :meth:`shape` moves; default the examples' mean body
            and mean features.

        Raises
        ------
        InputError
            Wrong shapes, non-finite values, too few examples or collinear features.
        """
        verts = _as_float(examples_verts, "examples_verts")
        g = _as_float(features, "features")
        names = tuple(str(x) for x in names)
        if verts.ndim != 3 or verts.shape[2] != 3 or verts.shape[1] == 0:
            raise InputError(f"examples_verts must have shape (m, n, 3), got {verts.shape}")
        if g.ndim != 2 or g.shape[0] != verts.shape[0]:
            raise InputError(f"features must have shape (m, k) with m = {verts.shape[0]} examples, got {g.shape}")
        m, n, _ = verts.shape
        k = g.shape[1]
        if k == 0 or len(names) != k or len(set(names)) != k:
            raise InputError(f"names must be {k} distinct feature names, got {names!r}")
        if m <= k:
            raise InputError(f"need more examples than features: {m} examples for {k} features")
        if not np.isfinite(verts).all():
            raise InputError("examples_verts contains NaN or infinite values")
        if not np.isfinite(g).all():
            raise InputError("features contains NaN or infinite values")

        g_mean = g.mean(axis=0)
        v_mean = verts.mean(axis=0)
        gc = g - g_mean
        yc = (verts - v_mean).reshape(m, n * 3)
        # SVD of the small (m, k) design; its pseudo-inverse serves every coordinate at once
        u, s, vt = np.linalg.svd(gc, full_matrices=False)
        if s[-1] <= s[0] * 1e-10 or s[0] == 0.0:
            raise InputError("features are constant or collinear over the examples; cannot separate their effects")
        r = (vt.T / s) @ (u.T @ yc)  # (k, n*3)
        res = (yc - gc @ r).reshape(m, n, 3)
        residual_rms = np.sqrt((res ** 2).sum(axis=2).mean(axis=0))
        out = cls(names, v_mean, g_mean, np.ascontiguousarray(r.reshape(k, n, 3)), residual_rms)
        if reference is not None:
            try:
                v_ref, g_ref = reference
            except (TypeError, ValueError):
                raise InputError("reference must be a pair (v_ref (n, 3), g_ref (k,) or dict)") from None
            v_ref = _as_float(v_ref, "reference verts")
            if v_ref.shape != (n, 3) or not np.isfinite(v_ref).all():
                raise InputError(f"reference verts must be finite with shape ({n}, 3), got {v_ref.shape}")
            out.v_ref = v_ref.copy()
            out.g_ref = out.feature_vector(g_ref, "reference features")
        return out

    def feature_vector(self, g, what="g_des") -> np.ndarray:
        """(k,) float64 m from a dict name -> m (exactly the fitted names) or a (k,) array."""
        k = len(self.features)
        if isinstance(g, dict):
            missing = [x for x in self.features if x not in g]
            extra = [x for x in g if x not in self.features]
            if missing or extra:
                raise InputError(f"{what}: expected features {', '.join(self.features)}; "
                                 f"missing {missing or 'none'}, unknown {extra or 'none'}")
            g = [g[x] for x in self.features]
        out = _as_float(g, what)
        if out.shape != (k,):
            raise InputError(f"{what} must have {k} values ({', '.join(self.features)}), got shape {out.shape}")
        if not np.isfinite(out).all():
            raise InputError(f"{what} contains NaN or infinite values")
        return out

    def shape(self, g_des) -> np.ndarray:
        """Body of the desired feature sizes.

        Parameters
        ----------
        g_des : dict name -> m, or (k,) float64, m
            Desired sizes of all fitted features.

        Returns
        -------
        (n, 3) float64, m
            ``v_ref + sum_k (g_des_k - g_ref_k) r_k``.
        """
        d = self.feature_vector(g_des) - self.g_ref
        return self.v_ref + np.tensordot(d, self.r, axes=1)


    def shape_measured(self, g_des, measurer, definition="iso", tol=2e-4, max_iter=10):
        """Body whose *measured* features meet ``g_des``, by correcting the inputs of :meth:`shape`.

        The linear model misses a measured girth where the measurement is not
        linear in the vertices (a tape girth is an extremum over planes whose
        plane can jump), so iterate ``g <- g - (measure(shape(g)) - g_des)``.

        Parameters
        ----------
        g_des : dict name -> m, or (k,) float64, m
        measurer : Measurer
            Measures ``features`` (names from ``measure.NAMES``).
        definition : str
            Measurement definition.
        tol : float, m
            Stop when every feature is within this of its target.
        max_iter : int

        Returns
        -------
        verts : (n, 3) float64, m
        measured : dict name -> m
            The features of ``verts``; compare with ``g_des`` (not guaranteed within ``tol``).
        """
        want = self.feature_vector(g_des)
        g = want.copy()
        for _ in range(max(1, int(max_iter))):
            verts = self.shape(g)
            values = measurer.measure(verts, definition, names=self.features, mass=False).values
            err = np.array([values[x] for x in self.features]) - want
            if np.all(np.abs(err) <= tol):
                break
            g = g - err
        return verts, {x: values[x] for x in self.features}


def _as_float(a, what) -> np.ndarray:
    try:
        return np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be numeric") from None


def examples_from_model(model, measurer, n_examples, rng, names=("bust", "waist", "hips"), gender="female",
                        amplitude=1.0):
    """Random example bodies from the hm08 measure channels, with their measured features.

    Each example is the young-adult average body of ``gender`` plus, for every
    feature, its primary measure channel (``morph.CHANNELS``, e.g.
    ``torso/measure-bust-circ-incr`` or ``-decr``) at a signed weight drawn
    uniformly from ``[-amplitude, amplitude]``. Features are measured with the
    ``iso`` definition.

    Parameters
    ----------
    model : BodyModel
    measurer : Measurer
    n_examples : int
    rng : numpy.random.Generator or int seed
    names : sequence of str
        Girths with a measure channel (keys of ``morph.CHANNELS``).
    gender : 'female', 'male' or 0..1
    amplitude : float
        Largest channel weight (0 < amplitude <= 1).

    Returns
    -------
    verts : (n_examples, 13380, 3) float64, m
        The body vertices of each example.
    features : (n_examples, k) float64, m
        Measured ``names`` of each example.
    """
    unknown = [x for x in names if x not in CHANNELS]
    if unknown:
        raise InputError(f"no measure channel for {', '.join(unknown)}; choose from {', '.join(CHANNELS)}")
    if not 0.0 < amplitude <= 1.0:
        raise InputError(f"amplitude must be in (0, 1], got {amplitude}")
    rng = np.random.default_rng(rng)
    base = model.macro_verts(Macro(gender=gender_value(gender)))
    verts = np.empty((int(n_examples), N_BODY, 3))
    feats = np.empty((int(n_examples), len(names)))
    for j in range(int(n_examples)):
        s = rng.uniform(-amplitude, amplitude, size=len(names))
        weights = {CHANNELS[x] + ("-incr" if w > 0 else "-decr"): abs(float(w)) for x, w in zip(names, s)}
        verts[j] = model.shape(weights, base=base)[:N_BODY]
        values = measurer.measure(verts[j], "iso", names=tuple(names), mass=False).values
        feats[j] = [values[x] for x in names]
    return verts, feats
