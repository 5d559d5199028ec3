"""Which geoms of an MJCF can touch, decided by MuJoCo's own collision geometry over the configurations a task visits.

The symbolic model has no contact forces, so a file is usable where no contact happens. Which geom pairs MuJoCo
*considers* is decided by its collision filter (``contype``/``conaffinity``, bodies welded together, parent and child
bodies, ``<exclude>``; plus every explicit ``<pair>``); whether a considered pair can *touch* is a question of
geometry, answered here with MuJoCo's ``mj_geomDistance`` (signed distance, negative when penetrating):

* **at the equilibrium**: the pair is in contact (closer than the margin) at the upright rest ``x_eq``. Nothing can
  run there; :func:`check_equilibrium_contacts` refuses the file naming the pair, its depth and the edit that fixes it.
* **away from upright**: the pair touches somewhere a swing-up goes (the cart anywhere on its rail, every hinge over
  its range or a full turn around upright) but not at upright. Balancing works; a swing-up is refused
  (:meth:`ContactReport.check_swingup`) naming the pair and where it touches (a 1-D search on one hinge, e.g. "hinge
  'hinge' within 0.35 rad of hanging").
* **never**: the pair cannot touch anywhere in that set. Accepted and listed.

The search is sound: a best-first branch and bound over boxes of the joints that move one geom of the pair relative
to the other, with a Lipschitz bound per joint (a point of a geom moves at most ``L_j`` m per rad of hinge ``j``:
the length of the rigid chain from the hinge's axis to the geom's bounding sphere; 1 m per m of a slide). A box
whose centre's distance minus ``sum_j L_j h_j`` (half-widths ``h_j``) stays at or above the margin cannot touch
anywhere in it. So a pair reported ``never`` is at least ``CONTACT_MARGIN / 2`` apart everywhere in the set (to within
MuJoCo's own distance accuracy), and a pair reported touching has a configuration closer than the margin. In a
planar model (every hinge axis parallel, every slide across it) each geom's extent across the plane of motion is the
same in every configuration, so a pair whose extents there are farther apart than the margin (a rail beside the cart,
a stop beside the poles) is cleared by that gap alone, without a search. The
margin, :data:`CONTACT_MARGIN` (1 mm) on top of the geoms' own ``margin``, makes numerically grazing pairs count.
"""
from __future__ import annotations

import functools
import heapq
import math
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from cartpole.models.params import CartPoleParams, MJCFError, load_model

#: m added to the geoms' own ``margin``: a pair closer than this (anywhere in the set searched) counts as touching.
CONTACT_MARGIN = 1e-3

#: Most distance evaluations the search spends on one pair before it stops (then ``certified`` is False).
MAX_EVALUATIONS = 5000

#: Distance evaluations spent, once a pair is found touching, on finding a deeper touch (best first).
DEEPEN_EVALUATIONS = 200

#: m: half the span searched along a slide that is unlimited, when no finite cart range is given and the geometry
#: does not bound the search by itself (a plane along the rail bounds nothing; a finite geom does).
UNLIMITED_SLIDE_SPAN = 10.0

CLASSES = ("never", "away_from_upright", "at_equilibrium")


class ContactError(MJCFError):
    """Geoms of the MJCF touch where the task needs to go (the symbolic model has no contacts)."""


@dataclass(frozen=True)
class ContactPair:
    """One geom pair MuJoCo's collision filter lets collide, and whether it can touch.

    Attributes
    ----------
    geom1, geom2 : str
        Geom names (``"geom 3"`` when unnamed); ``geom1`` is the one fixed to the world when one is.
    body1, body2 : str
        Their bodies.
    classification : str
        ``"never"``, ``"away_from_upright"`` or ``"at_equilibrium"`` (:data:`CLASSES`).
    min_clearance : float
        m, the smallest signed distance found over the set searched (negative: penetration depth).
    clearance_bound : float
        m, a proven lower bound of the distance over the set (``-inf`` when the search stopped early or a bound is
        unknown); for ``never`` pairs at least ``CONTACT_MARGIN / 2``.
    upright_clearance : float
        m, the signed distance at the upright equilibrium.
    qpos : tuple or None
        Where the deepest touch found is (nq,), None for ``never`` pairs.
    where : str or None
        Where they touch in words (a 1-D search on one joint from ``qpos``), None for ``never``.
    joints : tuple of str
        The joints that move one geom relative to the other (the ones searched).
    explicit : bool
        Declared by an explicit ``<pair>`` (MuJoCo's filter does not apply to it).
    static1 : bool
        ``geom1`` is fixed to the world (a floor, a rail).
    certified : bool
        The search finished (every box decided) within :data:`MAX_EVALUATIONS`.
    threshold : float
        m, the distance below which the pair counts as touching: the larger geom ``margin`` (or the ``<pair>``'s)
        plus :data:`CONTACT_MARGIN`.
    """

    geom1: str
    geom2: str
    body1: str
    body2: str
    classification: str
    min_clearance: float
    clearance_bound: float
    upright_clearance: float
    qpos: tuple | None
    where: str | None
    joints: tuple
    explicit: bool
    certified: bool
    threshold: float
    static1: bool = False

    def to_dict(self) -> dict:
        """JSON-ready dict of every field (infinite bounds as None)."""
        fin = lambda v: float(v) if math.isfinite(v) else None  # noqa: E731
        return {"geom1": self.geom1, "geom2": self.geom2, "body1": self.body1, "body2": self.body2,
                "classification": self.classification, "min_clearance": fin(self.min_clearance),
                "clearance_bound": fin(self.clearance_bound), "upright_clearance": fin(self.upright_clearance),
                "qpos": None if self.qpos is None else [float(v) for v in self.qpos], "where": self.where,
                "joints": list(self.joints), "explicit": self.explicit, "certified": self.certified,
                "threshold": self.threshold, "static1": self.static1}


@dataclass(frozen=True)
class ContactReport:
    """Every geom pair of an MJCF that MuJoCo's collision filter lets collide, classified by reachability.

    Attributes
    ----------
    mjcf : str
        Path of the MJCF ("" for text).
    enabled : bool
        False when the file disables contacts (``<flag contact="disable"/>`` or ``constraint="disable"``): no pairs.
    margin : float
        :data:`CONTACT_MARGIN`, m.
    cart_range : (2,) tuple
        m, the range searched along the cart's slide (the file's unless given; ``+-inf`` when unlimited).
    pairs : tuple of ContactPair
        Every candidate pair, in MuJoCo's geom order.
    seconds : float
        Wall time of the search, s.
    evaluations : int
        ``mj_geomDistance`` calls made.
    """

    mjcf: str
    enabled: bool
    margin: float
    cart_range: tuple
    pairs: tuple
    seconds: float
    evaluations: int

    def of_class(self, classification: str) -> tuple:
        """The pairs of one classification (:data:`CLASSES`)."""
        return tuple(p for p in self.pairs if p.classification == classification)

    @property
    def reachable(self) -> tuple:
        """Pairs that touch somewhere in the set searched (``away_from_upright`` or ``at_equilibrium``)."""
        return tuple(p for p in self.pairs if p.classification != "never")

    def to_dict(self) -> dict:
        """JSON-ready dict: ``enabled``, ``margin``, ``cart_range``, ``pairs`` (list of dicts), ``seconds``,
        ``evaluations``."""
        return {"enabled": self.enabled, "margin": self.margin,
                "cart_range": [float(v) if math.isfinite(v) else None for v in self.cart_range],
                "pairs": [p.to_dict() for p in self.pairs], "seconds": self.seconds, "evaluations": self.evaluations}

    def summary(self) -> str:
        """One sentence for the prose output: how many pairs can collide and which can touch."""
        return ContactReport.sentence(self.to_dict())

    @staticmethod
    def sentence(doc: dict) -> str:
        """:meth:`summary` of a report's :meth:`to_dict` (as the JSON holds it)."""
        if not doc["enabled"]:
            return "Contacts: disabled in the MJCF."
        pairs = doc["pairs"]
        if not pairs:
            return "Contacts: no geom pair can collide (contype/conaffinity)."
        never = [p for p in pairs if p["classification"] == "never"]
        parts = [f"{len(never)} of {len(pairs)} collidable geom pair(s) can never touch"
                 f" (margin {doc['margin'] * 1e3:g} mm)"]
        for p in pairs:
            if p["classification"] != "never":
                parts.append(f"'{p['geom1']}' and '{p['geom2']}' touch "
                             + ("at upright" if p["classification"] == "at_equilibrium"
                                else f"away from upright ({p['where']})"))
        return "Contacts: " + "; ".join(parts) + "."

    def check_swingup(self) -> None:
        """Refuse a swing-up when a pair touches anywhere it may go.

        Raises
        ------
        ContactError
            One sentence naming the first such pair, where it touches and the edit that keeps it clear.
        """
        for p in self.reachable:
            if p.classification == "at_equilibrium":
                raise _equilibrium_error(self.mjcf, p)
            where = f"MJCF '{self.mjcf}'" if self.mjcf else "The MJCF"
            raise ContactError(
                f"{where}: geoms '{p.geom1}' and '{p.geom2}' touch on the way up ({p.where}), not at upright; "
                f"{_fix(p, max(0.0, -p.min_clearance))}.")


def _fix(p: ContactPair, depth: float) -> str:
    """The edit that separates the pair, as the end of a sentence."""
    clear = depth + p.threshold
    if p.explicit:
        return f"remove their <pair> or move body '{p.body2}' {clear:.3g} m clear"
    return f"give '{p.geom1}' contype=\"0\" conaffinity=\"0\" or move body '{p.body2}' {clear:.3g} m clear"


# ---- the compiled model and its collision candidates ---------------------------------------------------------------
@functools.lru_cache(maxsize=16)
def _compiled(mjcf: str, xml: str):
    """The compiled model of a file (its path, so includes and meshes resolve) keyed also by the text read, so a file
    edited since is compiled again; the text itself when the file has moved since."""
    use_file = bool(mjcf) and (Path(mjcf).is_file() or not xml)
    return load_model(mjcf if use_file else None, xml=None if use_file else xml)[0]


def _mj(params: CartPoleParams):
    return _compiled(params.mjcf, params.xml)


def _gname(m, g: int) -> str:
    return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom {g}"


def _bname(m, b: int) -> str:
    return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or ("world" if b == 0 else f"body {b}")


def _jname(m, j: int) -> str:
    return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint {j}"


def contacts_enabled(m) -> bool:
    """True unless the compiled model ``m`` disables contacts (or every constraint)."""
    flags = mujoco.mjtDisableBit
    return not (int(m.opt.disableflags) & (flags.mjDSBL_CONTACT | flags.mjDSBL_CONSTRAINT))


def candidate_pairs(m) -> list:
    """Geom pairs MuJoCo's collision detection considers in the compiled model ``m``.

    Returns
    -------
    list of (g1, g2, margin, explicit)
        Geom ids, the pair's margin in m (the larger geom ``margin``, or the ``<pair>``'s) and whether it is an
        explicit ``<pair>``; empty when contacts are disabled. Filtered pairs: masks that do not match, bodies
        welded together (or both fixed to the world), a body and its parent (unless ``filterparent`` is
        disabled), ``<exclude>``.
    """
    if not contacts_enabled(m):
        return []
    out, seen = [], set()
    for i in range(m.npair):
        g1, g2 = int(m.pair_geom1[i]), int(m.pair_geom2[i])
        seen.add((min(g1, g2), max(g1, g2)))
        out.append((g1, g2, float(m.pair_margin[i]), True))
    filter_parent = not (int(m.opt.disableflags) & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    weld = m.body_weldid
    excluded = {int(s) for s in m.exclude_signature} if m.nexclude else set()
    for g1 in range(m.ngeom):
        for g2 in range(g1 + 1, m.ngeom):
            if (g1, g2) in seen:
                continue
            if not ((m.geom_contype[g1] & m.geom_conaffinity[g2]) or (m.geom_contype[g2] & m.geom_conaffinity[g1])):
                continue
            b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
            w1, w2 = int(weld[b1]), int(weld[b2])
            if w1 == w2:
                continue  # same rigid body, or both fixed to the world
            if filter_parent and w1 and w2 and (w1 == weld[m.body_parentid[w2]] or w2 == weld[m.body_parentid[w1]]):
                continue
            if ((min(b1, b2) << 16) + max(b1, b2)) in excluded:
                continue
            out.append((g1, g2, float(max(m.geom_margin[g1], m.geom_margin[g2])), False))
    return out


def _ancestor_joints(m, b: int) -> list:
    """Joint ids that move body ``b``, root first."""
    chain = []
    while b > 0:
        chain.extend(reversed(range(int(m.body_jntadr[b]), int(m.body_jntadr[b]) + int(m.body_jntnum[b]))))
        b = int(m.body_parentid[b])
    return chain[::-1]


class _Pair:
    """One candidate pair's search set-up: joints that move one geom relative to the other, their Lipschitz
    bounds (m of geom motion per unit of joint) and the box to search."""

    def __init__(self, m, d0, g1: int, g2: int, margin: float, explicit: bool, q_eq, lows, highs):
        if m.body_weldid[m.geom_bodyid[g2]] == 0 and m.body_weldid[m.geom_bodyid[g1]] != 0:
            g1, g2 = g2, g1  # geom1 the static one, geom2 the moving one
        self.g1, self.g2, self.explicit = g1, g2, explicit
        self.threshold = margin + CONTACT_MARGIN
        a1, a2 = _ancestor_joints(m, int(m.geom_bodyid[g1])), _ancestor_joints(m, int(m.geom_bodyid[g2]))
        L = {}
        for own in ((g1, a1, a2), (g2, a2, a1)):
            g, mine, theirs = own
            for k, j in enumerate(mine):
                if j in theirs:
                    continue
                L[j] = L.get(j, 0.0) + _lipschitz(m, d0, g, mine, k)
        self.joints = sorted(L)
        self.L = np.array([L[j] for j in self.joints])
        self.qadr = np.array([int(m.jnt_qposadr[j]) for j in self.joints], dtype=int)
        self.lo = np.array([lows[a] for a in self.qadr], float)
        self.hi = np.array([highs[a] for a in self.qadr], float)
        self.static_plane = (m.body_weldid[m.geom_bodyid[g1]] == 0 and m.geom_type[g1] == mujoco.mjtGeom.mjGEOM_PLANE)
        self._bound_slides(m, d0, q_eq)

    def _bound_slides(self, m, d0, q_eq) -> None:
        """Drop slides the pair's distance does not depend on (a world plane along the rail); make an unlimited
        slide's interval finite where the geometry bounds where contact can be."""
        keep = np.ones(len(self.joints), bool)
        for i, j in enumerate(self.joints):
            if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE:
                continue
            axis = d0.xaxis[j]
            if self.static_plane:
                normal = d0.geom_xmat[self.g1].reshape(3, 3)[:, 2]
                if abs(normal @ axis) < 1e-9:
                    keep[i] = False
                    continue
            if np.isfinite(self.lo[i]) and np.isfinite(self.hi[i]):
                continue
            others = [k for k in range(len(self.joints)) if k != i and m.jnt_type[self.joints[k]] != mujoco.mjtJoint.mjJNT_SLIDE]
            sweep = float(sum(self.L[k] * min(self.hi[k] - self.lo[k], 2 * np.pi) for k in others))
            rb = float(m.geom_rbound[self.g1] + m.geom_rbound[self.g2])
            if self.static_plane or rb == 0:
                span = UNLIMITED_SLIDE_SPAN
            else:
                span = float(np.linalg.norm(d0.geom_xpos[self.g1] - d0.geom_xpos[self.g2])) + rb + sweep \
                    + self.threshold + 1.0
            c = float(q_eq[self.qadr[i]])
            self.lo[i] = max(self.lo[i], c - span)
            self.hi[i] = min(self.hi[i], c + span)
        self.joints = [j for j, k in zip(self.joints, keep) if k]
        self.L, self.qadr, self.lo, self.hi = self.L[keep], self.qadr[keep], self.lo[keep], self.hi[keep]


def _lipschitz(m, d0, g: int, chain: list, k: int) -> float:
    """m that a point of geom ``g`` moves at most per unit of joint ``chain[k]`` (rad or m), whatever the other
    joints of ``chain`` are: 1 for a slide; for a hinge the rigid lengths from its axis down the chain to the geom's
    bounding sphere (inf for a moving plane, which has none)."""
    j = chain[k]
    if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
        return 1.0
    rb = float(m.geom_rbound[g])
    if rb <= 0:
        return math.inf
    length = 0.0
    for a, b in zip(chain[k:], chain[k + 1:]):
        length += float(np.linalg.norm(d0.xanchor[b] - d0.xanchor[a]))
        if m.jnt_type[b] == mujoco.mjtJoint.mjJNT_SLIDE:  # a slide below the hinge lengthens the arm by its stroke
            adr = int(m.jnt_qposadr[b])
            lo, hi = m.jnt_range[b] if m.jnt_limited[b] else (-math.inf, math.inf)
            length += max(abs(lo - m.qpos0[adr]), abs(hi - m.qpos0[adr]))
    return length + float(np.linalg.norm(d0.geom_xpos[g] - d0.xanchor[chain[-1]])) + rb


class _Distance:
    """``mj_geomDistance`` of one pair at configurations differing from ``q_eq`` in the pair's joints."""

    def __init__(self, m, q_eq):
        self.m, self.d = m, mujoco.MjData(m)
        self.q_eq = np.asarray(q_eq, float)
        self.calls = 0
        self._pair, self._adr = None, []
        self._kin, self._dist = mujoco.mj_kinematics, mujoco.mj_geomDistance

    def __call__(self, pair: _Pair, values) -> float:
        if pair is not self._pair:  # joints another pair moved go back to q_eq
            self.d.qpos[:] = self.q_eq
            self._pair, self._adr = pair, [int(a) for a in pair.qadr]
        qpos = self.d.qpos
        for a, v in zip(self._adr, values):
            qpos[a] = v
        self._kin(self.m, self.d)
        self.calls += 1
        return float(self._dist(self.m, self.d, pair.g1, pair.g2, 100.0, None))


def _search(pair: _Pair, dist: _Distance):
    """Best-first branch and bound of the pair's distance over its box.

    Returns ``(min found, its joint values, proven lower bound, finished)``.
    """
    n = len(pair.joints)
    if n == 0:
        v = dist(pair, np.zeros(0))
        return v, np.zeros(0), v, True
    L = [float(v) for v in pair.L]  # plain floats: the loop is Python-bound, small numpy arrays would dominate it
    center = [0.5 * (a + b) for a, b in zip(pair.lo, pair.hi)]
    half = [0.5 * (b - a) for a, b in zip(pair.lo, pair.hi)]

    def slack(h):
        return sum(l * w for l, w in zip(L, h) if w > 0)

    d = dist(pair, center)
    best, best_at = d, center
    heap = [(d - slack(half), 0, center, half)]
    counter = 1
    budget = dist.calls + MAX_EVALUATIONS
    deepen = None
    threshold = pair.threshold
    while heap:
        lb, _, c, h = heap[0]
        if lb >= threshold:
            return best, np.array(best_at), lb, True  # every box left is clear: the pair cannot touch
        if best < threshold:  # touching: a few more boxes, best first, to find a deeper witness, then stop
            deepen = dist.calls + DEEPEN_EVALUATIONS if deepen is None else deepen
            if dist.calls >= deepen or lb >= best:
                return best, np.array(best_at), lb, True
        if dist.calls >= budget:
            return best, np.array(best_at), lb, False
        heapq.heappop(heap)
        contrib = [l * w if w > 0 else 0.0 for l, w in zip(L, h)]
        i = max(range(n), key=contrib.__getitem__)
        if not contrib[i] > 0:  # a point: nothing left to split
            continue
        for sign in (-1.0, 1.0):
            c2, h2 = list(c), list(h)
            h2[i] = 0.5 * h[i]
            c2[i] = c[i] + sign * h2[i]
            d2 = dist(pair, c2)
            if d2 < best:
                best, best_at = d2, c2
            heapq.heappush(heap, (d2 - slack(h2), counter, c2, h2))
            counter += 1
    return best, np.array(best_at), best, True


def _descend(pair: _Pair, dist: _Distance, at: np.ndarray, value: float, step: float = 0.2, tol: float = 1e-3):
    """A pattern search from ``at`` (inside the pair's box) to a nearby smaller distance: each joint stepped both
    ways, the step halved when nothing improves, down to ``tol``. Returns ``(value, at)``."""
    at = np.array(at, float)
    scale = np.where(np.isfinite(pair.L) & (pair.L > 0), 1.0 / np.maximum(pair.L, 1e-9), 1.0)
    scale = scale / scale.max() if scale.size else scale
    while step > tol:
        moved = False
        for i in range(at.size):
            for sign in (-1.0, 1.0):
                trial = at.copy()
                trial[i] = min(max(at[i] + sign * step * scale[i], pair.lo[i]), pair.hi[i])
                v = dist(pair, trial)
                if v < value - 1e-12:
                    value, at, moved = v, trial, True
                    break
        if not moved:
            step *= 0.5
    return value, at


def _describe(m, pair: _Pair, dist: _Distance, at: np.ndarray, q_eq, q_hang) -> str:
    """Where the pair touches in words: the interval of one joint (the root-most hinge of the search, else the slide)
    around ``at`` in which the pair is closer than its threshold, the other joints held; found on a grid and refined
    by bisection."""
    if len(pair.joints) == 0:
        return "in every configuration"
    hinges = [i for i, j in enumerate(pair.joints) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    i = hinges[0] if hinges else 0
    j = pair.joints[i]
    lo, hi = pair.lo[i], pair.hi[i]
    turn = m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and hi - lo >= 2 * np.pi - 1e-9
    if turn:  # a full turn: scan it centred on the witness, so an interval across the box's seam stays whole
        lo, hi = at[i] - np.pi, at[i] + np.pi
    grid = np.linspace(lo, hi, 361)
    vals = at.copy()

    def f(x):
        vals[i] = x
        return dist(pair, vals) - pair.threshold

    inside = np.array([f(x) < 0 for x in grid])
    k = int(np.argmin(np.abs(grid - at[i])))
    if not inside[k]:
        inside[k] = True  # the witness itself touches; the grid point beside it may not
    a, b = k, k
    while a > 0 and inside[a - 1]:
        a -= 1
    while b < len(grid) - 1 and inside[b + 1]:
        b += 1

    def edge(out_x, in_x):
        for _ in range(30):
            mid = 0.5 * (out_x + in_x)
            if f(mid) < 0:
                in_x = mid
            else:
                out_x = mid
        return in_x

    left = grid[a] if a == 0 else edge(grid[a - 1], grid[a])
    right = grid[b] if b == len(grid) - 1 else edge(grid[b + 1], grid[b])
    name = _jname(m, j)
    others = [f"'{_jname(m, jj)}' at {round(float(at[ii]), 4) + 0.0:.3g} {'m' if m.jnt_type[jj] == mujoco.mjtJoint.mjJNT_SLIDE else 'rad'}"
              for ii, jj in enumerate(pair.joints) if ii != i]
    tail = f", {', '.join(others)}" if others else ""
    if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
        return f"slide '{name}' between {left:.3g} and {right:.3g} m{tail}"
    adr = int(pair.qadr[i])
    full = a == 0 and b == len(grid) - 1
    if full:
        return f"hinge '{name}' at any angle{tail}"
    ref, ref_name = (float(q_hang[adr]), "hanging") if q_hang is not None else (float(q_eq[adr]), "upright")
    if turn:  # the same angle one turn on: offsets from the reference's copy nearest the witness
        ref += 2 * np.pi * round((at[i] - ref) / (2 * np.pi))
    lo_off, hi_off = left - ref, right - ref
    if lo_off <= 0 <= hi_off and abs(lo_off + hi_off) < 1e-3 * max(1.0, hi_off - lo_off):
        return f"hinge '{name}' within {hi_off:.2f} rad of {ref_name}{tail}"
    return f"hinge '{name}' {lo_off:+.2f} to {hi_off:+.2f} rad from {ref_name}{tail}"


def _ranges(m, q_eq, cart_range, cart_adr):
    """Per-qpos search interval: a limited joint's range, an unlimited hinge a full turn around upright, an
    unlimited slide ``+-inf`` (bounded per pair); the cart's slide ``cart_range`` when given."""
    lows, highs = np.empty(m.nq), np.empty(m.nq)
    for j in range(m.njnt):
        a = int(m.jnt_qposadr[j])
        if m.jnt_limited[j]:
            lows[a], highs[a] = m.jnt_range[j]
        elif m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            lows[a], highs[a] = q_eq[a] - np.pi, q_eq[a] + np.pi
        else:
            lows[a], highs[a] = -np.inf, np.inf
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and highs[a] - lows[a] > 2 * np.pi:
            lows[a], highs[a] = q_eq[a] - np.pi, q_eq[a] + np.pi  # more than a turn adds nothing
    if cart_adr is not None and cart_range is not None:
        lows[cart_adr], highs[cart_adr] = cart_range
    return lows, highs


def contact_report(params: CartPoleParams, x_eq, *, x_hanging=None, cart_range=None) -> ContactReport:
    """Classify every geom pair MuJoCo may collide by whether it can touch (cached per compiled model and arguments).

    Parameters
    ----------
    params : CartPoleParams
        The model (its MJCF is compiled again, from its path or text).
    x_eq : (nx,) or (nq,) array
        The upright equilibrium (only ``qpos``, the first nq entries, is used); joints the search does not move
        stay there.
    x_hanging : (nx,) or (nq,) array, optional
        The hanging rest, the reference for the angles in ``where`` (default: upright is the reference).
    cart_range : (2,) array, optional
        m, the interval of the cart's slide to search (default the file's range; where unlimited, the geometry's
        own bound, else ``+-UNLIMITED_SLIDE_SPAN`` around ``x_eq``).

    Returns
    -------
    ContactReport
    """
    q_eq = tuple(float(v) for v in np.asarray(x_eq, float).ravel()[:params.nq])
    q_h = None if x_hanging is None else tuple(float(v) for v in np.asarray(x_hanging, float).ravel()[:params.nq])
    cr = None if cart_range is None else tuple(float(v) for v in cart_range)
    return _report(params.mjcf, params.xml, q_eq, q_h, cr)


@functools.lru_cache(maxsize=32)
def _report(mjcf: str, xml: str, q_eq: tuple, q_hang: tuple | None, cart_range: tuple | None) -> ContactReport:
    t0 = time.perf_counter()
    m = _compiled(mjcf, xml)
    slides = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE]
    cart_adr = int(m.jnt_qposadr[slides[0]]) if slides else None
    lows, highs = _ranges(m, np.asarray(q_eq), cart_range, cart_adr)
    searched = (float(lows[cart_adr]), float(highs[cart_adr])) if cart_adr is not None else (-math.inf, math.inf)
    enabled = contacts_enabled(m)
    d0 = mujoco.MjData(m)
    d0.qpos[:] = q_eq
    mujoco.mj_kinematics(m, d0)
    dist = _Distance(m, q_eq)
    normal = _motion_normal(m, d0)
    pairs = []
    for g1, g2, margin, explicit in candidate_pairs(m):
        pair = _Pair(m, d0, g1, g2, margin, explicit, q_eq, lows, highs)
        at_up = dist(pair, np.asarray(q_eq)[pair.qadr])
        gap = _plane_gap(m, d0, pair, normal)
        if gap >= pair.threshold:  # apart across the plane of motion in every configuration: no search needed
            best, best_at, bound, done = at_up, np.asarray(q_eq)[pair.qadr], gap, True
        else:
            best, best_at, bound, done = _search(pair, dist)
        if len(pair.joints):
            if q_hang is not None:  # hanging is where a floor is nearest: descend from there too
                seed = np.clip(np.asarray(q_hang)[pair.qadr], pair.lo, pair.hi)
                v = dist(pair, seed)
                if v < best:
                    best, best_at = v, seed
            best, best_at = _descend(pair, dist, best_at, best)
        q_best = np.array(q_eq)
        q_best[pair.qadr] = best_at
        if at_up < pair.threshold:
            cls = "at_equilibrium"
        elif best < pair.threshold:
            cls = "away_from_upright"
        else:
            cls = "never"
        where = None
        if cls == "at_equilibrium":
            where = "at the upright equilibrium"
        elif cls == "away_from_upright":
            where = _describe(m, pair, dist, np.asarray(best_at, float), q_eq, q_hang)
        pairs.append(ContactPair(
            geom1=_gname(m, pair.g1), geom2=_gname(m, pair.g2), body1=_bname(m, int(m.geom_bodyid[pair.g1])),
            body2=_root_body(m, pair.g2), classification=cls, min_clearance=float(min(best, at_up)),
            clearance_bound=float(min(bound, at_up)) if done else -math.inf, upright_clearance=float(at_up),
            qpos=None if cls == "never" else tuple(float(v) for v in (q_eq if cls == "at_equilibrium" else q_best)),
            where=where, joints=tuple(_jname(m, j) for j in pair.joints), explicit=explicit, certified=bool(done),
            threshold=pair.threshold, static1=bool(m.body_weldid[m.geom_bodyid[pair.g1]] == 0)))
    return ContactReport(mjcf=mjcf, enabled=enabled, margin=CONTACT_MARGIN, cart_range=searched, pairs=tuple(pairs),
                         seconds=time.perf_counter() - t0, evaluations=dist.calls)


def _motion_normal(m, d0):
    """The unit normal of the plane every point moves in, when the model is planar (every hinge axis parallel to it,
    every slide axis perpendicular), else None."""
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    if not hinges:
        return None
    n = np.asarray(d0.xaxis[hinges[0]], float)
    n = n / np.linalg.norm(n)
    for j in range(m.njnt):
        a = np.asarray(d0.xaxis[j], float)
        a = a / np.linalg.norm(a)
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and abs(abs(a @ n) - 1.0) > 1e-9:
            return None
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE and abs(a @ n) > 1e-9:
            return None
    return n


def _extent(m, d0, g: int, n) -> tuple:
    """The interval ``[lo, hi]`` (m) of ``x . n`` over geom ``g``'s points at the configuration of ``d0``; in a
    planar model with normal ``n`` it is the same in every configuration (rotations about ``n``, slides across it).
    ``(-inf, inf)`` for a plane not perpendicular to ``n`` and for types without a closed form (meshes, height
    fields, SDFs use their bounding sphere)."""
    G = mujoco.mjtGeom
    c = np.asarray(d0.geom_xpos[g], float) @ n
    R = np.asarray(d0.geom_xmat[g], float).reshape(3, 3)
    size = np.asarray(m.geom_size[g], float)
    local = R.T @ n  # n in the geom's frame
    t = int(m.geom_type[g])
    if t == G.mjGEOM_PLANE:
        if abs(abs(local[2]) - 1.0) > 1e-12:
            return -math.inf, math.inf
        return (-math.inf, c) if local[2] > 0 else (c, math.inf)  # the solid side is below the plane
    if t == G.mjGEOM_SPHERE:
        r = size[0]
    elif t == G.mjGEOM_CAPSULE:
        r = size[0] + size[1] * abs(local[2])
    elif t == G.mjGEOM_CYLINDER:
        r = size[1] * abs(local[2]) + size[0] * math.sqrt(max(0.0, 1.0 - local[2] ** 2))
    elif t == G.mjGEOM_BOX:
        r = float(np.abs(local) @ size)
    elif t == G.mjGEOM_ELLIPSOID:
        r = float(np.linalg.norm(size * local))
    else:
        r = float(m.geom_rbound[g]) if m.geom_rbound[g] > 0 else math.inf
    return c - r, c + r


def _plane_gap(m, d0, pair: "_Pair", normal) -> float:
    """m between the two geoms' extents across the plane of motion (``-inf`` when the model is not planar or they
    overlap there): a lower bound of their distance in every configuration."""
    if normal is None:
        return -math.inf
    lo1, hi1 = _extent(m, d0, pair.g1, normal)
    lo2, hi2 = _extent(m, d0, pair.g2, normal)
    return float(max(lo2 - hi1, lo1 - hi2))


def _root_body(m, g: int) -> str:
    """Name of the body to move to separate geom ``g`` from a static one: the root-most body with a joint above it
    (the cart), or its own body when it is fixed to the world."""
    b = int(m.geom_bodyid[g])
    root = b
    while b > 0:
        if m.body_jntnum[b]:
            root = b
        b = int(m.body_parentid[b])
    return _bname(m, root)


def check_equilibrium_contacts(params: CartPoleParams, x_eq) -> None:
    """Refuse an MJCF with a geom pair in contact at its upright equilibrium (one distance per candidate pair).

    Parameters
    ----------
    params : CartPoleParams
    x_eq : (nx,) or (nq,) array
        The upright equilibrium (its first nq entries are ``qpos``).

    Raises
    ------
    ContactError
        One sentence naming the pair, how deep they are in each other and the edit that separates them.
    """
    m = _mj(params)
    pairs = candidate_pairs(m)
    if not pairs:
        return
    q_eq = np.asarray(x_eq, float).ravel()[:params.nq]
    d = mujoco.MjData(m)
    d.qpos[:] = q_eq
    mujoco.mj_kinematics(m, d)
    for g1, g2, margin, explicit in pairs:
        dist = float(mujoco.mj_geomDistance(m, d, g1, g2, 100.0, None))
        if dist < margin + CONTACT_MARGIN:
            if m.body_weldid[m.geom_bodyid[g2]] == 0 and m.body_weldid[m.geom_bodyid[g1]] != 0:
                g1, g2 = g2, g1
            p = ContactPair(geom1=_gname(m, g1), geom2=_gname(m, g2), body1=_bname(m, int(m.geom_bodyid[g1])),
                            body2=_root_body(m, g2), classification="at_equilibrium", min_clearance=dist,
                            clearance_bound=dist, upright_clearance=dist, qpos=tuple(q_eq), where=None, joints=(),
                            explicit=explicit, certified=True, threshold=margin + CONTACT_MARGIN,
                            static1=bool(m.body_weldid[m.geom_bodyid[g1]] == 0))
            raise _equilibrium_error(params.mjcf, p)


def _equilibrium_error(mjcf: str, p: ContactPair) -> ContactError:
    """The one sentence for a pair in contact at the upright equilibrium."""
    where = f"MJCF '{mjcf}'" if mjcf else "The MJCF"
    depth = max(0.0, -p.upright_clearance)
    how = (f"{depth:.3g} m deep" if depth > 1e-6
           else f"{max(p.upright_clearance, 0.0):.2g} m apart, inside the {p.threshold:g} m margin")
    return ContactError(f"{where}: geoms '{p.geom1}' and '{p.geom2}' touch at the upright equilibrium ({how}) and the "
                        f"model has no contacts; {_fix(p, depth)}.")
