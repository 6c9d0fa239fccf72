"""Cassie-like bipeds: digitigrade legs with passive springs and rods.

A pelvis (free joint) carries two legs. The main chain has 5-7 hinges: hip roll (x), hip yaw
(z), hip pitch (y) with the thigh leaning forward, the knee (y) with the shin leaning back,
optionally a shin spring (passive hinge with ``spring_stiffness``) and a tarsus (passive hinge)
bringing the leg forward again, and the foot (y) with a flat capsule foot under the hip. Side
branches (``rods``, in this order) hang off the chain as in Cassie: an achilles rod on a ball
joint (hip pitch body), a knee spring (welded, knee body), a heel spring (passive hinge with
stiffness), a foot crank (motor-less hinge) and a plantar rod on the crank. With probability
``rods_first`` each rod comes before the chain's next body among its parent's children, as in
Agility's Cassie model, else after it.
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Joint, Part
from robovae.data.procedural.parts import capsule
from robovae.data.procedural.sampler import G, Sampler


def _rod(parent: Part, name: str, joints: list[Joint], vec: tuple, mass: float) -> Part:
    part = parent.add(Part(name, (0.0, 0.0, 0.0), joints))
    part.geoms.append(capsule((0.0, 0.0, 0.0), vec, 0.012, mass))
    return part


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a Cassie-like biped and ``floating=True``."""
    M = s.u("mass")
    pw = s.u("pelvis_half_width")
    pelvis = Part("pelvis", (0.0, 0.0, 0.0))
    pelvis.geoms.append(capsule((0.0, -pw, 0.0), (0.0, pw, 0.0), 0.6 * pw, 0.3 * M))
    thigh, shin, tarsus = s.u("thigh"), s.u("shin"), s.u("tarsus")
    fl = s.u("foot_half_length")
    n_main, n_rods = s.i("main_hinges"), s.i("rods")
    has_shin = n_main >= 6
    has_tarsus = n_main >= 7 or (n_main == 6 and s.rng.random() < 0.5)
    if n_main == 6 and has_tarsus:
        has_shin = False
    a, b = s.u((0.3, 0.7)), s.u((0.3, 0.7))
    t_vec = (thigh * math.sin(a), 0.0, -thigh * math.cos(a))
    s_vec = (-shin * math.sin(b), 0.0, -shin * math.cos(b))
    if not has_tarsus:  # the shin alone brings the foot back under the hip
        dx = -t_vec[0]
        s_vec = (dx, 0.0, -math.sqrt(max(shin ** 2 - dx ** 2, 0.25 * shin ** 2)))
    dx = -(t_vec[0] + s_vec[0])
    ta_vec = (dx, 0.0, -math.sqrt(max(tarsus ** 2 - dx ** 2, 0.25 * tarsus ** 2)))
    load = 0.5 * M * G * 0.5 * (thigh + shin)
    stiff = s.u("spring_stiffness")
    made: list[Part] = []
    for side, sy in (("left", 1.0), ("right", -1.0)):
        roll = pelvis.add(Part(f"{side}_hip_roll", (0.0, sy * pw, 0.0),
                               [s.hinge("x", "limit", gear=load)]))
        roll.geoms.append(capsule((0.0, 0.0, 0.0), (0.0, 0.0, -0.06), 0.04, 0.05 * M))
        yaw = roll.add(Part(f"{side}_hip_yaw", (0.0, 0.0, -0.06),
                            [s.hinge("z", "limit", gear=load)]))
        yaw.geoms.append(capsule((0.0, 0.0, 0.0), (0.0, 0.0, -0.06), 0.04, 0.04 * M))
        pitch = yaw.add(Part(f"{side}_hip_pitch", (0.0, 0.0, -0.06),
                             [s.hinge("y", "limit", gear=load)]))
        pitch.geoms.append(capsule((0.0, 0.0, 0.0), t_vec, 0.04, 0.15 * M))
        knee = pitch.add(Part(f"{side}_knee", t_vec, [s.hinge("y", "limit", gear=1.5 * load)]))
        lower = knee
        if has_shin:
            knee.geoms.append(capsule((0.0, 0.0, 0.0), (0.0, 0.0, -0.05), 0.03, 0.02 * M))
            lower = knee.add(Part(f"{side}_shin", (0.0, 0.0, -0.05),
                                  [s.hinge("y", (-0.1, 0.1), stiffness=stiff)]))
            sv = (s_vec[0], 0.0, s_vec[2] + 0.05)
        else:
            sv = s_vec
        lower.geoms.append(capsule((0.0, 0.0, 0.0), sv, 0.025, 0.04 * M))
        foot_parent, foot_pos = lower, sv
        if has_tarsus:
            foot_parent = lower.add(Part(f"{side}_tarsus", sv,
                                         [s.hinge("y", "limit", stiffness=0.1 * stiff)]))
            foot_parent.geoms.append(capsule((0.0, 0.0, 0.0), ta_vec, 0.02, 0.025 * M))
            foot_pos = ta_vec
        foot = foot_parent.add(Part(f"{side}_foot", foot_pos,
                                    [s.hinge("y", "limit", gear=0.3 * load)]))
        foot.geoms.append(capsule((-0.4 * fl, 0.0, -0.02), (fl, 0.0, -0.02), 0.02, 0.01 * M))
        if n_rods >= 1:
            made.append(_rod(pitch, f"{side}_achilles",
                             [Joint("ball", (0.0, 0.0, 1.0), None, 0.1, 0.0)],
                             (-0.05, 0.0, -0.8 * thigh), 0.005 * M))
        if n_rods >= 2:
            made.append(_rod(knee, f"{side}_knee_spring", [], (0.05, 0.0, -0.05), 0.005 * M))
        if n_rods >= 3:
            made.append(_rod(foot_parent, f"{side}_heel_spring",
                             [s.hinge("y", (-0.1, 0.1), stiffness=stiff)], (-0.05, 0.0, 0.03),
                             0.004 * M))
        if n_rods >= 4:
            crank = _rod(foot_parent, f"{side}_foot_crank", [s.hinge("y", "limit")],
                         (0.05, 0.0, -0.03), 0.004 * M)
            made.append(crank)
            if n_rods >= 5:
                plantar = crank.add(Part(f"{side}_plantar_rod", (0.05, 0.0, -0.03),
                                         [s.hinge("y", "limit")]))
                plantar.geoms.append(capsule((0.0, 0.0, 0.0), (0.1, 0.0, -0.1), 0.01,
                                             0.004 * M))
    if made and s.p("rods_first"):  # each rod before the next body of the chain (cassie)
        rods = {id(r) for r in made}
        for part, _ in pelvis.walk():
            part.children.sort(key=lambda c: id(c) not in rods)
    return pelvis, True
