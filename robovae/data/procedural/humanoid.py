"""Humanoids (berkeley / h1 / g1 / t1 / n1 / talos / apollo / op3 / dm_control-like).

A pelvis carries two legs of 5-7 hinges: three hip hinges in a real order (``z x y`` as
h1/talos, ``y x z`` as g1/t1/n1, or ``x z y``) on short hip bodies, the thigh, a knee (y), an
ankle pitch (y) and usually an ankle roll (x), in that order or roll first (``ankle_order``),
with a flat box foot, rarely a toe hinge. With probability ``upper_body`` a waist of 0-3
hinges (``z``, ``z y``, ``z x y``) holds the torso (0: the torso is part of the pelvis); the
torso carries a neck of 0-3 hinges with a head and two arms of 3-7 hinges (``arm_axes``:
shoulder, then elbow and wrist); an arm long enough to hang beside the pelvis leans out so
that it clears the pelvis and hips. Arms with a wrist (5+ hinges) end in nothing, a gripper or
a hand of 3-5 fingers; both hands follow one drawn plan.

Real files compose these parts in a few ways (``layout``): the pelvis is the root and lists
the legs before the upper body (unitree, fourier) or after it (talos, apollo); or the torso is
the root, with the head and arms and then the waist chain that ends in the pelvis and legs
(booster t1, robotis op3) or the head, the waist chain and then the arms (dm_control and
gymnasium humanoids). The torso lists the head before the arms with probability
``head_first``. A robot whose file keeps fixed links as welded bodies (``welded_frames``, as
n1 and apollo) may carry welded sensor bodies on the pelvis and torso, a welded torso body
above the waist joint and a welded end-effector body on each arm.
"""

from __future__ import annotations

import math

from robovae.data.procedural.blueprint import Geom, Part, reroot
from robovae.data.procedural.parts import (
    AUTO,
    Hand,
    Link,
    build_hand,
    capsule,
    chain,
    flange,
    sample_fingers,
    sample_gripper,
    welded_boxes,
)
from robovae.data.procedural.sampler import G, Sampler

_WAIST_AXES = {0: "", 1: "z", 2: "zy", 3: "zxy"}


def _leg(s: Sampler, pelvis: Part, side: str, sy: float, anchor: tuple, p: dict) -> Part:
    """One leg (``p``: the lengths, masses and loads shared by both legs); returns its first
    body."""
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
    n_ankle = min(p["hinges"] - 4, 2)
    ankle = p["ankle_drop"]
    for k, ax in enumerate(p["ankle"] if n_ankle == 2 else "y"[:n_ankle]):
        vec = (0.0, 0.0, -ankle) if k + 1 < n_ankle else (0.0, 0.0, 0.0)
        links.append(([s.hinge(ax, (-0.6, 0.6), gear=0.6 * load)], vec, 0.5 * p["r"],
                      0.01 * M))
    first = len(pelvis.children)
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
    return pelvis.children[first]


def _lean(start: tuple[float, float], upper: float, fore_drop: float, clear: float) -> float:
    """How far (m) the upper arm leans out over its length ``upper``: 10 % of it, or more
    where the arm would hang through the pelvis and hips. ``start``: the upper arm's start,
    out from the middle and above the pelvis's top; ``fore_drop``: how far the forearm hangs
    below the elbow; ``clear``: how far out from the middle the arm clears the pelvis and the
    hips. The line from the start to the elbow crosses the pelvis's top at ``y ≥ clear``
    (capped at 45°)."""
    out, above = start
    lean = 0.1 * upper
    if upper + fore_drop <= above or out + lean >= clear:
        return lean  # the arm ends above the pelvis, or hangs clear of it already
    share = min(above / upper, 1.0)  # of the upper arm above the pelvis's top
    return upper if share <= 0 else min(max((clear - out) / share, lean), upper)


def _arm(s: Sampler, torso: Part, side: str, sy: float, anchor: tuple, p: dict) -> Part:
    """One arm of pattern ``p["arm"]`` (``<shoulder axes>-<elbow and wrist axes>``): short
    shoulder bodies, the last one spanning the upper arm, the elbow body spanning the forearm,
    short wrist bodies; then the welded end-effector body and the hand. Returns its first
    body."""
    shoulder, rest = p["arm"].split("-")
    M, scale = p["M"], p["scale"]
    g = 0.04 * scale
    ua, fa = p["upper_arm"], p["forearm"]
    d = (math.sin(p["elbow"]), 0.0, -math.cos(p["elbow"]))
    wrist = 0.03 * scale
    vecs = [(0.0, sy * g, 0.0), (0.0, 0.0, -g)][: len(shoulder) - 1]
    start = (anchor[1] * sy + (g if len(shoulder) > 1 else 0.0),  # upper arm's start:
             p["hip_top"] - (g if len(shoulder) > 2 else 0.0))  # out, above the pelvis top
    vecs += [(0.0, sy * _lean(start, ua, fa * abs(d[2]), p["hip_clear"]), -ua),
             (fa * d[0], 0.0, fa * d[2])]
    vecs += [(d[0] * wrist, 0.0, d[2] * wrist)] * (len(rest) - 1)
    masses = [0.012] * (len(shoulder) - 1) + [0.025, 0.015] + [0.004] * (len(rest) - 1)
    links: list[Link] = []
    for k, ax in enumerate(shoulder + rest):
        lim = (-p["shoulder"], p["shoulder"]) if k < len(shoulder) else "limit"
        links.append(([s.hinge(ax, lim, gear=AUTO)], vecs[k], 0.045 * scale * (1 - 0.08 * k),
                      masses[k] * M))
    first = len(torso.children)
    last, tip = chain(torso, f"{side}_arm", anchor, links)
    if p["end_effector"]:
        last, tip = flange(last, f"{side}_end_effector", tip, d, wrist, 0.02 * scale, 0.004 * M)
    if p["hand"] is not None:
        build_hand(s, last, f"{side}_", tip, d, p["hand"])
    return torso.children[first]


def _welded(s: Sampler, on: bool, prefix: str, places: list) -> tuple[list[Part], str]:
    """Welded sensor bodies of ``<prefix>_sensors`` at ``places`` and their slot
    ``<prefix>_slot`` (none unless ``on``)."""
    if not on:
        return [], ""
    n = int(s.pick(f"{prefix}_sensors"))
    parts = welded_boxes(s, n, f"{prefix}_", places)
    return parts, s.pick(f"{prefix}_slot") if n else ""


def _hand(s: Sampler, scale: float) -> Hand | None:
    kind = s.pick("hand")
    if kind == "gripper":
        return sample_gripper(s.section("arm"), 0.7 * scale)
    return sample_fingers(s, scale) if kind == "fingers" else None


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
         "foot": (s.u("foot_half_length"), s.u("foot_half_width"), s.u((0.01, 0.025))),
         "ankle": s.pick("ankle_order")}
    legs = [_leg(s, pelvis, side, sy, (0.0, sy * 0.7 * pw, -0.5 * rp), p)
            for side, sy in (("left", 1.0), ("right", -1.0))]
    welded = s.p("welded_frames")
    sens, slot = _welded(s, welded, "pelvis", [(-rp, 0.0, 0.0), (rp, 0.0, 0.0)])
    p_first, p_after, p_last = ([q for q in sens if slot == k]
                                for k in ("first", "after_legs", "last"))
    if not s.p("upper_body"):
        pelvis.children = p_first + legs + p_after + p_last
        return pelvis, True

    layout = s.pick("layout")
    height, tw = s.u("torso_height"), s.u("torso_half_width")
    holder = pelvis
    pos = (0.0, 0.0, rp)
    z = 0.0  # height of the torso's frame above the pelvis's
    for k, ax in enumerate(_WAIST_AXES[int(s.pick("waist_hinges"))]):
        holder = holder.add(Part(f"waist{k}", pos, [s.hinge(ax, (-0.8, 0.8), gear=AUTO)]))
        z += pos[2]
        pos = (0.0, 0.0, 0.03)
        holder.geoms.append(capsule((0.0, 0.0, 0.0), pos, 0.5 * tw, 0.02 * M))
    base = pos
    torso = holder
    if welded and s.p("torso_link"):  # a welded torso body above the waist joint (n1)
        torso = holder.add(Part("torso", pos))
        z += pos[2]
        base = (0.0, 0.0, 0.0)
    top = (base[0], base[1], base[2] + height)
    torso.geoms.append(capsule(base, top, 0.6 * tw, 0.3 * M))
    upper = [c for c in pelvis.children if c not in legs]  # the waist chain (or nothing)
    arms: list[Part] = []
    if s.p("arms"):
        p.update(arm=s.pick("arm_axes"), upper_arm=s.u("upper_arm"), forearm=s.u("forearm"),
                 elbow=s.u((0.0, 0.6)), shoulder=s.u("shoulder_limit"))
        wrist = len(p["arm"]) - 1 >= 5  # hinges: the pattern without its '-'
        p["hand"] = _hand(s, scale) if wrist else None
        p["end_effector"] = welded and s.p("end_effector")
        shoulder_z = top[2] - 0.1 * height
        ra = 0.045 * scale  # the arm's thickest radius, and a margin
        p["hip_top"] = z + shoulder_z - rp - ra  # the pelvis's top under the shoulder
        p["hip_clear"] = max(pw + rp, 0.7 * pw + 0.5 * p["gap"] + p["r"]) + 1.2 * ra
        arms = [_arm(s, torso, side, sy, (0.0, sy * tw, shoulder_z), p)
                for side, sy in (("left", 1.0), ("right", -1.0))]
    head: Part = torso
    neck_top = top
    neck = s.pick("neck_axes")
    for k, ax in enumerate(neck if neck != "none" else ""):
        head = head.add(Part(f"neck{k}", neck_top, [s.hinge(ax, (-1.0, 1.0), gear=AUTO)]))
        neck_top = (0.0, 0.0, 0.04 * scale)
        head.geoms.append(capsule((0.0, 0.0, 0.0), neck_top, 0.02 * scale, 0.01 * M))
    r = s.u("head_radius")
    head.geoms.append(Geom("sphere", 0.05 * M, r, pos=(0.0, 0.0, neck_top[2] + r)))
    heads = [c for c in torso.children if c.name == "neck0"]
    first_arms = not s.p("head_first")
    sens, slot = _welded(s, welded, "torso", [(0.6 * tw, 0.0, base[2] + 0.7 * height), top])
    t_first, t_last = ([q for q in sens if slot == k] for k in ("first", "last"))
    seq = [arms, heads] if first_arms else [heads, arms]

    if layout in ("legs_first", "upper_first"):  # the pelvis is the root
        ups = t_first + seq[0] + seq[1] + t_last
        if torso is not pelvis:
            torso.children = [c for c in torso.children if c not in heads + arms] + ups
            ups = upper
        lower = legs + p_after
        pelvis.children = p_first + (lower + ups if layout == "legs_first" else ups + lower) \
            + p_last
        return pelvis, True
    if torso is pelvis:  # one body holds legs, head and arms (op3)
        lower = legs + p_after
        t_first, t_last = p_first + t_first, t_last + p_last
    else:  # hang the pelvis from the torso through the flipped waist chain
        pelvis.children = p_first + legs + p_after + p_last + upper
        torso.children = [c for c in torso.children if c not in heads + arms]
        root = reroot(pelvis, torso)
        lower = [root.children.pop()]
        root.name = "torso"
    # torso_root: head and arms, then the legs (t1, op3); torso_root_mid: head, legs, arms
    # (dm_control / gymnasium humanoid)
    middle = [seq[0], seq[1], lower] if layout == "torso_root" else [seq[0], lower, seq[1]]
    torso.children = t_first + [q for group in middle for q in group] + t_last
    return torso, True
