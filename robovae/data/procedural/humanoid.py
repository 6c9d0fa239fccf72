"""Humanoids (berkeley / h1 / g1 / t1 / n1 / talos-like).

A pelvis (free joint) carries two legs of 5-7 hinges: three hip hinges in a real order
(``z x y`` as h1/talos, ``y x z`` as g1/t1/n1, or ``x z y``) on short hip bodies, the thigh, a
knee (y), an ankle pitch (y), usually an ankle roll (x) with a flat box foot, rarely a toe
hinge. With probability ``upper_body`` a waist of 0-3 hinges (``z``, ``z y``, ``z x y``) holds
the torso (0: the torso is part of the pelvis); the torso carries two arms of 4-7 hinges
(shoulder ``y x z``, elbow ``y``, wrist ``x``/``y``/``z``) ending in nothing, a parallel
gripper or a hand of 2-5 fingers with 1-3 hinges each, a neck of 0-2 hinges with a head, and
0-2 welded sensor bodies (n1).
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Geom, Part
from robovae.data.procedural.parts import (
    AUTO,
    Link,
    capsule,
    chain,
    finger_hand,
    gripper,
    sensors,
)
from robovae.data.procedural.sampler import G, Sampler

_ARM_AXES = {4: "yxzy", 5: "yxzyx", 6: "yxzyxy", 7: "yxzyzxy"}
_WAIST_AXES = {0: "", 1: "z", 2: "zy", 3: "zxy"}


def _leg(s: Sampler, pelvis: Part, side: str, sy: float, anchor: tuple, p: dict) -> None:
    """One leg (``p``: the lengths, masses and loads shared by both legs)."""
    gap, thigh, shin, bend, M, load = (p[k] for k in ("gap", "thigh", "shin", "bend", "M",
                                                        "load"))
    hip_vecs = [(0.0, sy * 0.5 * gap, -0.5 * gap), (0.0, 0.0, -gap)]
    t_vec = (thigh * math.sin(bend), 0.0, -thigh * math.cos(bend))
    dx = t_vec[0]
    s_vec = (-dx, 0.0, -math.sqrt(shin ** 2 - dx ** 2))
    links: list[Link] = []
    for k, ax in enumerate(p["hip_order"]):
        vec = hip_vecs[k] if k < 2 else t_vec
        links.append(([s.hinge(ax, p["hip_limits"][k], gear=load)], vec, p["r"],
                      0.025 * M if k < 2 else 0.08 * M))
    links.append(([s.hinge("y", ((-0.2, -0.05), (1.8, 2.5)), gear=1.5 * load)], s_vec,
                  0.8 * p["r"], 0.04 * M))
    n_ankle = p["hinges"] - 4
    ankle = p["ankle_drop"]
    for k, ax in enumerate("yx"[:min(n_ankle, 2)]):
        vec = (0.0, 0.0, -ankle) if k + 1 < min(n_ankle, 2) else (0.0, 0.0, 0.0)
        links.append(([s.hinge(ax, (-0.6, 0.6), gear=0.6 * load)], vec, 0.5 * p["r"],
                      0.01 * M))
    last, tip = chain(pelvis, f"{side}_leg", anchor, links)
    fl, fw, fh = p["foot"]
    if p["hinges"] == 7:  # a toe hinge splits the foot
        last.geoms.append(Geom("box", 0.012 * M, pos=(0.0, 0.0, -fh), half=(0.6 * fl, fw, fh)))
        toe = last.add(Part(f"{side}_toe", (0.6 * fl, 0.0, 0.0),
                            [s.hinge("y", (-0.5, 0.5), gear=0.2 * load)]))
        toe.geoms.append(Geom("box", 0.004 * M, pos=(0.4 * fl, 0.0, -fh),
                              half=(0.4 * fl, fw, fh)))
    else:
        last.geoms.append(Geom("box", 0.015 * M, pos=(0.3 * fl, 0.0, -fh), half=(fl, fw, fh)))


def _arm(s: Sampler, torso: Part, side: str, sy: float, anchor: tuple, p: dict) -> None:
    n, M = p["arm_hinges"], p["M"]
    g = 0.04 * p["scale"]
    ua, fa = p["upper_arm"], p["forearm"]
    vecs = [(0.0, sy * g, 0.0), (0.0, 0.0, -g), (0.0, sy * 0.1 * ua, -ua),
            (fa * math.sin(p["elbow"]), 0.0, -fa * math.cos(p["elbow"]))]
    d = (math.sin(p["elbow"]), 0.0, -math.cos(p["elbow"]))
    wrist = 0.03 * p["scale"]
    vecs += [(d[0] * wrist, 0.0, d[2] * wrist)] * (n - 4)
    masses = [0.012, 0.012, 0.025, 0.015] + [0.004] * (n - 4)
    links: list[Link] = []
    for k, ax in enumerate(_ARM_AXES[n]):
        lim = (-p["shoulder"], p["shoulder"]) if k < 3 else "limit"
        links.append(([s.hinge(ax, lim, gear=AUTO)], vecs[k], 0.045 * p["scale"] * (1 - 0.08 * k),
                      masses[k] * M))
    last, tip = chain(torso, f"{side}_arm", anchor, links)
    if p["hand"] == "gripper":
        arm = s.section("arm")
        gripper(arm, last, f"{side}_", tip, d, 0.7 * p["scale"], arm.p("hinge_fingers"))
    elif p["hand"] == "fingers":
        finger_hand(s, last, f"{side}_", tip, d, p["scale"])


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a humanoid and ``floating=True``."""
    M = s.u("mass")
    scale = (M / 40.0) ** (1.0 / 3.0)
    pw = s.u("pelvis_half_width")
    rp = 0.45 * pw
    pelvis = Part("pelvis", (0.0, 0.0, 0.0))
    pelvis.geoms.append(capsule((0.0, -pw, 0.0), (0.0, pw, 0.0), rp, 0.12 * M))
    thigh = s.u("thigh")
    hinges = int(s.pick("leg_hinges"))
    hip_lim = [(-s.u("limit"), s.u("limit")) for _ in range(3)]
    p = {"M": M, "scale": scale, "gap": s.u("hip_gap"), "thigh": thigh,
         "shin": s.u("shin_ratio", thigh), "bend": s.u("knee_bend"), "hinges": hinges,
         "hip_order": s.pick("hip_order"), "hip_limits": hip_lim, "r": max(0.02, 0.12 * thigh),
         "ankle_drop": s.u((0.0, 0.04)), "load": 0.5 * M * G * 0.5 * thigh,
         "foot": (s.u("foot_half_length"), s.u("foot_half_width"), s.u((0.01, 0.025)))}
    for side, sy in (("left", 1.0), ("right", -1.0)):
        _leg(s, pelvis, side, sy, (0.0, sy * 0.7 * pw, -0.5 * rp), p)
    if not s.p("upper_body"):
        return pelvis, True
    height, tw = s.u("torso_height"), s.u("torso_half_width")
    torso = pelvis
    pos = (0.0, 0.0, rp)
    for k, ax in enumerate(_WAIST_AXES[int(s.pick("waist_hinges"))]):
        torso = torso.add(Part(f"waist{k}", pos, [s.hinge(ax, (-0.8, 0.8), gear=AUTO)]))
        pos = (0.0, 0.0, 0.03)
        torso.geoms.append(capsule((0.0, 0.0, 0.0), pos, 0.5 * tw, 0.02 * M))
    base = pos if torso is not pelvis else (0.0, 0.0, rp)
    top = (base[0], base[1], base[2] + height)
    torso.geoms.append(capsule(base, top, 0.6 * tw, 0.3 * M))
    if s.p("arms"):
        p.update(arm_hinges=int(s.pick("arm_hinges")), upper_arm=s.u("upper_arm"),
                 forearm=s.u("forearm"), elbow=s.u((0.0, 0.6)), hand=s.pick("hand"),
                 shoulder=s.u("shoulder_limit"))
        for side, sy in (("left", 1.0), ("right", -1.0)):
            _arm(s, torso, side, sy, (0.0, sy * tw, top[2] - 0.1 * height), p)
    head: Part = torso
    neck_top = top
    for k, ax in enumerate("zy"[: int(s.pick("neck_hinges"))]):
        head = head.add(Part(f"neck{k}", neck_top, [s.hinge(ax, (-1.0, 1.0), gear=AUTO)]))
        neck_top = (0.0, 0.0, 0.04 * scale)
        head.geoms.append(capsule((0.0, 0.0, 0.0), neck_top, 0.02 * scale, 0.01 * M))
    sensors(s, torso, "", (0.6 * tw, 0.6 * tw, top[2]))
    r = s.u("head_radius")
    head.geoms.append(Geom("sphere", 0.05 * M, r, pos=(0.0, 0.0, neck_top[2] + r)))
    return pelvis, True
