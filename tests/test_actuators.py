import pytest

from seactl.errors import InputError
from seactl.systems.sea.actuators import UT_SEA, SEAParams, load_sea

VALID = dict(motor_inertia=0.2, joint_inertia=0.01, motor_damping=1.0, joint_damping=0.1,
             spring_stiffness=200.0, current_to_torque=5.0)


def test_ut_sea_matches_table_ii_rotary_and_linear():
    """Oracle: the printed tables only -- Table II (rotary) and docs/theory/units.md (rotary
    table and linear view, r = 0.025 m); tolerance half a unit of the last printed digit."""
    assert UT_SEA.motor_inertia == pytest.approx(0.225)
    assert UT_SEA.joint_inertia == pytest.approx(0.014)
    assert UT_SEA.motor_damping == pytest.approx(1.375)
    assert UT_SEA.joint_damping == pytest.approx(0.1)
    assert UT_SEA.spring_stiffness == pytest.approx(218.75)
    assert UT_SEA.current_to_torque == pytest.approx(5.2025, abs=5e-5)
    assert UT_SEA.motor_torque_constant == pytest.approx(0.0276)
    assert UT_SEA.pulley_radius == pytest.approx(0.025)
    lin = UT_SEA.linear()
    assert lin["motor_inertia"] == pytest.approx(360.0)
    assert lin["joint_inertia"] == pytest.approx(22.4)
    assert lin["motor_damping"] == pytest.approx(2200.0)
    assert lin["joint_damping"] == pytest.approx(160.0)
    assert lin["spring_stiffness"] == pytest.approx(350000.0)
    assert lin["current_to_force"] == pytest.approx(208.1, abs=0.05)


@pytest.mark.parametrize("field,value", [
    ("motor_inertia", 0.0), ("motor_inertia", -1.0), ("joint_inertia", float("nan")),
    ("spring_stiffness", float("inf")), ("current_to_torque", -5.0),
    ("motor_damping", -0.1), ("joint_damping", float("nan")),
])
def test_invalid_fields_name_field_value_and_range(field, value):
    # Oracle: the documented error contract (InputError naming the field, the value and the
    # valid range).
    with pytest.raises(InputError) as exc:
        SEAParams(**{**VALID, field: value})
    msg = str(exc.value)
    assert field in msg and ">" in msg
    assert exc.value.field == field


def test_toml_roundtrip_and_errors(tmp_path):
    # Oracle: the values written into the TOML files; the error contract names the offending
    # key, value or file.
    good = tmp_path / "mine.toml"
    good.write_text("\n".join(f"{k} = {v}" for k, v in VALID.items()))
    a = load_sea(good)
    assert a.name == "mine" and a.spring_stiffness == 200.0
    nested = tmp_path / "nested.toml"
    nested.write_text("[actuator]\n" + "\n".join(f"{k} = {v}" for k, v in VALID.items()))
    assert load_sea(nested).motor_inertia == 0.2

    bad_key = tmp_path / "badkey.toml"
    bad_key.write_text(good.read_text() + "\nspring_stiffnes = 3\n")
    with pytest.raises(InputError, match="spring_stiffnes"):
        load_sea(bad_key)
    bad_val = tmp_path / "badval.toml"
    bad_val.write_text(good.read_text().replace("spring_stiffness = 200.0",
                                                "spring_stiffness = -2"))
    with pytest.raises(InputError, match=r"spring_stiffness = -2.*> 0"):
        load_sea(bad_val)
    missing = tmp_path / "missing.toml"
    missing.write_text("motor_inertia = 1\n")
    with pytest.raises(InputError, match="joint_inertia"):
        load_sea(missing)
    with pytest.raises(InputError, match="actuator"):
        load_sea("no-such-preset")
    broken = tmp_path / "broken.toml"
    broken.write_text("motor_inertia = = 1")
    with pytest.raises(InputError, match="valid TOML"):
        load_sea(broken)
