"""Hexapods: a flat torso and six legs in side pairs, each coxa (yaw), femur and tibia.

The coxa hinge (z) turns the leg about the vertical; femur and tibia hinge about the
horizontal axis across the leg. The femur rises ``femur_up`` above horizontal, the tibia comes
down to a foot sphere below the torso; front and rear legs are splayed forward and back.
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Geom, Part
from robovae.data.procedural.parts import capsule, unit
from robovae.data.procedural.sampler import G, Sampler


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a hexapod and ``floating=True``."""
    lx, wy, hz = s.u("torso_half_length"), s.u("torso_half_width"), s.u("torso_half_height")
    m_torso = s.u("torso_mass")
    torso = Part("torso", (0.0, 0.0, 0.0))
    torso.geoms.append(Geom("box", m_torso, pos=(0.0, 0.0, 0.0), half=(lx, wy, hz)))
    coxa, femur, tibia = s.u("coxa"), s.u("femur"), s.u("tibia")
    up, out, splay = s.u("femur_up"), s.u("tibia_out"), s.u("splay")
    tibia = max(tibia, (femur * math.sin(up) + hz + 0.02) / math.cos(out))
    m_seg = s.u("limb_mass", m_torso)
    foot = s.u("foot_radius")
    radius = max(0.006, 0.1 * femur)
    lim = s.u("limit")
    load = m_torso * 1.4 * G * (coxa + femur) / 3.0
    for row, fx in (("F", 1), ("M", 0), ("R", -1)):
        for side, sy in (("L", 1.0), ("R", -1.0)):
            name = f"{row}{side}"
            u = unit((math.sin(splay) * fx, sy * math.cos(splay * abs(fx)), 0.0))
            axis = (-u[1], u[0], 0.0)
            c = torso.add(Part(f"{name}_coxa", (0.8 * lx * fx, sy * wy, 0.0),
                               [s.hinge("z", (-lim, lim), gear=0.5 * load)]))
            c_vec = (u[0] * coxa, u[1] * coxa, 0.0)
            c.geoms.append(capsule((0.0, 0.0, 0.0), c_vec, radius, m_seg))
            f_vec = (u[0] * femur * math.cos(up), u[1] * femur * math.cos(up),
                     femur * math.sin(up))
            f = c.add(Part(f"{name}_femur", c_vec, [s.hinge(axis, (-lim, lim), gear=load)]))
            f.geoms.append(capsule((0.0, 0.0, 0.0), f_vec, radius, m_seg))
            t_vec = (u[0] * tibia * math.sin(out), u[1] * tibia * math.sin(out),
                     -tibia * math.cos(out))
            t = f.add(Part(f"{name}_tibia", f_vec, [s.hinge(axis, (-lim, lim), gear=load)]))
            t.geoms.append(capsule((0.0, 0.0, 0.0), t_vec, min(0.7 * radius, foot / 1.5),
                                   0.7 * m_seg))
            t.geoms.append(Geom("sphere", 0.1 * m_seg, foot, pos=t_vec))
    return torso, True
