"""validate_robot classifies real and broken robots, held and with zero controls; validate_many
keeps input order; the held validation is the first second of the standing test."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from robovae.data.zoo import zoo_files
from robovae.evaluate.quality.measure import measure
from robovae.evaluate.quality.standing import HeldRun, standing
from robovae.generate.validate import CONTROLS, REASONS, check_robot, validate_many, validate_robot


def _zoo(name: str) -> Path:
    return dict(zoo_files()[0])[name]


def _write(tmp_path: Path, name: str, body: str, option: str = "") -> Path:
    path = tmp_path / f"{name}.xml"
    path.write_text(f"<mujoco>{option}<worldbody>{body}</worldbody></mujoco>")
    return path


BOX = ('<body pos="0 0 {z}"><freejoint/><geom type="box" size=".1 .1 .1" mass="1"/>'
       '<body pos=".2 0 0"><joint type="hinge" axis="0 1 0"/>'
       '<geom type="capsule" fromto="0 0 0 .2 0 0" size=".03"/></body></body>')


ARM = ('<body pos="0 0 .5"><geom type="sphere" size=".05"/><body pos=".1 0 0">'
       '<joint type="hinge" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .4 0 0" size=".03"/>'
       '</body></body>')


@pytest.mark.parametrize("controls", CONTROLS)
def test_zoo_robots_are_valid(controls):
    for name in ["gym_ant", "dmc_cheetah", "dmc_walker"]:
        v = validate_robot(_zoo(name), controls=controls)
        assert v.valid and v.reason == "valid", (name, v.detail)
        assert v.steps >= 100 and v.energy_scale > 1


def test_compile_error_is_a_reason_not_an_exception(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><geom type='sphere'/>")
    v = validate_robot(bad)
    assert (v.valid, v.reason) == (False, "compile") and "\n" not in v.detail
    assert v.detail.startswith("malformed XML (XML_ERROR_")  # was MuJoCo's "XML parse error 8:"
    size = tmp_path / "size.xml"
    size.write_text("<mujoco><worldbody><body><joint/><geom type='box' size='0.1'/></body>"
                    "</worldbody></mujoco>")
    assert validate_robot(size).detail == "size 1 must be positive in geom (unnamed element, " \
                                          "line 1)"
    for path, what in ((tmp_path, "a folder, not a robot file"), (tmp_path / "no.xml",
                                                                  "no such file")):
        v = validate_robot(path)
        assert (v.reason, v.detail.split(" (")[0]) == ("compile", what)


def test_self_penetration_at_rest(tmp_path):
    two = ('<body pos="0 0 1"><freejoint/><geom type="sphere" size=".2"/></body>'
           '<body pos="0 0 1.1"><joint type="slide"/><geom type="sphere" size=".2"/></body>')
    v = validate_robot(_write(tmp_path, "overlap", two))
    assert v.reason == "self_penetration"
    apart = two.replace("0 0 1.1", "0 0 1.5")
    assert validate_robot(_write(tmp_path, "apart", apart)).valid


@pytest.mark.parametrize("controls", CONTROLS)
@pytest.mark.parametrize("flags", ["", '<flag sensor="disable"/>'])
def test_energy_blowup(tmp_path, flags, controls):
    """Gravity 10^4 times Earth's: the fall gains far more energy than m g h allows (also when
    the file turns sensors off)."""
    path = _write(tmp_path, "fast", BOX.format(z=2),
                  f'<option gravity="0 0 -1e5">{flags}</option>')
    v = validate_robot(path, controls=controls)
    assert v.reason == "energy_blowup" and v.max_kinetic > 100 * v.energy_scale
    assert "at step 1" in v.detail and v.steps == 2  # the exact step, replayed


@pytest.mark.parametrize("controls", CONTROLS)
def test_mujoco_warning(tmp_path, controls):
    """Gravity 10^11 times Earth's: the first step's acceleration is beyond MuJoCo's bound."""
    v = validate_robot(_write(tmp_path, "bad", BOX.format(z=1),
                              '<option gravity="0 0 -1e12"/>'), controls=controls)
    assert v.reason == "mujoco_warning" and "bad qacc" in v.detail and v.steps == 1


def test_unknown_controls_and_settings_out_of_range_are_refused(tmp_path):
    box = _write(tmp_path, "box", BOX.format(z=1))
    with pytest.raises(ValueError, match="controls must be one of held, zero"):
        validate_robot(box, controls="random")
    # a duration of -1 judged one step valid, NaN was a traceback, until 2026-11-29
    for bad, message in (({"duration": -1.0}, "validate_robot.duration must be a number > 0"),
                         ({"duration": float("nan")}, "duration must be a number > 0, got nan"),
                         ({"energy_factor": float("nan")}, "energy_factor must be a number"),
                         ({"penetration_tol": -1.0}, "penetration_tol must be a number >= 0")):
        with pytest.raises(ValueError, match=message):
            validate_robot(box, **bad)


@pytest.mark.parametrize("controls", CONTROLS)
def test_a_rigid_body_is_degenerate(tmp_path, controls):
    rigid = '<body pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1"/></body>'
    v = validate_robot(_write(tmp_path, "rigid", rigid), controls=controls)
    assert v.reason == "degenerate" and "nothing moves" in v.detail


def test_validate_many_in_order_with_workers(tmp_path):
    good = _write(tmp_path, "box", BOX.format(z=1))
    bad = tmp_path / "missing.xml"
    paths = [good, bad] * 5
    out = validate_many(paths, jobs=2)
    assert [v.reason for v in out] == ["valid", "compile"] * 5
    assert [v.path for v in out] == [str(p) for p in paths]
    assert {v.reason for v in out} <= set(REASONS)
    zero = validate_many(paths, jobs=2, controls="zero")
    assert [v.reason for v in zero] == ["valid", "compile"] * 5


@pytest.mark.parametrize("controls", CONTROLS)
@pytest.mark.parametrize("duration", [0.1, 0.5])
def test_duration_sets_the_number_of_steps(tmp_path, duration, controls):
    v = validate_robot(_write(tmp_path, "box", BOX.format(z=1)), duration=duration,
                       controls=controls)
    assert v.steps == round(duration / 0.002)


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_kinetic_energy_is_the_maximum_over_the_steps(tmp_path, integrator):
    """max_kinetic is the largest kinetic energy of the ``mj_step`` loop (one call of
    mujoco.rollout gives the same trajectory); check_robot returns the model it simulated, with
    a floor plane when the file has none. Zero controls: the model as compiled, from qpos0."""
    path = _write(tmp_path, "box", BOX.format(z=1), f'<option integrator="{integrator}"/>')
    checked = check_robot(path, controls="zero")
    v, model, floor = checked.validation, checked.model, checked.floor
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
    assert checked.stage is None and checked.held is None


def test_held_validation_simulates_the_held_robot(tmp_path):
    """Held: the standing test's model (implicitfast, joints PD-held at rest, floor at the
    robot's lowest point), from the rest pose; max_kinetic is the maximum of its step loop."""
    path = _write(tmp_path, "box", BOX.format(z=1))
    checked = check_robot(path)
    v, st, held = checked.validation, checked.stage, checked.held
    assert v.valid and held.done == v.steps == 500
    assert held.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert st.floor_z == pytest.approx(0.9, abs=1e-6)  # the box's bottom, not z = 0
    assert held.model.jnt_stiffness[1] > 0  # the unactuated hinge held by a spring
    model, data = held.model, mujoco.MjData(held.model)
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    mujoco.mj_setState(model, data, held.start, HeldRun.STATE)
    data.qacc_warmstart[:] = held.start_warmstart
    energy = []
    for _ in range(v.steps):
        mujoco.mj_step(model, data)
        energy.append(float(data.energy[1]))
    assert v.max_kinetic == max(energy) > 0
    assert (data.qpos == held.state[1:1 + model.nq]).all()  # the same trajectory
    # the stage is left at rest for the measures at rest
    assert st.data.time == 0 and (st.data.qpos == st.model.qpos0).all()


@pytest.mark.parametrize("kind", ["quadruped", "humanoid", "arm"])
def test_held_validation_is_the_first_second_of_the_standing_test(kind, tmp_path):
    """The standing test continues the validation's simulation: the same record, to the bit, as
    the standing test run from scratch on the file (fixed-base robots are validated held, and
    not standing-tested)."""
    from robovae.data.procedural import procedural_spec

    for seed in range(2):
        path = tmp_path / f"{kind}_{seed}.xml"
        path.write_text(procedural_spec(seed, kind).to_xml())
        checked = check_robot(path)
        assert checked.validation.valid, checked.validation.detail
        assert checked.stage.free == (kind != "arm")
        continued = measure(checked.stage, describe=False, held=checked.held)
        fresh = measure(path, describe=False)
        same = [k for k in fresh if not k.startswith("t_") and k not in ("name", "path")]
        assert {k: fresh[k] for k in same} == {k: continued[k] for k in same}
        again = check_robot(path)
        assert standing(path) == standing(again.stage, held=again.held)


@pytest.mark.parametrize("controls", CONTROLS)
def test_a_fixed_base_arm_is_validated(tmp_path, controls):
    v = validate_robot(_write(tmp_path, "arm", ARM), controls=controls)
    assert v.valid and v.steps == 500, v.detail


def test_a_held_arm_is_valid_where_zero_controls_blow_up(menagerie_dir):
    """Menagerie's Piper arm: its position servos (kp 2000, kv 200) driven by zero controls under
    the file's explicit Euler integrator blow up within 14 steps; held (the standing test's PD
    hold, implicitfast), it stays nearly still."""
    piper = menagerie_dir / "agilex_piper" / "piper.xml"
    zero, held = validate_robot(piper, controls="zero"), validate_robot(piper)
    assert zero.reason == "energy_blowup" and zero.steps < 20
    assert held.valid and held.max_kinetic < 0.01 * held.energy_scale
