"""Procedural robots of the classes real collections hold, built with ``mujoco.MjSpec``.

====================== ==================================================================
class                  tree (real robots it follows)
====================== ==================================================================
``quadruped``          4 legs × (abduction x, flexion y, knee y) (go1, go2, a1, spot)
``hexapod``            6 legs × (coxa z, femur, tibia)
``radial``             3-8 legs around a round body, 2-3 hinges each (ant)
``humanoid``           legs of 5-7 hinges, waist 0-3, arms of 3-7 hinges (wrists with
                       grippers or fingered hands, both alike), neck 0-3 and head, welded
                       sensor bodies; rooted at the pelvis (legs listed first or last) or at
                       the torso; or legs only (h1, g1, t1, n1, talos, berkeley, apollo, op3)
``biped``              Cassie-like digitigrade legs with springs and rods (cassie)
``arm``                fixed base, 4-7 hinges, welded flange, a gripper with two parallel
                       jaws, one moving jaw or two linkage jaws (z1, piper, franka)
``mobile_manipulator`` wheeled base, casters, torso lift, head, 1 arm or 2 mirrored arms
                       (tiago, tiago_dual)
====================== ==================================================================

Modules: :mod:`.blueprint` (the part tree), :mod:`.sampler` (draws from ``ranges.yaml``),
:mod:`.parts` (shared limbs, grippers, hands, wheels, motor sizing), one module per class,
:mod:`.spec` (part tree → ``MjSpec``), :mod:`.robots` (seed → plan → spec) and :mod:`.batch`
(many robots in parallel: graphs for datasets, or MJCF files).
"""

from robovae.data.procedural.batch import parse_procedural, procedural_graphs, write_procedural
from robovae.data.procedural.robots import (
    CLASSES,
    ProceduralConfig,
    default_mix,
    procedural_name,
    procedural_plan,
    procedural_spec,
)

__all__ = ["CLASSES", "ProceduralConfig", "default_mix", "parse_procedural", "procedural_graphs",
           "procedural_name", "procedural_plan", "procedural_spec", "write_procedural"]
