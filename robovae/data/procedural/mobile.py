"""Mobile manipulators (tiago / tiago_dual-like): a wheeled base, a torso, a head, 1-2 arms.

The base box floats (free joint) on 2 drive wheels plus 2 or 4 casters (a swivel hinge and a
caster-wheel hinge each) or on 4 wheels; wheels may hang on suspension slides. A column rises
from the base on a lift slide (else welded); on top sit a head on 0-2 hinges (pan z, tilt y)
and one arm reaching forward or two mirrored arms reaching from the sides (one
:func:`~robovae.data.procedural.arm.sample_arm` plan, ``arm_hinges`` hinges), with grippers;
the head comes before the arms with probability ``head_first`` (tiago, tiago_dual). Wheel and
caster hinges are unlimited.
"""

from __future__ import annotations

from robovae.data.procedural.arm import build_arm, sample_arm
from robovae.data.procedural.blueprint import Geom, Joint, Part
from robovae.data.procedural.parts import AUTO, capsule, wheel
from robovae.data.procedural.sampler import G, Sampler


def _free(s: Sampler, axis: tuple[float, float, float], gear: float = 0.0) -> Joint:
    return s.hinge(axis, None, gear=gear)


def sample(s: Sampler) -> tuple[Part, bool]:
    """The root part of a mobile manipulator and ``floating=True``."""
    lx, wy, hz = s.u("base_half_length"), s.u("base_half_width"), s.u("base_half_height")
    m_base = s.u("base_mass")
    base = Part("base", (0.0, 0.0, 0.0))
    base.geoms.append(Geom("box", m_base, pos=(0.0, 0.0, 0.0), half=(lx, wy, hz)))
    n_wheels, n_casters = int(s.pick("wheels")), int(s.pick("casters"))
    if n_wheels == 2 and n_casters == 0:
        n_casters = 2
    gap, radius = s.u("ground_gap"), s.u("wheel_radius")
    zc = -hz - gap + radius
    width = 0.4 * radius
    xs = [0.0] if n_wheels == 2 else [0.65 * lx, -0.65 * lx]
    susp = s.p("suspension")
    for i, x in enumerate(xs):
        for side, sy in (("l", 1.0), ("r", -1.0)):
            name = f"wheel{i}{side}"
            drive = _free(s, (0.0, 1.0, 0.0), gear=0.3 * m_base * G * radius)
            pos = (x, sy * (wy + 0.6 * width), zc)
            if susp:
                sp = base.add(Part(f"susp{i}{side}", (x, sy * 0.5 * wy, zc),
                                   [Joint("slide", (0.0, 0.0, 1.0), (-0.02, 0.02), 50.0, 0.01,
                                          20.0 * m_base * G)]))
                sp.geoms.append(capsule((0.0, 0.0, 0.0), (0.0, sy * (0.5 * wy + 0.6 * width),
                                                          0.0), 0.3 * radius, 0.05 * m_base))
                wheel(sp, name, (0.0, sy * (0.5 * wy + 0.6 * width), 0.0), radius, width,
                      0.03 * m_base, drive)
            else:
                wheel(base, name, pos, radius, width, 0.03 * m_base, drive)
    rc = s.u((0.3, 0.6)) * gap
    drop = gap - rc
    corners = [(0.8 * lx, 0.6 * wy), (-0.8 * lx, 0.6 * wy), (0.8 * lx, -0.6 * wy),
               (-0.8 * lx, -0.6 * wy)]
    if n_casters == 2:
        corners = [(0.8 * lx, 0.0), (-0.8 * lx, 0.0)]
    for k, (x, y) in enumerate(corners[:n_casters]):
        sw = base.add(Part(f"caster{k}", (x, y, -hz), [_free(s, (0.0, 0.0, 1.0))]))
        sw.geoms.append(capsule((0.0, 0.0, 0.0), (-0.5 * rc, 0.0, -drop), 0.4 * rc, 0.05))
        cw = sw.add(Part(f"caster{k}_wheel", (-0.5 * rc, 0.0, -drop),
                         [_free(s, (0.0, 1.0, 0.0))]))
        cw.geoms.append(Geom("sphere", 0.1, rc, pos=(0.0, 0.0, 0.0)))
    column = s.u("column")
    joints = [s.slide((0.0, 0.0, 1.0), (0.0, s.u("lift_travel")), AUTO)] if s.p("lift") else []
    torso = base.add(Part("torso", (-0.3 * lx, 0.0, hz), joints))
    torso.geoms.append(capsule((0.0, 0.0, 0.0), (0.0, 0.0, column), 0.5 * wy, 0.3 * m_base))
    n_arms, hinges = int(s.pick("arms")), int(s.pick("arm_hinges"))
    head_first = s.p("head_first")
    neck: Part = torso
    top = (0.0, 0.0, column)
    for k, ax in enumerate("zy"[: int(s.pick("head_hinges"))]):
        neck = neck.add(Part(f"head{k}", top, [s.hinge(ax, (-1.2, 1.2), gear=AUTO)]))
        top = (0.0, 0.0, 0.05)
        neck.geoms.append(capsule((0.0, 0.0, 0.0), top, 0.03, 0.5))
    neck.geoms.append(Geom("box", 1.5, pos=(0.05, 0.0, top[2] + 0.07), half=(0.08, 0.1, 0.07)))
    arm = s.section("arm")
    plan = sample_arm(arm, hinges=hinges)  # two arms mirror one plan (tiago_dual)
    # the arm's first link rises beside the column (out by its radius), its top below the
    # column's top and the head, so that the upper arm reaches out clear of both
    out = 0.5 * wy + plan.radius
    z_arm = max(0.3 * column, min(0.8 * column, column - plan.links[0][1] - 2.0 * plan.radius))
    if n_arms == 1:
        build_arm(arm, plan, torso, "arm_", (out, 0.0, z_arm), (1.0, 0.0, 0.0))
    else:
        for side, sy in (("left", 1.0), ("right", -1.0)):
            build_arm(arm, plan, torso, f"arm_{side}_", (0.0, sy * out, z_arm), (0.0, sy, 0.0))
    if not head_first and neck is not torso:  # the head after the arms
        torso.children.append(torso.children.pop(0))
    return base, True
