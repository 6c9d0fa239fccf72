"""Robot graph → complete MJCF files: ``robot.xml`` and ``scene.xml`` (SPEC §7, paper §6.1).

:func:`graph_to_spec` repairs the graph with :func:`robovae.generate.rules.apply_rules`, builds
its ``mujoco.MjSpec`` (:class:`robovae.generate.spec_builder.SpecBuilder`), compiles it and
places it on the floor; :func:`write_robot` writes it (and a scene including it) to a folder.

**Floor placement**: when a top-level body has a free joint and ``clearance`` is not None, the
model is compiled, ``mj_forward`` run at ``qpos0``, and the lowest point over the robot's geoms
(corners of each geom's bounding box ``geom_aabb`` in the world frame) is lifted to
``z = clearance`` (m) by shifting the free bodies' ``pos[2]``. This changes the root link's
``pos[2]`` (the only feature that changes); ``clearance=None`` keeps it. With ``stance`` the
stance rules run first (:mod:`robovae.generate.stance`: hanging wheels lowered onto the floor,
soles laid flat, a biped's stilts stood on their ends; :mod:`robovae.generate.overlaps`: the
branches through each other slid apart, on a fixed base too; :mod:`robovae.generate.bipeds`: a
biped's ankles made strong enough for its soles, then a ``home`` keyframe lifted with the
robot).

**Round trip** (MJCF → graph → :func:`write_robot` → graph), within the 6-digit MJCF
precision:

- ``full`` with geom nodes: the topology (``parent``, ``node_type``) and every feature, except
  the size components a primitive does not use (sphere: 2nd and 3rd, capsule/cylinder: 3rd),
  which MJCF output does not write, so they come back as 0 (``geom.size``, and ``link.size``
  when it copies such a geom's size). A ``full`` graph without any geom node gets invented
  geoms (one per link), which come back as geom nodes.
- ``paper34``: the topology and every feature except ``link.size`` of bodies that had no geom
  (size zero: the writer gives them a small sphere, which then has a size). A link's first geom
  is its ``link.size`` primitive; the bridges that join it to its parent and children come
  after it (:mod:`robovae.generate.link_geometry`), so the reader takes the size back.
  ``subtreemass`` is derived from the masses and recomputed by MuJoCo, so it survives too.
  Joint types are not features of ``paper34``: slide joints come back as hinges, which have
  the same features.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from robovae.data.features import FeatureSet
from robovae.data.loading import capture_mujoco_warnings, robot_root
from robovae.data.self_collision import exclude_resting_contacts
from robovae.data.tree_arrays import RobotTree
from robovae.evaluate.quality.attachment import attachment
from robovae.files import atomic_write
from robovae.generate.bipeds import balance_home, foot_soles, strong_ankles, two_legs
from robovae.generate.graph_view import as_feature_set
from robovae.generate.mjcf_numbers import mjcf_round
from robovae.generate.overlaps import PASSES, clear_limbs
from robovae.generate.rules import apply_rules
from robovae.generate.spec_builder import ActuatorMode, SpecBuilder
from robovae.generate.stance import (
    SOLE_TOL,
    Points,
    at_qpos0,
    candidate_points,
    ground_wheels,
    level_soles,
    level_stilts,
    support_points,
)
from robovae.settings import check_settings, number

__all__ = ["DEFAULT_CLEARANCE", "WriteResult", "graph_to_spec", "scene_xml", "write_robot"]

#: Gap between the lowest geom point and the floor for free-floating robots (m).
DEFAULT_CLEARANCE = 0.01


@dataclass
class WriteResult:
    """What :func:`write_robot` wrote.

    Attributes:
        robot_path: ``robot.xml``.
        scene_path: ``scene.xml`` (floor, light, ``<include file="robot.xml"/>``) or None.
        rules_fired: names of the rules (and writer fixes) that changed something.
        n_bodies, n_joints, n_geoms, n_actuators: counts of the compiled robot (world excluded).
    """

    robot_path: Path
    scene_path: Path | None
    rules_fired: list[str] = field(default_factory=list)
    n_bodies: int = 0
    n_joints: int = 0
    n_geoms: int = 0
    n_actuators: int = 0

    @property
    def rules(self) -> list[str]:
        """Alias of :attr:`rules_fired`."""
        return self.rules_fired

    @property
    def counts(self) -> dict[str, int]:
        """``{"bodies": ..., "joints": ..., "geoms": ..., "actuators": ...}``."""
        return {"bodies": self.n_bodies, "joints": self.n_joints, "geoms": self.n_geoms,
                "actuators": self.n_actuators}


#: What the writer's files depend on beyond the graph, named change by change: a generation
#: folder (``run.json``) and an optimisation log record it, so that neither is continued with
#: robots written another way. Name each change that alters written files here.
WRITER = ("spun discs as cylinders, slide rails limited, DC motors on continuous joints (and "
          "procedural wheels), hanging wheels grounded, biped stilts levelled, biped ankles "
          "strengthened, soles under biped point feet, twin limbs on the sagittal plane made "
          "equal (decoded graphs), leaves beside their limb as rods, limbs through each other "
          "slid apart, branches within a limb too (their joining geometry following, in up to "
          "three passes), bridges from the primitive's core, fixed bases' branches slid apart too, "
          "stray limbs off their pairs' ring mirrored (decoded graphs)")


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    with capture_mujoco_warnings():
        try:
            return spec.compile()
        except Exception as e:  # MuJoCo raises ValueError with its own message
            msg = " ".join(str(e).split())
            raise ValueError(f"MuJoCo rejected the generated robot: {msg}") from None


def _lowest_point(model: mujoco.MjModel, data: mujoco.MjData | None = None) -> float:
    """Lowest world z over all geoms' bounding boxes at ``qpos0`` (``inf`` without geoms):
    ``min_g  z_g + R_g[2] · c_g - |R_g[2]| · h_g`` for each geom's box centre ``c_g`` and
    half-sizes ``h_g`` in its frame (``mj_kinematics``: the poses are all it needs; ``data``:
    the model's kinematics at ``qpos0`` when the caller has them)."""
    if not model.ngeom:
        return math.inf
    data = at_qpos0(model, data)
    row = data.geom_xmat[:, 6:9]
    aabb = model.geom_aabb
    z = data.geom_xpos[:, 2] + np.einsum("gi,gi->g", row, aabb[:, :3]) \
        - np.einsum("gi,gi->g", np.abs(row), aabb[:, 3:])
    return float(z.min())


def _build(data: RobotTree, fs: FeatureSet, name: str, rules: bool, actuators: ActuatorMode,
           clearance: float | None, self_collision: bool, stance: bool = False
           ) -> tuple[mujoco.MjSpec, mujoco.MjModel, list[str]]:
    """The spec (stance rules and floor placement applied), a model compiled before the
    placement (its counts are right, its root height is not) and the fired rules."""
    check_settings("write_robot", clearance=(clearance, number(0).or_none()))
    if actuators not in ("auto", "all", "none"):
        raise ValueError(f"actuators must be 'auto', 'all' or 'none', not {actuators!r}")
    fired: list[str] = []
    if rules:
        data, fired = apply_rules(data, fs)
    feet: set[int] = set()

    def make() -> SpecBuilder:
        made = SpecBuilder(data, fs, name, actuators, self_collision)
        made.feet = feet
        return made

    builder = make()
    spec = builder.build()
    model = _compile(spec)
    clear = stance and model.ngeom > 0  # branches slid apart: fixed bases too
    stance = clear and bool(builder.free_bodies)
    placed = clearance is not None and bool(builder.free_bodies) and model.ngeom > 0
    # one MjData (about 0.4 ms to make) serves the stance rules and the floor placement, and
    # the stance rules share the geoms' candidate points of each compiled model
    kin = at_qpos0(model) if clear or placed else None
    root = robot_root(model)[0] if clear else -1  # the same body when built again
    pts = candidate_points(model, kin) if stance else None
    if stance and builder.side_leaves:
        feet |= _standing_leaves(builder, model, kin, pts)
    if feet:  # built again: the side leaves it stands on keep their soles
        builder = make()
        spec = builder.build()
        model = _compile(spec)
        kin = at_qpos0(model)
        pts = candidate_points(model, kin)
    shifts = ground_wheels(model, root, kin, pts) if stance else {}
    if shifts:  # the mounts moved in place, their bridges following them
        builder.move_built(shifts, builder.x.copy())
        model = _compile(spec)
        kin = at_qpos0(model)
        pts = candidate_points(model, kin)
    fired += builder.fixes + (["ground_wheels"] if shifts else [])
    slid = _clear_limbs(builder, spec, model, root, kin) if clear else None
    if slid is not None:
        model, kin = slid
        pts = candidate_points(model, kin) if stance else None
        fired.append("clear_limbs")
    if stance:  # both rules read the same model (level_soles changes only the spec)
        levelled = [name for name, fires in
                    (("level_soles", level_soles(spec, model, kin, pts)),
                     ("level_stilts", level_stilts(spec, model, root, kin, pts))) if fires]
        if levelled:
            fired += levelled
            model = _compile(spec)
            kin = at_qpos0(model)
            pts = candidate_points(model, kin)
    legs = two_legs(model, kin, root, pts) if stance else None  # the three rules' two legs
    if legs is not None and foot_soles(spec, model, root, kin, pts, legs):
        fired.append("foot_soles")
        model = _compile(spec)
        kin = at_qpos0(model)
        legs = two_legs(model, kin, root, candidate_points(model, kin))
    dz = 0.0
    if placed:
        assert clearance is not None  # placed says so
        dz = clearance - _lowest_point(model, kin)
        for body in builder.free_bodies:  # to_xml writes the spec's values: no recompile
            body.pos = [body.pos[0], body.pos[1], mjcf_round(body.pos[2] + dz)]
    if legs is not None:
        if strong_ankles(spec, model, root, data=kin, legs=legs):  # gears only
            fired.append("strong_ankles")
        if balance_home(spec, model, root, lift=dz, data=kin, legs=legs):
            fired.append("balance_home")
    if self_collision and exclude_resting_contacts(spec):  # the final spec: its keyframe too
        fired.append("self_collision_excludes")
    return spec, model, fired


def _standing_leaves(builder: SpecBuilder, model: mujoco.MjModel, kin: mujoco.MjData,
                     pts: Points | None) -> set[int]:
    """The side leaves of ``builder`` (written as rods) that reach within ``SOLE_TOL · L`` of
    the robot's lowest point: the robot stands on them, so they are feet and keep their box."""
    _, owner, _ = support_points(model, kin, SOLE_TOL, pts)
    names = {model.body(int(b)).name for b in model.geom_bodyid[owner]}
    return {i for i in builder.side_leaves if f"link{i}" in names}


def _clear_limbs(builder: SpecBuilder, spec: mujoco.MjSpec, model: mujoco.MjModel, root: int,
                 kin: mujoco.MjData) -> tuple[mujoco.MjModel, mujoco.MjData] | None:
    """Slide the branches of ``builder``'s ``spec`` (compiled as ``model``, ``kin`` its
    kinematics at ``qpos0``) apart by :func:`~robovae.generate.overlaps.clear_limbs`' slides,
    when that leaves fewer off-joint overlaps and every body attached: the model compiled then
    and its kinematics; else None, the spec as it was. Up to
    :data:`~robovae.generate.overlaps.PASSES` times, each pass on the robot the last one made
    (its slides added to theirs), while overlaps are left. Each pass moves the spec in place
    (:meth:`~robovae.generate.spec_builder.SpecBuilder.move_built`: the robot built again with
    the slides, without building it), undone when not kept."""
    best = None
    base = builder.x.copy()
    total: dict[str, np.ndarray] = {}
    count = None  # the off-joint overlaps of the robot the pass starts from
    for _ in range(PASSES):
        slides = clear_limbs(model, root, kin)
        if not slides:
            break
        for name, move in slides.items():  # in parents' frames, which no slide turns: they add
            total[name] = total.get(name, np.zeros(3)) + move
        undo = builder.move_built(total, base)
        moved = _compile(spec)
        moved_kin = at_qpos0(moved)
        # a mount moved reshapes the geometry joining it to its parent: every overlap counts
        after = attachment(moved, data=moved_kin)
        if count is None:
            count = attachment(model, data=kin).off_joint_pairs if after.off_joint_pairs else 1
        if not after.all_attached or after.off_joint_pairs >= count:
            undo()
            break  # slides come only for a robot with overlaps: none left is fewer
        best = (moved, moved_kin)
        model, kin, count = moved, moved_kin, after.off_joint_pairs
        if not count:
            break
    return best


def graph_to_spec(
    data: RobotTree,
    feature_set: str | FeatureSet = "paper34",
    name: str = "robot",
    rules: bool = True,
    *,
    actuators: ActuatorMode = "auto",
    clearance: float | None = DEFAULT_CLEARANCE,
    self_collision: bool = False,
    stance: bool = False,
) -> tuple[mujoco.MjSpec, list[str]]:
    """Build the ``mujoco.MjSpec`` of a robot graph (mapping: :mod:`robovae.generate.spec_builder`;
    floor placement: module docstring).

    Args:
        data: robot graph in physical units (e.g. decoded and de-normalised).
        feature_set: the registry set ``data.x`` follows (``paper34`` or ``full``).
        name: model name (``spec.modelname``).
        rules: apply :func:`robovae.generate.rules.apply_rules` first (recommended: without
            them a malformed graph may not compile).
        actuators: ``auto``, ``all`` or ``none`` (:mod:`robovae.generate.spec_builder`).
        clearance: lift free-floating robots so their lowest point is this high above
            ``z = 0``; ``None`` keeps the root link's position.
        self_collision: let the robot's geoms collide with each other (``conaffinity = 1``);
            the body pairs in contact at rest are excluded from colliding
            (:mod:`robovae.data.self_collision`, reported as ``self_collision_excludes``).
        stance: a free-floating robot gets its hanging wheels lowered onto the floor, its soles
            laid flat and, standing on two feet, its stilts stood on their ends, soles under
            point feet, ankles strong enough for its soles and a balanced ``home`` keyframe
            (:mod:`robovae.generate.stance`: ``ground_wheels``, ``level_soles``,
            ``level_stilts``; :mod:`robovae.generate.bipeds`: ``foot_soles``, ``strong_ankles``,
            ``balance_home``); any robot, fixed bases too, gets its branches through each
            other slid apart (:mod:`robovae.generate.overlaps`: ``clear_limbs``).

    Returns:
        The spec (already compiled once, so ``spec.to_xml()`` works) and the names of the rules
        and writer fixes that changed something.

    Raises:
        ValueError: when MuJoCo rejects the model (only possible with ``rules=False``).
    """
    fs = as_feature_set(feature_set)
    spec, _, fired = _build(data, fs, name, rules, actuators, clearance, self_collision, stance)
    return spec, fired


def scene_xml(robot_file: str = "robot.xml", name: str = "scene") -> str:
    """MJCF of a scene: ``<include file=robot_file/>``, a floor plane and a light.

    The floor and light are built with ``MjSpec`` (once per process); the ``<include>``
    element (which ``MjSpec`` cannot express) and the model name are set in its XML tree.
    """
    root = copy.deepcopy(_scene_tree())
    root.set("model", name)
    root.insert(0, ET.Element("include", file=robot_file))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


@functools.cache
def _scene_tree() -> ET.Element:
    spec = mujoco.MjSpec()
    spec.modelname = "scene"
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                            rgba=[0.82, 0.84, 0.86, 1.0])
    spec.worldbody.add_light(name="sun", pos=[0, 0, 4], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    spec.compile()
    root = ET.fromstring(spec.to_xml())
    for compiler in root.findall("compiler"):  # the robot file's compiler settings apply
        root.remove(compiler)
    return root


def write_robot(
    data: RobotTree,
    out_dir: str | os.PathLike,
    feature_set: str | FeatureSet = "paper34",
    name: str = "robot",
    scene: bool = True,
    *,
    rules: bool = True,
    actuators: ActuatorMode = "auto",
    clearance: float | None = DEFAULT_CLEARANCE,
    self_collision: bool = False,
    stance: bool = False,
    check: bool = True,
    durable: bool = True,
) -> WriteResult:
    """Write a robot graph as ``out_dir/robot.xml`` (and ``out_dir/scene.xml``).

    Both files are written atomically (temporary file in ``out_dir``, then ``os.replace``),
    ``robot.xml`` first: when ``scene.xml`` exists, the folder is complete. With ``check`` the
    robot XML is loaded with MuJoCo before anything is written (callers that validate the file
    anyway may skip it); with ``durable`` each file is fsync'ed before it is moved into place
    (callers that sync a whole batch at once, e.g. with ``os.sync``, may skip it).

    Args:
        data: the robot graph (as in :func:`graph_to_spec`).
        feature_set: as in :func:`graph_to_spec`.
        name: as in :func:`graph_to_spec`.
        rules: as in :func:`graph_to_spec`.
        actuators: as in :func:`graph_to_spec`.
        clearance: as in :func:`graph_to_spec`.
        self_collision: as in :func:`graph_to_spec`.
        stance: as in :func:`graph_to_spec`.
        out_dir: folder to write into (created if missing).
        scene: also write ``scene.xml`` (floor, light, ``<include file="robot.xml"/>``).
        check: load the XML with MuJoCo before writing.
        durable: fsync every file before ``os.replace``.

    Raises:
        ValueError: when MuJoCo rejects the model (only possible with ``rules=False``).
    """
    fs = as_feature_set(feature_set)
    spec, model, fired = _build(data, fs, name, rules, actuators, clearance, self_collision,
                                stance)
    with capture_mujoco_warnings():  # to_xml compiles the spec again (MuJoCo's bindings)
        xml = spec.to_xml()
    if check:
        with capture_mujoco_warnings():
            try:
                mujoco.MjModel.from_xml_string(xml)
            except Exception as e:
                msg = " ".join(str(e).split())
                raise ValueError(f"the written robot XML does not load: {msg}") from None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    robot_path = out / "robot.xml"
    atomic_write(robot_path, xml, durable)
    scene_path = None
    if scene:
        scene_path = out / "scene.xml"
        atomic_write(scene_path, scene_xml(robot_path.name, f"{name}_scene"), durable)
    return WriteResult(robot_path, scene_path, fired, n_bodies=model.nbody - 1,
                       n_joints=model.njnt, n_geoms=model.ngeom, n_actuators=model.nu)
