"""A run's derived series computed in one compiled call (compiled rows: drift and energy; the native path:
multipliers), each against a per-sample computation: Pinocchio's own frame placements, frame velocities and energies,
pinstab's Python pass over the constraints, and Pinocchio's solve sample by sample."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pinstab import build_system, load_scene, simulate
from pinstab.errors import PenetrationWarning
from pinstab.series import ClosureSeries, StateSeries

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
EPS = np.finfo(float).eps
# planar-point; on the world (bricard); a motor and a damper, which store no energy (slider-crank)
SCENES = [("fourbar", {}), ("nfourbar", {"N": 3}), ("bricard", {}), ("slider-crank", {})]


def pinocchio_series(model: pin.Model, closures, q: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """max |phi| [m], max |G v| [m/s] and the energy [J] at (q, v) from Pinocchio's frame placements, frame velocities
    (LOCAL_WORLD_ALIGNED) and energy functions: the closures' point differences and their rates."""
    data = model.createData()
    pin.forwardKinematics(model, data, q, v)
    pin.updateFramePlacements(model, data)
    phi, rate = [], []
    for closure in closures:
        point_b, speed_b = closure.world_placement_b.translation, np.zeros(3)
        if closure.frame_b is not None:
            point_b = data.oMf[closure.frame_b].translation
            speed_b = pin.getFrameVelocity(model, data, closure.frame_b, LWA).linear
        phi.append(closure.selection @ (data.oMf[closure.frame_a].translation - point_b))
        rate.append(closure.selection @ (pin.getFrameVelocity(model, data, closure.frame_a, LWA).linear - speed_b))
    energy = pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(model, data, q)
    return float(np.abs(np.concatenate(phi)).max()), float(np.abs(np.concatenate(rate)).max()), float(energy)


@pytest.mark.parametrize(("name", "parameters"), SCENES)
def test_compiled_series_equal_pinocchio_sample_by_sample(name, parameters):
    """The compiled drift and energy of a run equal, at every sample, Pinocchio's own point positions and energies
    to 4 ulp of the mechanism's size [m] and of the energy [J], and its point velocities to 64 ulp of the largest
    point speed [m/s]; and pinstab's Python pass over the constraints to the last bit (position drift, energy)."""
    trajectory = simulate(load_scene(name, **parameters), duration=0.2)
    series = trajectory._series
    assert isinstance(series, StateSeries) and series._closures is not None
    model = series.system.model
    closures = model.constraints.constraints
    size = max(1.0, model.length_scale)
    states = zip(trajectory.q, trajectory.v, strict=True)
    expected = np.array([pinocchio_series(model.model, closures, q, v) for q, v in states])
    speed = max(1.0, float(np.abs(trajectory.v).max()) * size)
    np.testing.assert_allclose(trajectory.position_drift, expected[:, 0], rtol=0, atol=4 * EPS * size)
    np.testing.assert_allclose(trajectory.velocity_drift, expected[:, 1], rtol=0, atol=64 * EPS * speed)
    np.testing.assert_allclose(trajectory.energy, expected[:, 2], rtol=4 * EPS, atol=0)
    python = np.array(
        [
            (*model.violation(q, v, t), model.energy(q, v))
            for t, q, v in zip(trajectory.t, trajectory.q, trajectory.v, strict=True)
        ]
    )
    assert np.array_equal(trajectory.position_drift, python[:, 0])
    assert np.array_equal(trajectory.energy, python[:, 2])
    np.testing.assert_allclose(trajectory.velocity_drift, python[:, 1], rtol=0, atol=64 * EPS * speed)
    assert trajectory.position_drift.max() > 0 and trajectory.velocity_drift.max() > 0  # not a vacuous comparison


# welds (delta, dual-panda-box), joint relations with moving targets (double-pendulum-servo, ring-on-rod), fingertip
# contacts with and without rotation rows (allegro-sphere, allegro-box), under a tilting gravity (allegro-tilt)
COMPILED_ROWS = ["delta", "dual-panda-box", "double-pendulum-servo", "ring-on-rod", "allegro-sphere", "allegro-box",
                 "allegro-tilt"]  # fmt: skip


@pytest.mark.parametrize("name", COMPILED_ROWS)
def test_compiled_series_of_every_row_kind_equal_the_python_pass(name):
    """At random states and times of scenes of compiled rows other than point closures: the compiled position drift
    and energy are pinstab's Python pass over the constraints (``violation``, ``energy``) to the last bit, the velocity
    drift to 16 ulp of the largest."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PenetrationWarning)  # allegro-box's start: the rows hold anywhere
        model = build_system(load_scene(name)).model
    series = ClosureSeries.of(model)
    assert series is not None
    rng = np.random.default_rng(5)
    q = np.array([pin.integrate(model.model, model.scene.q0, 0.2 * rng.standard_normal(model.nv)) for _ in range(6)])
    v, t = rng.standard_normal((6, model.nv)), rng.uniform(0.0, 2.0, 6)
    compiled = series.drift_and_energy(q, v, t)
    python = np.array([(*model.violation(q[k], v[k], t[k]), model.energy(q[k], v[k])) for k in range(6)])
    assert np.array_equal(compiled["position_drift"], python[:, 0])
    assert np.array_equal(compiled["energy"], python[:, 2])
    speed = python[:, 1].max()
    np.testing.assert_allclose(compiled["velocity_drift"], python[:, 1], rtol=0, atol=16 * EPS * speed)
    assert python[:, 0].min() > 0 and speed > 0  # off the constraints, moving: not a comparison of zeros


def test_compiled_series_are_nan_at_non_finite_samples_and_left_to_python_with_springs(tmp_path):
    """A non-finite sample gives NaN (as the Python pass); a scene with a spring (its potential energy), one with rows
    without compiled form (a rolling disk) and one with unilateral rows (a bouncing ball) are left to the Python
    pass."""
    trajectory = simulate("fourbar", duration=0.01)
    closures = ClosureSeries(trajectory._series.system.model)
    q, v = trajectory.q.copy(), trajectory.v.copy()
    q[3, 0] = np.nan
    v[5, 1] = np.inf
    series = closures.drift_and_energy(q, v, trajectory.t)
    for values in series.values():
        assert np.isnan(values[[3, 5]]).all() and np.isfinite(np.delete(values, [3, 5])).all()
    robots = Path(__file__).resolve().parents[1] / "robots"
    sprung = (robots / "slider-crank.toml").read_text().replace("stiffness = 0.0", "stiffness = 50.0")
    (tmp_path / "sprung.toml").write_text(sprung.replace('"urdf/', f'"{robots}/urdf/'))
    assert ClosureSeries.of(build_system(load_scene("slider-crank"), "baumgarte").model) is not None  # no spring
    assert ClosureSeries.of(build_system(load_scene(tmp_path / "sprung.toml"), "baumgarte").model) is None
    assert ClosureSeries.of(build_system(load_scene("rolling-disk"), "baumgarte").model) is None  # Python rows
    assert ClosureSeries.of(build_system(load_scene("bouncing-ball"), "baumgarte").model) is None  # unilateral


@pytest.mark.parametrize("scene", ["fourbar", "slider-crank"])
def test_native_multipliers_in_one_call_equal_pinocchio_sample_by_sample(scene):
    """On the native path the multipliers of every sample in one compiled call equal, to the last bit, those of
    Pinocchio's solve made sample by sample (``ConstrainedSystem.multipliers``: under Python's forces of the elements,
    the slider-crank's torque and damper, which the compiled call sums itself at each sample's time); NaN at a
    non-finite sample."""
    trajectory = simulate(scene, duration=0.3)
    series = trajectory._series
    system = series.system
    assert system.path == "native" and system.native.force_obstacle is None
    one_by_one = np.array(
        [system.multipliers(q, v, t) for t, q, v in zip(trajectory.t, trajectory.q, trajectory.v, strict=True)]
    )
    assert np.array_equal(trajectory.multipliers, one_by_one)
    assert np.abs(one_by_one).max() > 1.0  # the closure carries the links' weight [N]
    q = trajectory.q.copy()
    q[2] = np.nan
    forces = series.multipliers(trajectory.t, q, trajectory.v)
    assert np.isnan(forces[2]).all() and np.array_equal(np.delete(forces, 2, axis=0), np.delete(one_by_one, 2, axis=0))
