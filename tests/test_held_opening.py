"""Held contacts that open during a run (issue 34): a held frictionless contact whose point leaves its plane is left
out of the dynamics (no force, no work) while it is open, and a run whose open contact comes back to its plane at
speed stops there (an impact, which held rows do not model: ContactInfeasibleError, exit 5, what was computed kept).

The case: a 0.056 kg ball of radius r = 0.01 m whose one frictionless contact is its body point (0, 0, -r), spun at
w = 50 rad/s about x. The spin lifts the point off at once (its acceleration along the normal w^2 r - g = 15.2 m/s^2
> 0): the ball falls freely, centre z = r - g t^2 / 2, the point's gap r - g t^2 / 2 - r cos(w t) back at 0 at
t = 0.0638350 s. Held, its row pushed the point back on its way down: 0.00829 J -> 0.01681 J with exit 0."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
from fuzzing import cli, mechanical_energy, toml_document
from scipy.optimize import brentq

from pinstab import ContactInfeasibleError, simulate
from pinstab.constraints import ConstraintValues
from pinstab.generators import painleve_rod
from pinstab.scene import scene_from_dict
from pinstab.solvers.impacts import REST_SPEED
from pinstab.system import OpenRows, build_system

GRAVITY, RADIUS, SPIN, DT = 9.81, 0.01, 50.0, 1e-3
SPINNING = {
    "gravity": [0.0, 0.0, -GRAVITY],
    "robot": {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"},
    "objects": [{"name": "crate", "shape": "sphere", "radius": RADIUS, "mass": 0.056, "position": [0.0, 0.0, RADIUS]}],
    "contacts": [{"name": "c0", "kind": "plane-contact", "frame_a": "crate", "offset_a": [0.0, 0.0, -RADIUS]}],
    "initial": {"v": {"crate": [0.0, 0.0, 0.0, SPIN, 0.0, 0.0]}},
}
CLOSING = brentq(lambda t: RADIUS - 0.5 * GRAVITY * t**2 - RADIUS * np.cos(SPIN * t), 0.03, 0.07)  # 0.0638350 s


def free_flight(t: float) -> tuple[np.ndarray, np.ndarray]:
    """The ball's (q, v) at t [s] in free flight: centre falling from r, spin constant (v in body axes)."""
    turn = pin.exp3(np.array([SPIN * t, 0.0, 0.0]))
    q = np.r_[0.0, 0.0, RADIUS - 0.5 * GRAVITY * t**2, pin.Quaternion(turn).coeffs()]
    return q, np.r_[turn.T @ np.array([0.0, 0.0, -GRAVITY * t]), SPIN, 0.0, 0.0]


def stopped_run(scene, **options):
    """The run of ``scene`` to 0.12 s, which must stop where the contact closes again: (the error, its run)."""
    with pytest.raises(ContactInfeasibleError, match=r"held contacts close again at t = 0\.06\d+ s: c0 at") as info:
        simulate(scene, contacts="held", duration=0.12, **options)
    return info.value, info.value.trajectory


def test_the_spinning_contact_stops_where_it_closes_again_with_its_energy(tmp_path: Path) -> None:
    """The issue's command: exit 5 naming the contact, the time and --contacts event; the JSON ends at the last
    grid time before the closed-form closing (0.063 s), its energy the start's to 1e-9 J (was +0.0085 J, exit 0)."""
    path = tmp_path / "mid.toml"
    path.write_text(toml_document(SPINNING), encoding="utf-8")
    outcome = cli(["run", str(path), "--contacts", "held", "--duration", "0.12", "--json"])
    assert outcome.code == 5, outcome
    assert "held contacts close again at t = 0.064 s: c0 at 0.657" in outcome.message
    assert "--contacts event" in outcome.message
    info = json.loads(outcome.out)
    assert info["t_end"] == pytest.approx(np.floor(CLOSING / DT) * DT, abs=1e-12)
    assert abs(info["energy_end"] - info["energy_start"]) <= 1e-9
    assert info["stopped"]["error"] == "ContactInfeasibleError"


def test_an_open_contact_exerts_no_force_the_ball_flies_as_the_closed_form() -> None:
    """rk4 at dt = 1e-3 s: the run up to the stop is the free flight to 1e-8 (measured 4.3e-9 rad; 4.4e-13 at
    dt = 1e-4 s, fourth order), the event-driven run's to 1e-8 (measured 4.4e-9), the contact's force 0 once released
    (1e-18 N at the start's solve); the error names the contact."""
    scene = scene_from_dict(SPINNING, "spinning")
    error, held = stopped_run(scene)
    assert error.contacts == ["c0"] and CLOSING < error.time <= CLOSING + DT
    flight = [free_flight(t) for t in held.t]
    worst = max(
        float(np.abs(pin.difference(scene.model, q, got)).max()) for (q, _), got in zip(flight, held.q, strict=True)
    )
    assert worst < 1e-8
    assert float(np.abs(held.v - np.array([v for _, v in flight])).max()) < 1e-7
    assert float(np.abs(held.multipliers[0]).max()) < 1e-15  # the start's solve: released (ProxQP's rounding)
    assert float(np.abs(held.multipliers[1:]).max()) == 0.0  # then left out
    event = simulate(scene, contacts="event", duration=0.12)
    assert [e["t"] for e in event.info.contact_events if e["to"] == "closing"][0] == pytest.approx(CLOSING, abs=1e-9)
    same = np.isin(np.round(event.t, 12), np.round(held.t, 12))
    assert int(same.sum()) == len(held.t)
    assert float(np.abs(event.q[same] - held.q).max()) < 1e-8


@pytest.mark.parametrize(
    ("options", "energy_error"),
    [
        ({"method": "projection"}, 1e-9),  # its post-step projection put the point back at rest: +0.019 J, exit 0
        ({"method": "post"}, 1e-9),
        ({"integrator": "heun"}, 2e-6),  # second order: 1.42e-6 J
        ({"integrator": "dopri5", "rtol": 1e-8}, 1e-9),  # error control: the stop at the closing time itself
    ],
)
def test_every_method_and_integrator_stops_at_the_closing(options: dict, energy_error: float) -> None:
    """Other methods and integrators stop there too, before the impact, the energy kept to the integrator's
    accuracy [J] (rk4, dopri5: 1.7e-10 J; heun 1.42e-6 J, of 0.0083 J)."""
    scene = scene_from_dict(SPINNING, "spinning")
    error, held = stopped_run(scene, **options)
    assert held.t[-1] <= CLOSING < error.time + 1e-9
    energy = mechanical_energy(scene, held.q, held.v)
    assert float(np.abs(energy - energy[0]).max()) <= energy_error


@pytest.mark.parametrize(("integrator", "dt"), [("rk4", 1e-3), ("rk4", 1e-2), ("euler", 1e-3)])
def test_a_loaded_frictionless_contact_stays_held(integrator: str, dt: float) -> None:
    """The painleve rod without friction: its end slides on the floor, pressed (5.9 N down to 1.9 N). Held rows drift
    at steps' starts up to 5e-4 m (euler) and ProxQP leaves them slack by 1e-8 relative: neither opens the contact
    (a threshold on the slack alone opened it at t = 0.032 s and stopped the run as an impact)."""
    data = painleve_rod(0.3)
    data["contacts"][0].pop("mu")
    run = simulate(scene_from_dict(data, "rod"), contacts="held", duration=0.3, integrator=integrator, dt=dt)
    assert run.t[-1] == pytest.approx(0.3) and float(run.multipliers.min()) > 1.8


def values(gap: float, rate: float) -> ConstraintValues:
    """One unilateral row's values: its gap [m] and its rate [m/s]."""
    return ConstraintValues(np.array([gap]), np.zeros((1, 6)), np.zeros(1), np.array([rate]), None)


@pytest.mark.parametrize(("speed", "stops"), [(REST_SPEED, False), (2 * REST_SPEED, True)])
def test_an_open_contact_back_at_the_rest_speed_is_held_again(speed: float, stops: bool) -> None:
    """The rule at its boundary: a released row is open while its gap is positive; back at its plane at REST_SPEED
    (at rest) it is held again, at twice that it stops the run. A step taken again from an earlier state starts from
    the rows open then."""
    scene = scene_from_dict(SPINNING, "spinning")
    opened = build_system(scene).opened
    assert isinstance(opened, OpenRows)
    assert not opened.begin(values(0.0, 0.0), 0.0).any()
    slack = SimpleNamespace(
        jacobian=np.eye(1, 6, 2), rhs=np.zeros(1), mass_matrix=np.eye(6), free_force=np.r_[0, 0, 5.0, 0, 0, 0]
    )
    opened.release(slack, SimpleNamespace(multipliers=np.zeros(1), acceleration=np.r_[0, 0, 5.0, 0, 0, 0]), 0.0)
    assert opened.rows.all()
    assert opened.begin(values(1e-3, -speed), 0.001).all() and opened.within(values(1e-3, -speed), 0.0015).all()
    if stops:
        with pytest.raises(ContactInfeasibleError, match=r"c0 at 2e-06 m/s"):
            opened.begin(values(0.0, -speed), 0.002)
    else:
        assert not opened.begin(values(0.0, -speed), 0.002).any()
    assert opened.begin(values(1e-3, 0.0), 0.001).all()  # again from t = 0.001 s: open then
    assert not opened.begin(values(0.0, 0.0), 0.0).any()  # and from the start: held
