"""validate_robot classifies real and broken robots; validate_many keeps input order."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from robovae.data.zoo import zoo_files
from robovae.generate.validate import REASONS, check_robot, validate_many, validate_robot


def _zoo(name: str) -> Path:
    return dict(zoo_files()[0])[name]


def _write(tmp_path: Path, name: str, body: str, option: str = "") -> Path:
    path = tmp_path / f"{name}.xml"
    path.write_text(f"<mujoco>{option}<worldbody>{body}</worldbody></mujoco>")
    return path


BOX = ('<body pos="0 0 {z}"><freejoint/><geom type="box" size=".1 .1 .1" mass="1"/>'
       '<body pos=".2 0 0"><joint type="hinge" axis="0 1 0"/>'
       '<geom type="capsule" fromto="0 0 0 .2 0 0" size=".03"/></body></body>')


def test_zoo_robots_are_valid():
    for name in ["gym_ant", "dmc_cheetah", "dmc_walker"]:
        v = validate_robot(_zoo(name))
        assert v.valid and v.reason == "valid", (name, v.detail)
        assert v.steps >= 100 and v.energy_scale > 1


def test_compile_error_is_a_reason_not_an_exception(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><geom type='sphere'/>")
    v = validate_robot(bad)
    assert (v.valid, v.reason) == (False, "compile") and "\n" not in v.detail


def test_self_penetration_at_rest(tmp_path):
    two = ('<body pos="0 0 1"><freejoint/><geom type="sphere" size=".2"/></body>'
           '<body pos="0 0 1.1"><joint type="slide"/><geom type="sphere" size=".2"/></body>')
    v = validate_robot(_write(tmp_path, "overlap", two))
    assert v.reason == "self_penetration"
    apart = two.replace("0 0 1.1", "0 0 1.5")
    assert validate_robot(_write(tmp_path, "apart", apart)).valid


@pytest.mark.parametrize("flags", ["", '<flag sensor="disable"/>'])
def test_energy_blowup(tmp_path, flags):
    """Gravity 10^4 times Earth's: the fall gains far more energy than m g h allows (also when
    the file turns sensors off)."""
    path = _write(tmp_path, "fast", BOX.format(z=2),
                  f'<option gravity="0 0 -1e5">{flags}</option>')
    v = validate_robot(path)
    assert v.reason == "energy_blowup" and v.max_kinetic > 100 * v.energy_scale


def test_a_rigid_body_is_degenerate(tmp_path):
    rigid = '<body pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1"/></body>'
    v = validate_robot(_write(tmp_path, "rigid", rigid))
    assert v.reason == "degenerate" and "nothing moves" in v.detail


def test_validate_many_in_order_with_workers(tmp_path):
    good = _write(tmp_path, "box", BOX.format(z=1))
    bad = tmp_path / "missing.xml"
    paths = [good, bad] * 5
    out = validate_many(paths, jobs=2)
    assert [v.reason for v in out] == ["valid", "compile"] * 5
    assert [v.path for v in out] == [str(p) for p in paths]
    assert {v.reason for v in out} <= set(REASONS)


@pytest.mark.parametrize("duration", [0.1, 0.5])
def test_duration_sets_the_number_of_steps(tmp_path, duration):
    v = validate_robot(_write(tmp_path, "box", BOX.format(z=1)), duration=duration)
    assert v.steps == round(duration / 0.002)


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_kinetic_energy_is_the_maximum_over_the_steps(tmp_path, integrator):
    """max_kinetic is the largest kinetic energy of the ``mj_step`` loop (one call of
    mujoco.rollout gives the same trajectory); check_robot returns the model it simulated, with
    a floor plane when the file has none."""
    path = _write(tmp_path, "box", BOX.format(z=1), f'<option integrator="{integrator}"/>')
    v, model, _, floor, _ = check_robot(path)
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    energy = []
    for _ in range(v.steps):
        mujoco.mj_step(model, data)
        energy.append(float(data.energy[1]))
    assert v.valid and v.max_kinetic == max(energy) > 0
    assert model.geom(floor.name).type == mujoco.mjtGeom.mjGEOM_PLANE
    assert model.geom(floor.name).pos[2] == 0
