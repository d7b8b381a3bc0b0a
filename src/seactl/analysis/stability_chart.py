"""Stability chart over two delays: crossing curves, regions and their certified counts.

The crossing curves (:mod:`seactl.analysis.crossing_curves`) cut the chart ``[0, T1] x
[0, T2]`` into regions in each of which the number of right-half-plane roots is constant
(roots cross the imaginary axis only on the curves; a retarded equation's roots move
continuously with the delays).  The curves are drawn on a raster of ``resolution x
resolution`` pixels (densely sampled, every pixel they pass marked); the regions are the
4-connected components of the unmarked pixels, each represented by its point farthest from
the curves, where :func:`seactl.analysis.margins.certified_right_roots` counts the roots.
The counts are checked against the crossing directions: across a curve crossed by the
root ``jw`` the count changes by ``2 sign(d Re s / d tau . n)`` (implicit function theorem
on ``Delta``, Gu, Niculescu & Chen 2005, Section 5); disagreements are reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from seactl.analysis.crossing_curves import Branch, crossing_branches
from seactl.analysis.margins import certified_right_roots
from seactl.analysis.roots import frequency_scale
from seactl.analysis.torus import TorusPolynomial
from seactl.diagram.blockdiagram import QuasiPolynomial
from seactl.diagram.delayterms import DelayTerms

CHECKS_PER_BRANCH = 12
"""Points of each branch where the crossing direction is compared with the counts."""
PROBE_PIXELS = 2.5
"""Largest distance [pixels] of the two probes on either side of a curve; a third of the
gap to the nearest other curve where that is smaller."""
THIN_PIXELS = 4.0
"""Where another curve is nearer than this [pixels], the probes are counted directly (the
region between may hold no whole pixel)."""
MAX_DIRECT = 4000
"""Most probes counted directly (evenly subsampled beyond)."""


@dataclass
class Chart:
    """What :func:`stability_chart` computes (delays [s], frequencies [rad/s])."""

    branches: list[Branch]
    labels: np.ndarray
    points_s: np.ndarray
    counts: np.ndarray
    pixels: np.ndarray
    design_s: np.ndarray
    design_count: int
    checks: list[dict[str, Any]] = field(default_factory=list)


def one_design(terms: DelayTerms) -> DelayTerms:
    """The :class:`DelayTerms` of a batch of one design, as a batch of shape ``(1,)``."""
    J, n1 = terms.coeffs.shape[0], terms.coeffs.shape[-1]
    D = len(terms.names)
    return DelayTerms(terms.coeffs.reshape(J, 1, n1), terms.exponents, terms.names,
                      terms.delays_s.reshape(D, 1))


def counts_at(terms: DelayTerms, i1: int, i2: int, points_s: np.ndarray) -> np.ndarray:
    """Certified right-half-plane root counts (-1: not certain) at ``points_s`` ``(R, 2)``
    [s], the other delays at the design's."""
    if points_s.shape[0] == 0:
        return np.zeros(0, int)
    tau = np.repeat(terms.delays_s, points_s.shape[0], axis=1)
    tau[i1], tau[i2] = points_s[:, 0], points_s[:, 1]
    q = terms.at(tau).flat()
    return certified_right_roots(q, frequency_scale(q))


def samples(b: Branch, max_s: tuple[float, float], n: int) -> np.ndarray:
    """``(S, 2)`` points of a branch in pixel units (column, row), its segments sampled
    every quarter pixel."""
    x, y = b.tau1_s / max_s[0] * n, b.tau2_s / max_s[1] * n
    if x.size == 1:
        return np.column_stack([x, y])
    m = np.ceil(4 * np.hypot(np.diff(x), np.diff(y))).astype(int) + 1
    t = np.concatenate([np.linspace(0, 1, k, endpoint=False) for k in m] + [[1.0]])
    i = np.concatenate([np.repeat(np.arange(m.size), m), [m.size - 1]])
    return np.column_stack([x[i] + t * (x[i + 1] - x[i]), y[i] + t * (y[i + 1] - y[i])])


def rasterize(branches: list[Branch], max_s: tuple[float, float], n: int) -> np.ndarray:
    """``(n, n)`` boolean image (row: ``tau2``, column: ``tau1``) of the pixels the curves
    pass through."""
    img = np.zeros((n, n), bool)
    for b in branches:
        p = np.floor(samples(b, max_s, n)).astype(int)
        ok = ((p >= 0) & (p < n)).all(axis=1)
        img[p[ok, 1], p[ok, 0]] = True
    return img


def regions(curves: np.ndarray, max_s: tuple[float, float]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The components of the free pixels: the label image (-1 on the curves), each
    component's point farthest from the curves and the chart's edges ``(R, 2)`` [s], and
    its size [pixels]."""
    from scipy import ndimage

    n = curves.shape[0]
    lab, count = ndimage.label(~curves)
    if count == 0:
        return lab - 1, np.zeros((0, 2)), np.zeros(0, int)
    dist = ndimage.distance_transform_edt(np.pad(~curves, 1))[1:-1, 1:-1]  # (edges too)
    pos = np.array(ndimage.maximum_position(dist, lab, np.arange(1, count + 1)), float)
    pts = np.column_stack([(pos[:, 1] + 0.5) / n * max_s[0], (pos[:, 0] + 0.5) / n * max_s[1]])
    size = np.bincount(lab.ravel(), minlength=count + 1)[1:]
    return lab - 1, pts, size


def merge_corners(labels: np.ndarray, counts: np.ndarray, pixels: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Components with the same count that touch at a pixel's corner joined (a thin
    diagonal region falls apart into such pieces on the raster; two regions meeting where
    two curves cross are joined only if their counts agree): the new label image and, per
    new label, the old component kept as its representative (the largest)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = []
    for a, b in ((labels[:-1, :-1], labels[1:, 1:]), (labels[:-1, 1:], labels[1:, :-1])):
        m = (a >= 0) & (b >= 0) & (a != b)
        pairs.append(np.column_stack([a[m], b[m]]))
    pairs = np.unique(np.concatenate(pairs), axis=0)
    pairs = pairs[(counts[pairs[:, 0]] == counts[pairs[:, 1]]) & (counts[pairs[:, 0]] >= 0)]
    R = counts.size
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), (R, R))
    _, comp = connected_components(g, directed=False)
    order = np.lexsort((-pixels, comp))
    keep = order[np.concatenate([[True], np.diff(comp[order]) != 0])]
    new = np.full(R + 1, -1)
    new[:R] = np.searchsorted(comp[keep], comp)
    return new[labels], keep


def crossing_direction(terms: DelayTerms, i1: int, i2: int, tau_s: np.ndarray,
                       w: np.ndarray) -> np.ndarray:
    """``(P, 2)``: ``grad Re s`` [1/s^2] of the root ``s = jw`` at ``tau_s`` ``(P, 2)``,
    ``ds/dtau_i = -(dDelta/dtau_i) / (dDelta/ds)``, ``dDelta/dtau_i = -s sum_j E_ji
    p_j(s) e^{-s tau_j}``; NaN at a multiple root."""
    tau = np.repeat(terms.delays_s, tau_s.shape[0], axis=1)
    tau[i1], tau[i2] = tau_s[:, 0], tau_s[:, 1]
    q = terms.at(tau).flat()
    s = 1j * w[:, None]
    _, dq = q.with_derivative(s)
    out = np.full(tau_s.shape, np.nan)
    for col, i in enumerate((i1, i2)):
        e = terms.exponents[:, i].astype(float)[:, None, None]
        qi = QuasiPolynomial(q.coeffs * e, q.delays)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[:, col] = (s * qi(s) / dq)[:, 0].real
    return out


@dataclass
class Probes:
    """Interior vertices of the branches, in pixel units: ``centre (P, 2)`` (column, row),
    unit ``normal (P, 2)``, ``gap``: the distance to the nearest other curve or a third of
    the curve's radius of curvature there if smaller, ``w (P,)`` [rad/s], and ``check``:
    the points where the crossing direction is compared with the counts."""

    centre: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    w: np.ndarray
    check: np.ndarray
    branch: np.ndarray


def curve_probes(branches: list[Branch], max_s: tuple[float, float], n: int) -> Probes:
    """Every interior vertex of every branch, its normal and its gap to other curves."""
    cen, nrm, w, chk, own, rad = [], [], [], [], [], []
    for k, b in enumerate(branches):
        m = b.w_rad_s.size
        if m < 3:
            continue
        x, y = b.tau1_s / max_s[0] * n, b.tau2_s / max_s[1] * n
        t = np.column_stack([x[2:] - x[:-2], y[2:] - y[:-2]])
        t /= np.maximum(np.hypot(t[:, 0], t[:, 1]), 1e-300)[:, None]
        cen.append(np.column_stack([x[1:-1], y[1:-1]]))
        rad.append(_circumradius(x, y))
        nrm.append(np.column_stack([-t[:, 1], t[:, 0]]))
        w.append(b.w_rad_s[1:-1])
        c = np.zeros(m - 2, bool)
        c[np.unique(np.linspace(0, m - 3, CHECKS_PER_BRANCH).astype(int))] = True
        chk.append(c)
        own.append(np.full(m - 2, k))
    if not cen:
        z = np.zeros((0, 2))
        return Probes(z, z, np.zeros(0), np.zeros(0), np.zeros(0, bool), np.zeros(0, int))
    cen_a, owner = np.concatenate(cen), np.concatenate(own)
    gap = np.minimum(_gaps(branches, max_s, n, cen_a, owner), np.concatenate(rad) / 3)
    return Probes(cen_a, np.concatenate(nrm), gap, np.concatenate(w), np.concatenate(chk),
                  owner)


def _circumradius(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The radius of the circle through each vertex and its two neighbours (inf if they
    are aligned)."""
    ax, ay, bx, by = x[:-2] - x[1:-1], y[:-2] - y[1:-1], x[2:] - x[1:-1], y[2:] - y[1:-1]
    cross = np.abs(ax * by - ay * bx)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.hypot(ax, ay) * np.hypot(bx, by) * np.hypot(ax - bx, ay - by) / (2 * cross)
    return np.where(np.isfinite(r), r, np.inf)


def _gaps(branches: list[Branch], max_s: tuple[float, float], n: int, centre: np.ndarray,
          owner: np.ndarray) -> np.ndarray:
    """Distance [pixels] from each point of a branch to the nearest point of another
    branch, or of its own branch where the arc between them is not nearly straight (an
    arc longer than 1.2 times the distance: the other side of a thin loop)."""
    from scipy.spatial import cKDTree

    radius = 3 * THIN_PIXELS
    pts = [samples(b, max_s, n) for b in branches]
    arc = [np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))]) for p in pts]
    sowner = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)])
    sarc = np.concatenate(arc)
    allp = np.concatenate(pts)
    tree = cKDTree(allp)
    own_tree = {k: cKDTree(p) for k, p in enumerate(pts)}
    gap = np.full(len(centre), np.inf)
    for j, (idx, k, c) in enumerate(zip(tree.query_ball_point(centre, radius), owner,
                                        centre)):
        idx = np.asarray(idx, int)
        if idx.size == 0:
            continue
        here = arc[k][own_tree[k].query(c)[1]]
        dist = np.hypot(*(allp[idx] - c).T)
        far = (sowner[idx] != k) | (np.abs(sarc[idx] - here) > 1.2 * dist + 0.02)
        if far.any():
            gap[j] = dist[far].min()
    return gap


def side_counts(terms: DelayTerms, i1: int, i2: int, pr: Probes, labels: np.ndarray,
                counts: np.ndarray, max_s: tuple[float, float]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The counts on either side of each probe's curve (``(2, P)``, sides ``+normal``,
    ``-normal``; -2 where not evaluated): from the region's label where the probe is in a
    whole free pixel and clear of other curves, else counted directly where needed (a check
    point or a thin place).  Also the probes' distance [pixels] from the curve, their
    pixels' labels ``(2, P)`` (-1 on a curve) and points ``(2, P, 2)`` [s]."""
    n = labels.shape[0]
    eps = np.minimum(PROBE_PIXELS, pr.gap / 3)
    side = np.full((2, pr.w.size), -2)
    lab = np.full((2, pr.w.size), -1)
    px = np.stack([pr.centre + sg * eps[:, None] * pr.normal for sg in (1, -1)])
    direct = np.zeros((2, pr.w.size), bool)
    for j in range(2):
        ij = np.floor(px[j]).astype(int)
        inside = ((ij >= 0) & (ij < n)).all(axis=1)
        lab[j, inside] = labels[ij[inside, 1], ij[inside, 0]]
        coarse = (lab[j] >= 0) & (eps >= 1.0)
        side[j, coarse] = counts[lab[j, coarse]]
        direct[j] = ~coarse & inside & (pr.check | (pr.gap < THIN_PIXELS)) & (eps > 1e-3)
    jj, kk = np.nonzero(direct)
    if jj.size > MAX_DIRECT:
        keep = np.unique(np.linspace(0, jj.size - 1, MAX_DIRECT).astype(int))
        jj, kk = jj[keep], kk[keep]
    pts = px / n * np.asarray(max_s, float)
    side[jj, kk] = counts_at(terms, i1, i2, pts[jj, kk])
    return side, eps, lab, pts


def group_regions(pr: Probes, side: np.ndarray, lab: np.ndarray, pts: np.ndarray,
                  n_components: int, max_s: tuple[float, float], n: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Regions as groups of raster components and of probes on curve pixels (thin places):
    two are one region where their probes follow each other along a branch on the same
    side with the same count, or (probes on curve pixels) lie within 2 pixels with the same
    count.  Returns the group of each node (the components, then those probes) and the
    probes' ``(side, probe)`` table."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    R = n_components
    thin_j, thin_k = np.nonzero((lab < 0) & (side >= 0))
    node = lab.copy()
    node[thin_j, thin_k] = R + np.arange(thin_j.size)
    edges = []
    a, b = np.arange(pr.w.size - 1), np.arange(1, pr.w.size)
    for j in range(2):
        ok = ((pr.branch[a] == pr.branch[b]) & (side[j, a] >= 0) & (side[j, a] == side[j, b])
              & (node[j, a] >= 0) & (node[j, b] >= 0))
        edges.append(np.column_stack([node[j, a[ok]], node[j, b[ok]]]))
    tp = pts[thin_j, thin_k] / np.asarray(max_s, float) * n
    near = (cKDTree(tp).query_pairs(2.0, output_type="ndarray").reshape(-1, 2)
            if len(tp) else np.zeros((0, 2), int))
    c = side[thin_j, thin_k]
    edges.append(R + near[c[near[:, 0]] == c[near[:, 1]]])
    e = np.concatenate(edges)
    N = R + thin_j.size
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), (N, N))
    return connected_components(g, directed=False)[1], np.column_stack([thin_j, thin_k])


def region_table(groups: np.ndarray, thin: np.ndarray, side: np.ndarray, pts: np.ndarray,
                 points: np.ndarray, counts: np.ndarray, pixels: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One row per group: its point [s] (its largest component's, or its first thin
    probe's), count and pixels; and each component's new label."""
    R = counts.size
    allp = np.vstack([points, pts[thin[:, 0], thin[:, 1]]])
    allc = np.concatenate([counts, side[thin[:, 0], thin[:, 1]]])
    allpix = np.concatenate([pixels, np.zeros(len(thin), int)])
    order = np.lexsort((-allpix, groups))
    first = order[np.concatenate([[True], np.diff(groups[order]) != 0])]
    new = np.searchsorted(groups[first], groups)
    size = np.bincount(new, weights=allpix, minlength=first.size).astype(int)
    return allp[first], allc[first], size, new[:R]


def checks(terms: DelayTerms, i1: int, i2: int, pr: Probes, side: np.ndarray,
           eps: np.ndarray, max_s: tuple[float, float], n: int) -> list[dict[str, Any]]:
    """At the check points, the count's change across the curve against ``2 sign(grad Re s
    . normal)``: one record each (``tau1_s``, ``tau2_s``, ``w_rad_s``, ``expected_change``,
    ``observed_change``, ``consistent``); skipped where a side has no certain count or the
    root is multiple."""
    k = np.flatnonzero(pr.check & (side >= 0).all(axis=0))
    T = np.asarray(max_s, float)
    tau = pr.centre[k] / n * T
    g = crossing_direction(terms, i1, i2, tau, pr.w[k])
    rate = (g * pr.normal[k] * T / n).sum(axis=1)
    out = []
    for i, r in zip(k, rate):
        if not np.isfinite(r) or r == 0:
            continue
        expected, observed = 2 * int(np.sign(r)), int(side[0, i] - side[1, i])
        out.append({"tau1_s": float(pr.centre[i, 0] / n * T[0]),
                    "tau2_s": float(pr.centre[i, 1] / n * T[1]), "w_rad_s": float(pr.w[i]),
                    "expected_change": expected, "observed_change": observed,
                    "consistent": expected == observed})
    return out


def stability_chart(terms: DelayTerms, delays: tuple[str, str], max_s: tuple[float, float],
                    resolution: int = 1000) -> Chart:
    """The stability chart of a one-design :class:`DelayTerms` over ``delays`` in
    ``[0, max_s[0]] x [0, max_s[1]]`` [s], the other delays at the design's.

    Parameters
    ----------
    terms : DelayTerms
        One design (batch of size 1).
    delays : tuple of str
        The two delays varied.
    max_s : tuple of float
        The chart's extent [s].
    resolution : int
        Pixels per side of the raster that separates the regions.

    Returns
    -------
    Chart
        Curves, label image, one point and certified count per region (a region narrower
        than a pixel, found by the probes beside the curves, has 0 pixels), the design's
        point and count, and the crossing-direction checks.
    """
    terms = one_design(terms)
    i1, i2 = terms.index(delays[0]), terms.index(delays[1])
    branches = crossing_branches(TorusPolynomial.of(terms, i1, i2), max_s)
    labels, pts, size = regions(rasterize(branches, max_s, resolution), max_s)
    design = terms.delays_s[[i1, i2], 0].astype(float)
    counts = counts_at(terms, i1, i2, np.vstack([pts, design[None]]))
    design_count, counts = int(counts[-1]), counts[:-1]
    if counts.size:
        labels, keep = merge_corners(labels, counts, size)
        merged = np.bincount(labels[labels >= 0], minlength=keep.size)
        pts, counts, size = pts[keep], counts[keep], merged
    pr = curve_probes(branches, max_s, resolution)
    side, eps, lab, probe_pts = side_counts(terms, i1, i2, pr, labels, counts, max_s)
    found = checks(terms, i1, i2, pr, side, eps, max_s, resolution)
    groups, thin = group_regions(pr, side, lab, probe_pts, counts.size, max_s, resolution)
    pts, counts, size, relabel = region_table(groups, thin, side, probe_pts, pts, counts, size)
    labels = np.where(labels >= 0, np.concatenate([relabel, [-1]])[labels], -1)
    return Chart(branches, labels, pts, counts, size, design, design_count, found)
