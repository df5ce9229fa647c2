"""``joint-actuator``: MuJoCo's actuator on a joint (``<motor>``, ``<position>``, ``<velocity>``, or ``<general>``
with a fixed gain and an affine bias, no activation dynamics), driven by a control input given as a constant or a
time table.

With the control ``u`` (clipped to ``ctrlrange`` when given), the actuator's length ``l = gear q`` and velocity
``ldot = gear qdot``, the actuator force is ``f = gain u + bias_0 + bias_1 l + bias_2 ldot`` (clipped to
``forcerange`` when given) and the joint gets ``gear f`` [N m or N] — MuJoCo's law (``mj_fwdActuation``): a motor
is gain 1, bias 0; a position servo gain ``kp``, bias ``(0, -kp, -kv)``; a velocity servo gain ``kv``, bias
``(0, 0, -kv)``. Its work enters the run's energy balance as power ``tau . v``. A model evaluates its actuators at
once (:class:`JointActuators`: their tables in one compiled evaluation, the law in one pass). The law is compiled
(``cpp/joint_actuators.hpp``), its one place.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import SceneError
from ..kernels import CompiledActuators
from ..kinematics import Kinematics
from ..tables import SceneTables, vector
from .base import FORCE_KINDS, ForceElement, bounded_load
from .time_table import TimeTable, read_table

ACTUATOR_KEYS = {"name", "kind", "joint", "gear", "gain", "bias", "ctrl", "table", "ctrlrange", "forcerange"}
UNLIMITED = (-np.inf, np.inf)


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
        self._law = compiled_law([self])

    def force(self, q: float, qdot: float, t: float) -> float:
        """The actuator force f [N or N m] at joint position q [rad or m], velocity qdot and time t [s]."""
        return float(self._law.forces(np.array([q]), np.array([qdot]), t)[0])

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        return self._law.generalized_force(kin.q, v, t)

    @classmethod
    def batch(cls, elements: list[ForceElement]) -> ForceElement:
        """The actuators ``elements`` evaluated at once (:class:`JointActuators`)."""
        return JointActuators([element for element in elements if isinstance(element, JointActuator)])


class JointActuators(ForceElement):
    """Joint actuators evaluated at once: their control tables in one compiled evaluation, the law over them in one
    pass (:func:`compiled_law`), each actuator's ``gear f`` added to its joint's coordinate in their order.

    Args:
        actuators: the actuators (at least one), of one model.
    """

    def __init__(self, actuators: list[JointActuator]) -> None:
        self.name = ", ".join(actuator.name for actuator in actuators)
        self.needs_kinematics = any(actuator.needs_kinematics for actuator in actuators)
        self._law = compiled_law(actuators)

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        return self._law.generalized_force(kin.q, v, t)


def compiled_law(actuators: list[JointActuator]) -> CompiledActuators:
    """The compiled law of ``actuators`` (``cpp/joint_actuators.hpp``, the one place of the module's law): their
    tables, joints (the position read where bias_1 is not zero), gears, gains, biases and ranges."""
    return CompiledActuators(
        [actuator.control.compiled() for actuator in actuators],
        np.array([actuator.dof for actuator in actuators], dtype=np.int32),
        np.array([actuator.q_index if actuator.bias[1] else -1 for actuator in actuators], dtype=np.int32),
        np.array([actuator.gear for actuator in actuators], dtype=float),
        np.array([actuator.gain for actuator in actuators], dtype=float),
        np.array([actuator.bias for actuator in actuators], dtype=float).T.reshape(3, -1),
        np.array([actuator.ctrlrange for actuator in actuators], dtype=float).T.reshape(2, -1),
        np.array([actuator.forcerange for actuator in actuators], dtype=float).T.reshape(2, -1),
        actuators[0].nv,
    )


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
