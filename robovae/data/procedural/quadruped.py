"""Quadrupeds (go1/go2/a1/spot/barkour-like): a box torso and four legs of three hinges each.

Each leg: a hip body on an abduction hinge (x) whose capsule reaches sideways to the thigh
axis, a thigh on a flexion hinge (y) tilted ``thigh_tilt`` from vertical, a calf on a knee
hinge (y) that brings the foot sphere back under the hip; the foot is at least 1.5 times as
thick as the calf, so it is the lowest point. Knees point back, front, inward
(front back, rear front: the tilt is capped so that the front and rear thighs do not cross
under the torso) or outward. The tree is the 26-node quadruped of real robots: free
joint, torso, 4 × (3 hinges + 3 bodies), and with probability 0.2 one or two welded sensor
bodies on the torso, listed before the legs (barkour_vb) or after them (``sensor_slot``).
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Geom, Part
from robovae.data.procedural.parts import capsule, sensors
from robovae.data.procedural.sampler import G, Sampler


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a quadruped and ``floating=True``."""
    lx, wy, hz = s.u("torso_half_length"), s.u("torso_half_width"), s.u("torso_half_height")
    m_torso = s.u("torso_density") * 8.0 * lx * wy * hz
    torso = Part("torso", (0.0, 0.0, 0.0))
    torso.geoms.append(Geom("box", m_torso, pos=(0.0, 0.0, 0.0), half=(lx, wy, hz)))
    offset = s.u("hip_offset")
    thigh = s.u("thigh_ratio", lx)
    calf = s.u("calf_ratio", thigh)
    tilt = s.u("thigh_tilt")
    knees = s.pick("knees")
    masses = (s.u("hip_mass", m_torso), s.u("thigh_mass", m_torso), s.u("calf_mass", m_torso))
    foot = s.u("foot_radius")
    radius = max(0.012, 0.12 * thigh)
    ab = s.u("abduction")
    flex = (s.u("flexion_low"), s.u("flexion_high"))
    knee = (s.u("knee_low"), s.u("knee_high"))
    total = m_torso + 4 * (sum(masses) + 0.1 * masses[2])
    load = 0.25 * total * G * (thigh + calf)  # a quarter of the weight at a leg's length
    x_hip = 0.85 * lx
    if knees == "inward":  # front and rear knees meet under the torso: keep them apart
        reach = max(x_hip - 1.25 * 0.8 * radius, 0.0) / thigh
        tilt = min(tilt, math.asin(min(reach, 1.0)))
    for name, fx, sy in (("FL", 1, 1), ("FR", 1, -1), ("RL", -1, 1), ("RR", -1, -1)):
        kd = {"back": 1.0, "front": -1.0, "inward": float(fx), "outward": float(-fx)}[knees]
        hip = torso.add(Part(f"{name}_hip", (fx * x_hip, sy * wy, 0.0),
                             [s.hinge("x", (-ab, ab), gear=0.5 * load)]))
        hip.geoms.append(capsule((0.0, 0.0, 0.0), (0.0, sy * offset, 0.0), radius, masses[0]))
        th = hip.add(Part(f"{name}_thigh", (0.0, sy * offset, 0.0),
                          [s.hinge("y", flex, gear=load)]))
        t_vec = (-kd * thigh * math.sin(tilt), 0.0, -thigh * math.cos(tilt))
        th.geoms.append(capsule((0.0, 0.0, 0.0), t_vec, 0.8 * radius, masses[1]))
        dx = -t_vec[0]
        c_vec = (dx, 0.0, -math.sqrt(max(calf ** 2 - dx ** 2, 0.25 * calf ** 2)))
        cf = th.add(Part(f"{name}_calf", t_vec, [s.hinge("y", knee, gear=1.5 * load)]))
        cf.geoms.append(capsule((0.0, 0.0, 0.0), c_vec, min(0.5 * radius, foot / 1.5), masses[2]))
        cf.geoms.append(Geom("sphere", 0.1 * masses[2], foot, pos=c_vec))
    sensors(s, torso, "", (lx, wy, hz))
    return torso, True
