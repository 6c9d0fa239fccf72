"""Radial-legged robots (ant-like): ``legs`` legs spread evenly around a round torso.

Each leg starts with a hip segment on a yaw hinge (z) reaching out horizontally, then 1-2
segments on hinges about the horizontal axis across the leg, going down ``leg_down`` below
horizontal to an optional foot sphere; all legs share one sampled template.
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Geom, Part
from robovae.data.procedural.parts import Link, chain
from robovae.data.procedural.sampler import G, Sampler


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a radial-legged robot and ``floating=True``."""
    n, segs = s.i("legs"), s.i("segments")
    radius = s.u("torso_radius")
    m_torso = s.u("torso_mass")
    torso = Part("torso", (0.0, 0.0, 0.0))
    torso.geoms.append(Geom("sphere", m_torso, radius, pos=(0.0, 0.0, 0.0)))
    hip = s.u("hip_length", max(1.0, radius / 0.15))
    lengths = [s.u("leg_length", max(1.0, radius / 0.15)) for _ in range(segs - 1)]
    downs = [s.u("leg_down") for _ in range(segs - 1)]
    drop = sum(ln * math.sin(d) for ln, d in zip(lengths, downs))
    if drop < radius + 0.03:  # the feet must reach below the torso
        lengths = [ln * (radius + 0.03) / drop for ln in lengths]
    r_seg = s.u("radius")
    m_seg = s.u("limb_mass", m_torso)
    foot = s.u("foot_radius")
    lim = s.u("limit")
    load = m_torso * 1.4 * G * (hip + sum(lengths)) / max(3, n - 1)
    phase = s.u((0.0, 2.0 * math.pi / n))
    for k in range(n):
        a = phase + 2.0 * math.pi * k / n
        u = (math.cos(a), math.sin(a), 0.0)
        axis = (-u[1], u[0], 0.0)
        links: list[Link] = [([s.hinge("z", (-lim, lim), gear=0.5 * load)],
                              (u[0] * hip, u[1] * hip, 0.0), r_seg, m_seg)]
        for ln, d in zip(lengths, downs):
            vec = (u[0] * ln * math.cos(d), u[1] * ln * math.cos(d), -ln * math.sin(d))
            links.append(([s.hinge(axis, (-lim, lim), gear=load)], vec, 0.8 * r_seg, m_seg))
        last, tip = chain(torso, f"leg{k}_", (u[0] * radius, u[1] * radius, 0.0), links)
        if foot > 0.01:
            last.geoms.append(Geom("sphere", 0.2 * m_seg, foot, pos=tip))
    return torso, True
