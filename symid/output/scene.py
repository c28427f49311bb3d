"""The mechanism drawn: where each body, joint, slot, gear and spring is at
each tabled instant (`scene`), and how one instant is drawn on an Axes.

Geometry comes from the table's q columns and the mechanism's points; every
line that carries results has a `gid` ("path:<body>:<n>", "pin:<constraint>").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from symid.backends import Array
from symid.model.mechanism import GROUND, Element, Mechanism
from symid.model.params import parameter_values, to_float
from symid.output.summary import Table
from symid.symbolic.constraints import TYPES as CONSTRAINTS
from symid.symbolic.forces import TYPES as FORCES

if TYPE_CHECKING:
    from matplotlib.axes import Axes

BLOCK = 0.09         # bodies smaller than this fraction of the drawing are drawn as blocks

# Where the traced paths come from: points where parts meet or loads act,
# not actuator or spring attachments (these would only add clutter).
TRACED = ("revolute", "revolute_revolute", "pin_in_slot", "translational", "point_force")
SLOTS = ("pin_in_slot", "translational")
GEARS = ("gear", "gear_on_link")


@dataclass
class Scene:
    """What to draw, in global coordinates [m]; every array has instants first.

    Attributes:
        outlines: body -> (instants, k, 2) closed outline through its points
            (k = 2: a bar); extent: body -> its largest size in the outline.
            A body smaller than `BLOCK` x size is drawn as a block.
        phi: body -> (instants,) angle, for blocks and gear ticks.
        anchors: ground pivots, (x, y) each.
        pins: constraint -> (instants, 2) revolute points.
        links: (name, Pi, Pj, kind) with kind "link" or "cylinder".
        slots: (name, start, end, on_ground), ends (instants, 2).
        gears: (body, centre (instants, 2), radius, phi (instants,)); body may be ground.
        springs: (name, Pi, Pj); torsion: (name, centre (instants, 2)).
        paths: (body, (instants, 2)) of the points that move.
        size: the drawing's extent, for symbol sizes.
    """

    names: list[str]
    outlines: dict[str, Array] = field(default_factory=dict)
    phi: dict[str, Array] = field(default_factory=dict)
    extent: dict[str, float] = field(default_factory=dict)
    gear_bodies: set[str] = field(default_factory=set)
    anchors: list[tuple[float, float]] = field(default_factory=list)
    pins: dict[str, Array] = field(default_factory=dict)
    links: list[tuple[str, Array, Array, str]] = field(default_factory=list)
    slots: list[tuple[str, Array, Array, bool]] = field(default_factory=list)
    gears: list[tuple[str, Array, float, Array]] = field(default_factory=list)
    springs: list[tuple[str, Array, Array]] = field(default_factory=list)
    torsion: list[tuple[str, Array]] = field(default_factory=list)
    paths: list[tuple[str, Array]] = field(default_factory=list)
    size: float = 1.0
    bounds: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)

    def color(self, body: str) -> str:
        return f"C{self.names.index(body) % 10}" if body in self.names else "0.45"


class _Geometry:
    """Global positions of body points over the run, from the table's q columns."""

    def __init__(self, mechanism: Mechanism, table: Table) -> None:
        self.values = parameter_values(mechanism.parameters)
        self.n = len(table["t"])
        self.q = {b.name: tuple(np.asarray(table[f"{b.name}.{c}"], dtype=float) for c in ("x", "y", "phi"))
                  for b in mechanism.bodies}

    def num(self, pair: Any) -> Array:
        return np.array([to_float(v, self.values) for v in pair])

    def point(self, body: str, s: Array) -> Array:
        """(instants, 2) global position of body point s."""
        if body == GROUND:
            return np.tile(s, (self.n, 1))
        x, y, phi = self.q[body]
        c, sn = np.cos(phi), np.sin(phi)
        return np.stack([x + c * s[0] - sn * s[1], y + sn * s[0] + c * s[1]], 1)

    def angle(self, body: str) -> Array:
        return np.zeros(self.n) if body == GROUND else self.q[body][2]


def _element_points(mechanism: Mechanism, geo: _Geometry) -> list[tuple[Element, str, str, Array]]:
    """(element, role, body, s) for every point where a constraint or force acts."""
    out = []
    for e in mechanism.constraints + mechanism.forces:
        family = CONSTRAINTS.get(e.type) or FORCES[e.type]
        for role, body in e.bodies.items():
            key = family.points.get(role)
            if isinstance(key, str):  # a point that moves on the body (a pitch point) is not drawn
                out.append((e, role, body, geo.num(e.values[key])))
    return out


def _hull(points: Array) -> Array:
    """Convex hull (counter-clockwise) of 2-D points; 1 or 2 points when degenerate."""
    pts = sorted({(round(float(x), 12), round(float(y), 12)) for x, y in points})
    if len(pts) <= 2:
        return np.array(pts)

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        chain: list[tuple[float, float]] = []
        for p in seq:
            while len(chain) >= 2 and ((chain[-1][0] - chain[-2][0]) * (p[1] - chain[-2][1])
                                       - (chain[-1][1] - chain[-2][1]) * (p[0] - chain[-2][0])) <= 0:
                chain.pop()
            chain.append(p)
        return chain

    return np.array(half(pts)[:-1] + half(pts[::-1])[:-1])  # collinear: the two extremes


def scene(table: Table, mechanism: Mechanism) -> Scene:
    """The mechanism's drawable geometry over the run (needs the q columns).

    Raises:
        ValueError: the table has no q columns.
    """
    if any(f"{b.name}.x" not in table.columns for b in mechanism.bodies):
        raise ValueError("the table has no q columns (positions) to draw the mechanism from")
    geo = _Geometry(mechanism, table)
    sc = Scene([b.name for b in mechanism.bodies])
    points = _element_points(mechanism, geo)

    # Body outlines through the centre of mass and every point on the body.
    for b in mechanism.bodies:
        local = np.array([[0.0, 0.0]] + [s for _, _, body, s in points if body == b.name])
        hull = _hull(local)
        sc.outlines[b.name] = np.stack([geo.point(b.name, p) for p in hull], 1)
        sc.phi[b.name] = geo.angle(b.name)
        sc.extent[b.name] = float(max(np.hypot(*(p - r)) for p in hull for r in hull))

    by_type: dict[str, list[Element]] = {}
    for c in mechanism.constraints:
        by_type.setdefault(c.type, []).append(c)

    def at(c: Element, role: str, key: str) -> Array:
        return geo.point(c.bodies[role], geo.num(c.values[key]))

    for c in by_type.get("revolute", []) + by_type.get("pin_in_slot", []):
        sc.pins[c.name] = at(c, "j", "sj")
    for kind, family in (("link", "revolute_revolute"), ("cylinder", "distance_driver")):
        for c in by_type.get(family, []):
            sc.links.append((c.name, at(c, "i", "si"), at(c, "j", "sj"), kind))
    for family in SLOTS:
        for c in by_type.get(family, []):
            sc.slots.append(_slot(c, geo))
    for family in GEARS:
        for c in by_type.get(family, []):
            sc.gears += _gears(c, mechanism, geo)
    sc.gear_bodies = {g[0] for g in sc.gears}
    for f in mechanism.forces:
        if f.type == "spring_damper":
            sc.springs.append((f.name, at(f, "i", "si"), at(f, "j", "sj")))
        elif f.type == "rotational_spring_damper":
            sc.torsion.append((f.name, _torsion_centre(f, by_type.get("revolute", []), geo)))

    # Ground pivots: ground points of everything but guides (drawn as slots).
    for e, role, body, s in points:
        if body == GROUND and e.type not in SLOTS + ("translational_driver",):
            if not any(np.allclose(s, a) for a in sc.anchors):
                sc.anchors.append((float(s[0]), float(s[1])))

    everything = [o.reshape(-1, 2) for o in sc.outlines.values()] + [np.array(sc.anchors).reshape(-1, 2)]
    everything += [p for p in sc.pins.values()] + [s for _, a, b, _ in sc.slots for s in (a, b)]
    everything += [c + sign * r for _, c, r, _ in sc.gears for sign in (-1, 1)]
    allpts = np.concatenate(everything)
    lo, hi = allpts.min(0), allpts.max(0)
    sc.size = float(max(hi - lo)) or 1.0
    pad = 0.08 * sc.size
    sc.bounds = (lo[0] - pad, hi[0] + pad, lo[1] - 1.6 * pad, hi[1] + pad)

    # Traced paths: each distinct moving point where something acts on a body.
    for e, role, body, s in points:
        if body == GROUND or e.type not in TRACED or (e.type in SLOTS and role == "i"):
            continue
        path = geo.point(body, s)
        if np.ptp(path, axis=0).max() < 1e-6 * sc.size:
            continue
        if any(np.allclose(path, other, atol=1e-9 * sc.size) for _, other in sc.paths):
            continue
        sc.paths.append((body, path))
    # A body that ends at its centre of mass (a pendulum on one hinge): trace that end too.
    for b in mechanism.bodies:
        ends = sc.outlines[b.name][0]
        centre = geo.point(b.name, np.zeros(2))
        if len(ends) > 1 and np.min(np.hypot(*(ends - centre[0]).T)) < 1e-9 * sc.size \
                and not any(np.allclose(centre, other, atol=1e-9 * sc.size) for _, other in sc.paths):
            sc.paths.append((b.name, centre))
    return sc


def _slot(c: Element, geo: _Geometry) -> tuple[str, Array, Array, bool]:
    """The slot line on body i, long enough for the pin's travel over the run."""
    si, vi, sj = (geo.num(c.values[k]) for k in ("si", "vi", "sj"))
    u = vi / np.linalg.norm(vi)
    pi, pj = geo.point(c.bodies["i"], si), geo.point(c.bodies["j"], sj)
    phi = geo.angle(c.bodies["i"])
    # Travel along the slot, measured in body i's frame.
    d = pj - pi
    cos, sin = np.cos(phi), np.sin(phi)
    along = (cos * d[:, 0] + sin * d[:, 1]) * u[0] + (cos * d[:, 1] - sin * d[:, 0]) * u[1]
    lo, hi = float(along.min()), float(along.max())
    margin = 0.15 * (hi - lo) + 0.05 * max(abs(lo), abs(hi), 1e-3)
    start = geo.point(c.bodies["i"], si + (lo - margin) * u)
    end = geo.point(c.bodies["i"], si + (hi + margin) * u)
    return c.name, start, end, c.bodies["i"] == GROUND


def _axis(body: str, other: str, mechanism: Mechanism, geo: _Geometry) -> Array | None:
    """The point of `body` where a revolute joins it to `other` (None: no such joint)."""
    for c in mechanism.constraints:
        if c.type == "revolute" and {c.bodies["i"], c.bodies["j"]} == {body, other}:
            role = "i" if c.bodies["i"] == body else "j"
            return geo.point(body, geo.num(c.values["s" + role]))
    return None


def _centre(body: str, carrier: str | None, mechanism: Mechanism, geo: _Geometry) -> Array | None:
    """Centre of a gear: its axis, the revolute that carries it (on the
    carrier, else on ground, else any revolute on it); its centre of mass
    only when no revolute holds it (a gear may be eccentric: its pitch circle
    turns about the axis, not about the centre of mass). A ground gear on a
    carrier is centred on the carrier's pivot on the ground (or the carrier's
    centre of mass)."""
    if body != GROUND:
        for other in (carrier, GROUND) if carrier is not None else (GROUND,):
            axis = _axis(body, other, mechanism, geo)
            if axis is not None:
                return axis
        for c in mechanism.constraints:
            if c.type == "revolute" and body in c.bodies.values():
                return _axis(body, c.bodies["j" if c.bodies["i"] == body else "i"], mechanism, geo)
        return geo.point(body, np.zeros(2))
    if carrier is None:
        return None
    axis = _axis(GROUND, carrier, mechanism, geo)
    return axis if axis is not None else geo.point(carrier, np.zeros(2))


def _gears(c: Element, mechanism: Mechanism, geo: _Geometry) -> list[tuple[str, Array, float, Array]]:
    """Pitch circles of a gear pair, from K and the centre distance:
    r_j = d / |1 - K|, r_i = |K| r_j (external K < 0, internal K > 0)."""
    k = to_float(c.values["K"], geo.values)
    carrier = c.bodies.get("k")
    ci, cj = (_centre(c.bodies[r], carrier, mechanism, geo) for r in ("i", "j"))
    if ci is None or cj is None or abs(1 - k) < 1e-12:
        return []
    d = float(np.hypot(*(cj[0] - ci[0])))
    if d <= 0:
        return []
    rj = d / abs(1 - k)
    return [(c.bodies["i"], ci, abs(k) * rj, geo.angle(c.bodies["i"])),
            (c.bodies["j"], cj, rj, geo.angle(c.bodies["j"]))]


def _torsion_centre(f: Element, revolutes: list[Element], geo: _Geometry) -> Array:
    """Where a torsion spring sits: the revolute between its two bodies, else body j's centre."""
    pair = {f.bodies["i"], f.bodies["j"]}
    for c in revolutes:
        if {c.bodies["i"], c.bodies["j"]} == pair:
            return geo.point(c.bodies["j"], geo.num(c.values["sj"]))
    return geo.point(f.bodies["j"], np.zeros(2))


def _zigzag(a: Array, b: Array, width: float, turns: int = 7) -> Array:
    """A spring's zigzag from a to b, shape (points, 2)."""
    d = b - a
    length = float(np.hypot(*d)) or 1.0
    u, n = d / length, np.array([-d[1], d[0]]) / length
    s = np.concatenate([[0.0, 0.15], 0.15 + 0.7 * (np.arange(2 * turns) + 0.5) / (2 * turns), [0.85, 1.0]])
    side = np.concatenate([[0, 0], np.where(np.arange(2 * turns) % 2 == 0, 1.0, -1.0), [0, 0]])
    return a + np.outer(s * length, u) + np.outer(side * width, n)


def draw_paths(ax: "Axes", sc: Scene) -> None:
    """Draw the traced paths of the moving points (dashed, in their body's colour)."""
    for n, (body, path) in enumerate(sc.paths):
        ax.plot(path[:, 0], path[:, 1], color=sc.color(body), lw=0.9, ls="--", alpha=0.55, zorder=1,
                gid=f"path:{body}:{n}")


def draw(ax: "Axes", sc: Scene, k: int) -> None:
    """Draw the mechanism at instant k on `ax` (paths apart: `draw_paths`)."""
    from matplotlib.patches import Circle, Polygon, Rectangle

    size = sc.size
    for x, y in sc.anchors:  # a ground pivot: a triangle on a hatched base
        h = 0.045 * size
        ax.add_patch(Polygon([(x, y), (x - 0.6 * h, y - h), (x + 0.6 * h, y - h)], closed=True,
                             facecolor="0.85", edgecolor="0.25", lw=1.0, zorder=2))
        ax.add_patch(Rectangle((x - 0.9 * h, y - 1.45 * h), 1.8 * h, 0.45 * h, facecolor="none",
                               edgecolor="0.35", hatch="////", lw=0.0, zorder=2))
        ax.plot([x - 0.9 * h, x + 0.9 * h], [y - h, y - h], color="0.25", lw=1.2, zorder=2)
    for name, start, end, on_ground in sc.slots:
        xs, ys = [start[k, 0], end[k, 0]], [start[k, 1], end[k, 1]]
        if on_ground:  # a guide fixed to the ground: hatched strip beside the channel
            u = (end[k] - start[k]) / (np.hypot(*(end[k] - start[k])) or 1.0)
            off = -np.array([-u[1], u[0]]) * 0.03 * size
            if off[1] > 0:
                off = -off
            ax.add_patch(Polygon([start[k] + off, end[k] + off, end[k] + 1.7 * off, start[k] + 1.7 * off],
                                 closed=True, facecolor="none", edgecolor="0.35", hatch="////", lw=0.0, zorder=2))
        ax.plot(xs, ys, color="0.35", lw=9, solid_capstyle="round", zorder=3)
        ax.plot(xs, ys, color="white", lw=5.5, solid_capstyle="round", zorder=3)
    for body, centre, radius, phi in sc.gears:
        c = centre[k]
        ground = body == GROUND
        ax.add_patch(Circle(tuple(c), radius, facecolor="none" if ground else sc.color(body),
                            alpha=1.0 if ground else 0.25, edgecolor="none", zorder=4))
        ax.add_patch(Circle(tuple(c), radius, facecolor="none", edgecolor="0.3" if ground else sc.color(body),
                            lw=3.0 if ground else 1.6, ls="-", zorder=4))
        if not ground:
            tip = c + radius * np.array([np.cos(phi[k]), np.sin(phi[k])])
            ax.plot([c[0], tip[0]], [c[1], tip[1]], color=sc.color(body), lw=1.6, zorder=4)
    for body, outline in sc.outlines.items():
        pts = outline[k]
        color = sc.color(body)
        z = 5 + 0.9 * (1 - min(sc.extent[body] / size, 1))  # smaller bodies on top of larger ones
        if sc.extent[body] < BLOCK * size:
            if body in sc.gear_bodies:
                continue
            half = max(0.045 * size, 0.6 * sc.extent[body])
            c, s = np.cos(sc.phi[body][k]), np.sin(sc.phi[body][k])
            corners = np.array([[-1.3, -1], [1.3, -1], [1.3, 1], [-1.3, 1]]) * half
            block = pts.mean(0) + corners @ np.array([[c, s], [-s, c]])
            ax.add_patch(Polygon(block, closed=True, facecolor=color, alpha=0.45, edgecolor=color, lw=2, zorder=z))
        elif len(pts) == 2:
            ax.plot(pts[:, 0], pts[:, 1], color=color, lw=7, solid_capstyle="round", alpha=0.85, zorder=z)
        else:
            ax.add_patch(Polygon(pts, closed=True, facecolor=color, alpha=0.35, edgecolor=color, lw=2,
                                 joinstyle="round", zorder=z))
    for name, pi, pj, kind in sc.links:
        a, b = pi[k], pj[k]
        if kind == "cylinder":
            u = (b - a) / (np.hypot(*(b - a)) or 1.0)
            shortest = float(np.min(np.hypot(*(pj - pi).T)))
            ax.plot([a[0] + 0.2 * shortest * u[0], b[0]], [a[1] + 0.2 * shortest * u[1], b[1]],
                    color="0.55", lw=2.5, solid_capstyle="round", zorder=6)
            barrel = a + 0.6 * shortest * u
            ax.plot([a[0], barrel[0]], [a[1], barrel[1]], color="0.2", lw=7, solid_capstyle="butt", zorder=6)
        else:
            ax.plot([a[0], b[0]], [a[1], b[1]], color="0.3", lw=3, solid_capstyle="round", zorder=6)
        ax.plot([a[0], b[0]], [a[1], b[1]], ls="none", marker="o", ms=5, mfc="white", mec="0.1", zorder=8)
    for name, pi, pj in sc.springs:
        zigzag = _zigzag(pi[k], pj[k], 0.02 * size)  # not `z`: that is a float zorder above
        ax.plot(zigzag[:, 0], zigzag[:, 1], color="0.15", lw=1.1, zorder=7, gid=f"spring:{name}")
    for name, centre in sc.torsion:
        turn = np.linspace(0, 4 * np.pi, 120)
        r = 0.012 * size + 0.035 * size * turn / turn[-1]
        ax.plot(centre[k, 0] + r * np.cos(turn), centre[k, 1] + r * np.sin(turn), color="0.15", lw=0.9, zorder=7)
    for name, p in sc.pins.items():
        ax.plot([p[k, 0]], [p[k, 1]], ls="none", marker="o", ms=6, mfc="white", mec="0.1", mew=1.3, zorder=9,
                gid=f"pin:{name}")
    from matplotlib.ticker import MaxNLocator

    ax.set_xlim(sc.bounds[0], sc.bounds[1])
    ax.set_ylim(sc.bounds[2], sc.bounds[3])
    ax.set_aspect("equal")
    ax.xaxis.set_major_locator(MaxNLocator(6))
    ax.yaxis.set_major_locator(MaxNLocator(6))
