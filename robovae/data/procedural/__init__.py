"""Procedural robots of the classes real collections hold, built with ``mujoco.MjSpec``.

====================== ==================================================================
class                  tree (real robots it follows)
====================== ==================================================================
``quadruped``          4 legs × (abduction x, flexion y, knee y) (go1, go2, a1, spot)
``hexapod``            6 legs × (coxa z, femur, tibia)
``radial``             3-8 legs around a round body, 2-3 hinges each (ant)
``humanoid``           legs of 5-7 hinges, waist 0-3, arms 4-7 with grippers or fingered
                       hands, neck 0-2 and head; or legs only (h1, g1, t1, talos, berkeley)
``biped``              Cassie-like digitigrade legs with springs and rods (cassie)
``arm``                fixed base, 4-7 hinges, parallel-jaw gripper (z1, piper)
``mobile_manipulator`` wheeled base, casters, torso lift, head, 1-2 arms (tiago)
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
