"""Kirgetov's servoconstraint examples [K section 7] as bundled scenes, against the seed's closed forms.

- ``homing`` (7.1-7.3, parallel homing): prescribed y2 - y1 = 0, z2 - z1 = 0, controls = forces on m2 along
  y and z. Dynamic conditions (7.3): m2 y1'' = Y2, m2 z1'' = Z2 (Y2, Z2 the total forces on m2, control
  included), so with m1 y1'' = Y1 the controls are u = (m2/m1) Y1 - Y2_applied (and the same along z); the
  pursued point moves freely (m1 r1'' = F1) and the pursuer along the line by m2 x2'' = X2.
- ``appell-plate`` (7.4-7.6): the equation of motion (7.5) J alpha'' + F (R sin alpha - a cos alpha) = u,
  J = M (R^2 + b^2 + k^2) + I1; the dynamic condition of fulfilment (7.6, Appell's equation)
  M (b^2 + k^2) alpha'' - M R b alpha'^2 = F a cos alpha. 7.6 fixes the motion (free of u and I1); 7.5
  gives the control. Realized by a real constraint instead (Appell's direct tangency, no control), the
  motion obeys 7.5 with u = 0 and not 7.6.
- ``ring-on-rod`` (7e): keeping r = c needs -m c alpha'^2 = F > 0; with a motor torque on the rod the
  decoupling matrix S N B is zero (the rod pushes the ring only across itself): rank loss, exit 2.
"""

from __future__ import annotations

import json
import math
import re
import tomllib

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

import pinstab
from conftest import ROBOTS
from pinstab.cli import main
from pinstab.errors import ServoInfeasibleError
from pinstab.scene import scene_from_dict

GRAVITY = 9.81  # [m/s^2], along -z in every scene here

# homing.toml / urdf/homing.urdf
M1, M2 = 2.0, 0.5  # [kg]
K1 = 8.0  # [N/m] m1's spring to the origin
K2, C2, ANCHOR2 = 2.0, 0.4, np.array([-3.0, 0.0, 0.0])  # [N/m], [N s/m], [m] m2's spring-damper

# appell-plate.toml / urdf/appell-plate.urdf
PLATE_MASS, PLATE_INERTIA = 2.0, 0.075  # M [kg], M k^2 about G [kg m^2]
DISK_INERTIA = 0.54  # I1 [kg m^2]
R, A, B = 0.5, 0.6, 0.3  # OC, CA, CG [m]
F = 4.0  # [N] along Ox at A
BETA0 = 0.4  # [rad] initial plate angle, at rest

# ring-on-rod.toml / urdf/ring-on-rod.urdf
RING_MASS, RADIUS, PULL = 0.2, 0.5, 2.0  # m [kg], c [m], F [N]


@pytest.fixture(scope="module")
def homing_run() -> pinstab.Trajectory:
    return pinstab.simulate("homing", method="baumgarte", integrator="rk4", dt=1e-3, duration=5.0)


@pytest.fixture(scope="module")
def appell_run() -> pinstab.Trajectory:
    return pinstab.simulate("appell-plate", method="baumgarte", integrator="rk4", dt=1e-3, duration=5.0)


# -- parallel homing (7.1-7.3) -------------------------------------------------------------------------------


def homing_applied_forces(q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The applied forces [N] on m1 and on m2 (without the controls) at q = (x1, y1, z1, x2, y2, z2) [m]."""
    weight = np.array([0.0, 0.0, -GRAVITY])
    pursued = -K1 * q[:3] + M1 * weight
    offset = q[3:] - ANCHOR2
    length = np.linalg.norm(offset)
    direction = offset / length
    pursuer = -(K2 * length + C2 * direction @ v[3:]) * direction + M2 * weight
    return pursued, pursuer


def homing_controls(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Closed form (7.3) with m1 r1'' = F1: (u_y, u_z) = (m2/m1) (Y1, Z1) - (Y2, Z2)_applied [N]."""
    pursued, pursuer = homing_applied_forces(q, v)
    return M2 / M1 * pursued[1:] - pursuer[1:]


def test_homing_controls_are_the_dynamic_conditions_7_3(homing_run):
    controls = homing_run.servo_figures["controls"]
    expected = np.array([homing_controls(q, v) for q, v in zip(homing_run.q, homing_run.v, strict=True)])
    assert homing_run.t[-1] == pytest.approx(5.0)
    assert np.abs(controls - expected).max() <= 1e-9  # [N], acceptance line
    assert np.abs(expected).max() > 0.5  # the controls do work: a zero control would fail above
    assert homing_run.summary()["max_servo_error"] <= 1e-9  # [m] y2 - y1, z2 - z1


def test_homing_equations_of_motion_7_2(homing_run):
    """m1 r1'' = F1 (the pursued point is free), m2 x2'' = X2; m2 y2'' = Y2 + u_y; zero servo reactions."""
    system = pinstab.build_system(pinstab.load_scene("homing"), "baumgarte")
    for q, v, t in zip(homing_run.q[::500], homing_run.v[::500], homing_run.t[::500], strict=True):
        evaluation = system.dynamics(q, v, t)
        pursued, pursuer = homing_applied_forces(q, v)
        acceleration = evaluation.acceleration
        np.testing.assert_allclose(M1 * acceleration[:3], pursued, rtol=0, atol=1e-10)
        np.testing.assert_allclose(M2 * acceleration[3], pursuer[0], rtol=0, atol=1e-10)
        np.testing.assert_allclose(M2 * acceleration[4:], pursuer[1:] + evaluation.controls, rtol=0, atol=1e-10)
        np.testing.assert_array_equal(evaluation.multipliers, 0.0)


def test_the_pursued_point_oscillates_as_if_alone(homing_run):
    """m1 on its spring under gravity: r1(t) = r_eq + (r1(0) - r_eq) cos(w t) + r1'(0)/w sin(w t), w = 2 rad/s."""
    omega = math.sqrt(K1 / M1)
    rest = np.array([0.0, 0.0, -M1 * GRAVITY / K1])
    q0, v0 = homing_run.q[0, :3], homing_run.v[0, :3]
    t = homing_run.t[:, None]
    expected = rest + (q0 - rest) * np.cos(omega * t) + v0 / omega * np.sin(omega * t)
    assert np.abs(homing_run.q[:, :3] - expected).max() <= 1e-10  # [m], RK4 at 1 ms over 5 s (2.8e-12 measured)
    np.testing.assert_allclose(homing_run.q[:, 4:], homing_run.q[:, 1:3], rtol=0, atol=1e-9)


# -- Appell's plate on a rotating disk (7.4-7.6) -------------------------------------------------------------


def plate_inertia_term() -> float:
    """M (b^2 + k^2) [kg m^2]: the plate's inertia about C."""
    return PLATE_MASS * B**2 + PLATE_INERTIA


def appell_alpha_acceleration(alpha: float, rate: float) -> float:
    """alpha'' [rad/s^2] from the dynamic condition 7.6: M (b^2 + k^2) alpha'' - M R b alpha'^2 = F a cos alpha."""
    return (F * A * math.cos(alpha) + PLATE_MASS * R * B * rate**2) / plate_inertia_term()


def appell_control(alpha: float, rate: float, disk_inertia: float = DISK_INERTIA) -> float:
    """u [N m] from the equation of motion 7.5 with alpha'' from 7.6."""
    total = PLATE_MASS * R**2 + plate_inertia_term() + disk_inertia
    return total * appell_alpha_acceleration(alpha, rate) + F * (R * math.sin(alpha) - A * math.cos(alpha))


def appell_reference(t: np.ndarray) -> np.ndarray:
    """beta(t) [rad] of Appell's equation 7.6, M (b^2+k^2) beta'' - M R b beta'^2 + F a sin beta = 0, to 1e-12."""

    def rates(_, state):
        beta, rate = state
        return [rate, (PLATE_MASS * R * B * rate**2 - F * A * math.sin(beta)) / plate_inertia_term()]

    solution = solve_ivp(rates, (0.0, t[-1]), [BETA0, 0.0], method="DOP853", rtol=1e-13, atol=1e-13, t_eval=t)
    return solution.y[0]


def test_appell_control_is_7_5_with_7_6_over_5_s(appell_run):
    alpha, rate = appell_run.q[:, 0], appell_run.v[:, 0]
    expected = np.array([appell_control(a, w) for a, w in zip(alpha, rate, strict=True)])
    controls = appell_run.servo_figures["controls"][:, 0]
    assert appell_run.t[-1] == pytest.approx(5.0)
    assert np.abs(controls - expected).max() <= 1e-8  # [N m], acceptance line
    assert np.ptp(expected) > 1.0  # [N m]: the control varies over the run
    np.testing.assert_allclose(appell_run.q[:, 1], -math.pi / 2, rtol=0, atol=1e-12)  # alpha - beta = pi/2


def test_appell_motion_follows_7_6(appell_run):
    beta = appell_run.q[:, 0] + appell_run.q[:, 1]
    reference = appell_reference(appell_run.t)
    assert np.abs(beta - reference).max() <= 1e-10  # [rad], RK4 at 1 ms over 5 s (2.3e-12 measured)
    assert np.ptp(reference) > 0.5  # [rad]: the plate swings


def _appell_variant(disk_inertia: float | None = None, as_closure: bool = False) -> pinstab.Scene:
    """The bundled plate with another disk inertia I1 [kg m^2], or with the servo made a real constraint
    (Appell's direct tangency between plate and disk; no actuation)."""
    data = tomllib.loads((ROBOTS / "appell-plate.toml").read_text())
    urdf = (ROBOTS / "urdf" / "appell-plate.urdf").read_text()
    if disk_inertia is not None:  # the transverse moments follow (a thin disk: half each), so it stays a rigid body
        urdf = re.sub(
            r'ixx="[^"]*"(.*?)iyy="[^"]*"(.*?)izz="0.54"',
            lambda m: (
                f'ixx="{disk_inertia / 2!r}"{m.group(1)}iyy="{disk_inertia / 2!r}"{m.group(2)}izz="{disk_inertia!r}"'
            ),
            urdf,
            count=1,
        )
    data["robot"] = {"urdf_text": urdf}
    if as_closure:
        data["closures"] = data.pop("servos")
        del data["actuation"]
    return scene_from_dict(data, name="appell-variant", base_dir=ROBOTS)


def test_appell_equation_is_the_condition_of_fulfilment_not_the_equation_of_motion():
    """Under the servo, alpha'' follows 7.6 whatever I1 (7.6 is free of u and I1) and u takes up I1's
    change through 7.5; under a real constraint (no control) alpha'' follows 7.5 with u = 0, and 7.6 fails."""
    alpha0 = BETA0 + math.pi / 2
    q, v = np.array([alpha0, -math.pi / 2]), np.array([0.7, 0.0])
    condition = appell_alpha_acceleration(alpha0, 0.7)
    for disk_inertia in (DISK_INERTIA, 5.0):
        evaluation = pinstab.build_system(_appell_variant(disk_inertia), "baumgarte").dynamics(q, v, 0.0)
        assert evaluation.acceleration[0] == pytest.approx(condition, abs=1e-12)
        assert evaluation.controls[0] == pytest.approx(appell_control(alpha0, 0.7, disk_inertia), abs=1e-12)
        assert evaluation.multipliers[0] == 0.0
    tangency = pinstab.build_system(_appell_variant(as_closure=True), "baumgarte").dynamics(q, v, 0.0)
    total = PLATE_MASS * R**2 + plate_inertia_term() + DISK_INERTIA
    appell_4 = -F * (R * math.sin(alpha0) - A * math.cos(alpha0)) / total
    assert tangency.acceleration[0] == pytest.approx(appell_4, abs=1e-12)
    assert abs(tangency.acceleration[0] - condition) > 0.5  # [rad/s^2] (0.94 here): the motions differ
    assert abs(tangency.multipliers[0]) > 0.1  # [N m]: the contact reacts; the servo's reaction is zero


# -- the ring on a rod (7e) ----------------------------------------------------------------------------------


@pytest.mark.parametrize("rate", [0.0, 1.5, -4.0])
def test_the_ring_cannot_be_kept_on_the_circle(rate):
    scene = pinstab.load_scene("ring-on-rod")
    system = pinstab.build_system(scene, "baumgarte")
    with pytest.raises(ServoInfeasibleError) as caught:
        system.dynamics(np.array([0.3, RADIUS]), np.array([rate, 0.0]), 0.0)
    assert caught.value.constraints == ["keep-radius"]
    np.testing.assert_allclose(np.abs(caught.value.direction), [1.0], atol=1e-12)
    assert caught.value.time == 0.0


@pytest.mark.parametrize("torque", [-50.0, 0.0, 50.0])
def test_the_rod_torque_does_not_reach_the_ring_radius(torque):
    """r'' = c alpha'^2 + F/m > 0 whatever the torque: keeping r = c would need -m c alpha'^2 = F [K 7e]."""
    model = pinstab.load_scene("ring-on-rod").model
    data = model.createData()
    rate = 1.5
    acceleration = pin.aba(model, data, np.array([0.3, RADIUS]), np.array([rate, 0.0]), np.array([torque, PULL]))
    assert acceleration[1] == pytest.approx(RADIUS * rate**2 + PULL / RING_MASS, abs=1e-12)


def test_cli_servo_check_of_ring_on_rod_exits_2_naming_the_servo(capsys):
    assert main(["servo", "ring-on-rod", "--check"]) == 2
    message = capsys.readouterr().err
    assert "'keep-radius' cannot be realized at t = 0 s" in message
    assert "no control reaches the direction" in message and "keep-radius[0]" in message
    assert "rank 0 < 1" in message and "controls: rod" in message


def test_the_centrifugal_reading_is_a_sign_limit():
    """Kirgetov's reading of 7e: the rod acts on r only through m r alpha'^2 >= 0. As a radial control with
    lower = 0 the servo needs it at -F: the limit message names the control, its bounds and the servo."""
    data = tomllib.loads((ROBOTS / "ring-on-rod.toml").read_text())
    data["robot"]["urdf"] = str(ROBOTS / "urdf" / "ring-on-rod.urdf")
    data["actuation"] = {"matrix": [[0.0], [1.0]], "names": ["centrifugal"], "lower": [0.0]}
    scene = scene_from_dict(data, name="ring-centrifugal")
    system = pinstab.build_system(scene, "baumgarte")
    with pytest.raises(ServoInfeasibleError, match=r"'keep-radius'.*within the control limits") as caught:
        system.dynamics(np.array([0.0, RADIUS]), np.zeros(2), 0.0)  # at rest: no centrifugal term yet
    assert "centrifugal = -2 outside [0, inf]" in str(caught.value)


# -- the realizable scenes through the CLI ------------------------------------------------------------------


def test_cli_servo_check_of_the_realizable_scenes(capsys):
    assert main(["servo", "appell-plate", "--check", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    alpha0 = BETA0 + math.pi / 2
    assert report["controls_at_start"]["disk"] == pytest.approx(appell_control(alpha0, 0.0), abs=1e-12)
    assert main(["servo", "homing", "--check", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    scene = pinstab.load_scene("homing")
    expected = homing_controls(scene.q0, scene.v0)
    assert [report["controls_at_start"][n] for n in ("y2", "z2")] == pytest.approx(expected, abs=1e-12)
    np.testing.assert_allclose(report["decoupling_singular_values"], [1 / M2, 1 / M2], rtol=1e-12)
