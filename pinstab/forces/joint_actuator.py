"""``joint-actuator``: MuJoCo's actuator on a joint (``<motor>``, ``<position>``, ``<velocity>``, or ``<general>``
with a fixed gain and an affine bias, no activation dynamics), driven by a control input given as a constant or a
time table.

With the control ``u`` (clipped to ``ctrlrange`` when given), the actuator's length ``l = gear q`` and velocity
``ldot = gear qdot``, the actuator force is ``f = gain u + bias_0 + bias_1 l + bias_2 ldot`` (clipped to
``forcerange`` when given) and the joint gets ``gear f`` [N m or N] — MuJoCo's law (``mj_fwdActuation``): a motor
is gain 1, bias 0; a position servo gain ``kp``, bias ``(0, -kp, -kv)``; a velocity servo gain ``kv``, bias
``(0, 0, -kv)``. Its work enters the run's energy balance as power ``tau . v``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import SceneError
from ..kernels import CompiledTarget
from ..kinematics import Kinematics
from ..tables import SceneTables, vector
from .base import FORCE_KINDS, ForceElement, bounded_load
from .time_table import TimeTable, read_table

ACTUATOR_KEYS = {"name", "kind", "joint", "gear", "gain", "bias", "ctrl", "table", "ctrlrange", "forcerange"}
UNLIMITED = (-np.inf, np.inf)
Values = float | np.ndarray  # one actuator's number, or an array of one per actuator


class JointActuator(ForceElement):
    """A joint actuator with MuJoCo's affine law (see the module).

    Args:
        name: element name. dof: the joint's velocity index. q_index: its configuration index. nv: the model's
            velocity dimension. gear: [-] (the length is gear q). gain: [N or N m per control unit]. bias:
            (bias_0 [N], bias_1 [N/m or N/rad of length], bias_2 [N s/m or N s/rad of length]). control: the
            control input u(t). ctrlrange: (low, high) the control is clipped to. forcerange: (low, high) [N or
            N m] the actuator force is clipped to.
    """

    def __init__(
        self,
        name: str,
        dof: int,
        q_index: int,
        nv: int,
        gear: float,
        gain: float,
        bias: np.ndarray,
        control: TimeTable,
        ctrlrange: tuple[float, float] = UNLIMITED,
        forcerange: tuple[float, float] = UNLIMITED,
    ) -> None:
        self.name, self.dof, self.q_index, self.nv = name, dof, q_index, nv
        self.gear, self.gain, self.bias = gear, gain, np.asarray(bias, float)
        self.control, self.ctrlrange, self.forcerange = control, ctrlrange, forcerange
        self.needs_kinematics = bool(self.bias[1])  # reads kin.q

    def force(self, q: float, qdot: float, t: float) -> float:
        """The actuator force f [N or N m] at joint position q [rad or m], velocity qdot and time t [s]."""
        law = self.gear, self.gain, self.bias, self.ctrlrange, self.forcerange
        return float(actuator_force(self.control(t), q, qdot, *law))

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        tau = np.zeros(self.nv)
        q = float(kin.q[self.q_index]) if self.bias[1] else 0.0
        tau[self.dof] = self.gear * self.force(q, float(v[self.dof]), t)
        return tau

    @classmethod
    def batch(cls, elements: list[ForceElement]) -> ForceElement:
        """The actuators ``elements`` evaluated at once (:class:`JointActuators`)."""
        return JointActuators([element for element in elements if isinstance(element, JointActuator)])


class JointActuators(ForceElement):
    """Joint actuators evaluated at once: their control tables in one compiled evaluation, the law
    (:func:`actuator_force`) over arrays, each actuator's ``gear f`` added to its joint's coordinate in their order.

    Args:
        actuators: the actuators (at least one), of one model.
    """

    def __init__(self, actuators: list[JointActuator]) -> None:
        self.name = ", ".join(actuator.name for actuator in actuators)
        self.nv = actuators[0].nv
        self.dofs = np.array([actuator.dof for actuator in actuators])
        self.gear = np.array([actuator.gear for actuator in actuators])
        self.gain = np.array([actuator.gain for actuator in actuators])
        self.bias = np.array([actuator.bias for actuator in actuators]).T  # (3, n): bias_0, bias_1, bias_2
        self.ctrlrange = np.array([actuator.ctrlrange for actuator in actuators]).T  # (2, n): low, high
        self.forcerange = np.array([actuator.forcerange for actuator in actuators]).T
        self.reading = np.flatnonzero(self.bias[1])  # the actuators whose force reads their joint's position
        self.q_indices = np.array([actuators[i].q_index for i in self.reading], dtype=int)
        self.needs_kinematics = bool(self.reading.size)
        self._controls = CompiledTarget([actuator.control.compiled() for actuator in actuators])

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        q = np.zeros(self.dofs.size)
        q[self.reading] = kin.q[self.q_indices]
        law = self.gear, self.gain, self.bias, self.ctrlrange, self.forcerange
        forces = actuator_force(self._controls.evaluate(t)[0], q, v[self.dofs], *law)
        return np.bincount(self.dofs, weights=self.gear * forces, minlength=self.nv)


def actuator_force(
    control: Values,
    q: Values,
    qdot: Values,
    gear: Values,
    gain: Values,
    bias: np.ndarray,
    ctrlrange: tuple[Values, Values] | np.ndarray,
    forcerange: tuple[Values, Values] | np.ndarray,
) -> Values:
    """MuJoCo's affine actuator force f [N or N m] (the module's law), elementwise over arrays of actuators or for
    one: the control clipped to ``ctrlrange`` (low, high), ``f = gain u + bias_0 + bias_1 gear q + bias_2 gear qdot``
    at joint position q [rad or m] and velocity qdot [rad/s or m/s], clipped to ``forcerange`` (low, high) [N or N m].
    """
    u = np.minimum(np.maximum(control, ctrlrange[0]), ctrlrange[1])
    f = gain * u + bias[0] + bias[1] * gear * q + bias[2] * gear * qdot
    return np.minimum(np.maximum(f, forcerange[0]), forcerange[1])


def _range(entry: dict, key: str, where: str) -> tuple[float, float]:
    if key not in entry:
        return UNLIMITED
    low, high = vector(entry[key], 2, f"{where}.{key}", None)
    if not low <= high:
        raise SceneError(f"{where}.{key}: the low end {low:g} is above the high end {high:g}")
    return float(low), float(high)


@FORCE_KINDS.register("joint-actuator", summary="MuJoCo's actuator on a 1-DOF joint (motor, position, velocity)")
def parse_joint_actuator(entry: dict[str, Any], tables: SceneTables, name: str, where: str) -> JointActuator:
    """Scene table: ``joint``; ``gear`` (default 1), ``gain`` (default 1), ``bias`` (3 numbers, default 0); the
    control ``ctrl`` (a constant) or ``table`` ([[t, ctrl], ...]); optional ``ctrlrange`` and ``forcerange`` ([low,
    high]). Gains, biases and forces at most 1e12 in magnitude."""
    tables.check_keys(entry, ACTUATOR_KEYS, where)
    model = tables.model
    joint = model.joints[tables.joint_id(entry.get("joint"), f"{where}.joint")]
    if joint.nv != 1:
        raise SceneError(f"{where}: joint {entry['joint']!r} has {joint.nv} DOF; an actuator needs a 1-DOF joint")
    gear, gain = tables.number(entry, "gear", where, 1.0), tables.number(entry, "gain", where, 1.0)
    bias = vector(entry.get("bias", [0.0, 0.0, 0.0]), 3, f"{where}.bias", None)
    for value, what in ((gear, "gear"), (gain, "gain"), *((b, f"bias[{k}]") for k, b in enumerate(bias))):
        bounded_load(value, f"{where}.{what}", "SI")
    times, values = read_table(entry, tables, "ctrl", None, where)
    control = TimeTable(f"joint-actuator '{name}'", times, values)
    return JointActuator(
        name,
        joint.idx_v,
        joint.idx_q,
        model.nv,
        gear,
        gain,
        bias,
        control,
        _range(entry, "ctrlrange", where),
        _range(entry, "forcerange", where),
    )
