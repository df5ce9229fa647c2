"""The actuators of an MJCF file as MuJoCo reads them, each a ``joint-actuator`` force element
(:mod:`pinstab.forces.joint_actuator`) named as the actuator (``actuator<i>`` when unnamed): ``<motor>``,
``<position>`` (``kp``, ``kv``), ``<velocity>`` (``kv``) and ``<general>`` with a fixed gain, no or an affine bias and
no activation dynamics, on a 1-DOF joint (``joint``), with their ``gear``, ``ctrlrange`` and ``forcerange``
(``ctrllimited``/``forcelimited``: ``auto`` limits a given range under ``<compiler autolimits>``).

The control of each is, in this order: the scene's ``robot.ctrl`` table (``{name = value}`` or ``{name = [[t, u],
...]}``), the start keyframe's ``ctrl``, MuJoCo's 0. Other actuators (on a tendon, a site or a body; cylinders,
muscles, adhesion, activation dynamics, ``dampratio``, ``inheritrange``) are not read: a note names each.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import SceneError, choices
from .mjcf_joints import limited_range
from .mjcf_xml import MjcfDocument

ACTUATOR_TAGS = ("general", "motor", "position", "velocity", "intvelocity", "damper", "cylinder", "muscle", "adhesion")
TRANSMISSIONS = ("tendon", "site", "body", "jointinparent", "cranksite")  # not read: noted
ZERO_WHEN_READ = ("dampratio", "timeconst", "inheritrange")  # a non-zero value is a law this reader does not hold


def read_actuators(
    document: MjcfDocument, joint_names: set[str], controls: Any, start_ctrl: np.ndarray | None, notes: list[str]
) -> list[dict[str, Any]]:
    """The file's actuators as ``joint-actuator`` scene entries (those not read noted in ``notes``), their controls
    from ``controls`` (``robot.ctrl``), else ``start_ctrl`` (a keyframe's, one per actuator of the file), else 0.

    Raises:
        SceneError: ``robot.ctrl`` not a table, naming an actuator the file does not have (the actuators listed),
            or given for one that is not read; a bad number, range or joint of an actuator (named).
    """
    actuators = [item for section in document.root.findall("actuator") for item in section]
    names = [item.get("name") or f"actuator{index}" for index, item in enumerate(actuators)]
    if controls is None:
        controls = {}
    if not isinstance(controls, dict):
        raise SceneError(f"robot.ctrl must be a table of actuator names to controls, got {controls!r}")
    unknown = sorted(set(controls) - set(names))
    if unknown:
        raise SceneError(
            f"robot.ctrl: {', '.join(map(repr, unknown))} not an actuator of {document.path}; {choices(names)}"
        )
    entries, left = [], []
    for index, (element, name) in enumerate(zip(actuators, names, strict=True)):
        where = f"robot.mjcf actuator {name!r}"
        law = _law(document, element, joint_names, where)
        if isinstance(law, str):
            if name in controls:
                raise SceneError(f"robot.ctrl.{name}: the actuator is not read ({law})")
            left.append(f"{name!r} ({law})")
            continue
        entry = {"name": name, "kind": "joint-actuator", **law}
        control = controls.get(name, 0.0 if start_ctrl is None else float(start_ctrl[index]))
        entry |= {"table": control} if isinstance(control, list) else {"ctrl": control}
        entries.append(entry)
    if left:
        notes.append(f"actuators not read (no force in the run): {', '.join(left)}")
    return entries


@dataclass
class _Actuator:
    """MuJoCo's actuator as its XML reader builds it: one per ``<default>`` class, which every actuator element of
    the class (``<motor>``, ``<position>``, ... alike) edits in turn, then copied and edited by each actuator element.

    Attributes:
        gain: ``gainprm[0]``. bias: ``biasprm[:3]``. types: (dyntype, gaintype, biastype). attributes: the plain
            attributes given so far (gear, ranges, limits, transmission).
    """

    gain: float = 1.0
    bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    types: tuple[str, str, str] = ("none", "fixed", "none")
    attributes: dict[str, str] = field(default_factory=dict)

    def edited(self, element: ET.Element, where: str) -> _Actuator:
        """This actuator edited by ``element`` as MuJoCo's reader edits it: a shortcut sets its law from its own
        ``kp``/``kv``, else from the gain and bias it finds (a ``<position>`` default's kp is its servos' kp)."""
        own = {key: value for key, value in element.attrib.items() if key not in ("class", "name")}

        def number(key: str, default: float) -> float:
            try:
                value = float(own[key]) if key in own else default
            except ValueError:
                raise SceneError(f"{where}: {key}={own[key]!r} is not a number") from None
            if not np.isfinite(value):
                raise SceneError(f"{where}: {key}={own[key]!r} is not finite")
            return value

        edited = _Actuator(self.gain, self.bias, self.types, self.attributes | own)
        if element.tag == "motor":
            edited.gain, edited.bias, edited.types = 1.0, (0.0, 0.0, 0.0), ("none", "fixed", "none")
        elif element.tag == "position":
            kp, kv = number("kp", self.gain), number("kv", -self.bias[2] if self.bias[2] < 0 else 0.0)
            edited.gain, edited.bias, edited.types = kp, (0.0, -kp, -kv), ("none", "fixed", "affine")
        elif element.tag == "velocity":
            kv = number("kv", self.gain)
            edited.gain, edited.bias, edited.types = kv, (0.0, 0.0, -kv), ("none", "fixed", "affine")
        elif element.tag == "general":
            keys = ("dyntype", "gaintype", "biastype")
            types = (own.get(keys[0], self.types[0]), own.get(keys[1], self.types[1]), own.get(keys[2], self.types[2]))
            gains = _parameters(own["gainprm"], "gainprm", where) if "gainprm" in own else [self.gain, 0.0, 0.0]
            biases = _parameters(own["biasprm"], "biasprm", where) if "biasprm" in own else list(self.bias)
            edited.gain, edited.bias, edited.types = gains[0], (biases[0], biases[1], biases[2]), types
        else:
            edited.types = (f"<{element.tag}>", "", "")
        return edited


def _law(document: MjcfDocument, element: ET.Element, joint_names: set[str], where: str) -> dict[str, Any] | str:
    """The ``joint-actuator`` keys of ``element`` (joint, gear, gain, bias, ranges), or why it is not read."""
    actuator = _Actuator()
    for default in document.default_chain(element):
        for item in default:
            if item.tag in ACTUATOR_TAGS:
                actuator = actuator.edited(item, f"{where} (its <default>)")
    actuator = actuator.edited(element, where)
    if actuator.types[0].startswith("<"):
        return actuator.types[0]
    if actuator.types != ("none", "fixed", actuator.types[2]) or actuator.types[2] not in ("none", "affine"):
        return "dyntype {}, gaintype {}, biastype {}".format(*actuator.types)
    attributes = actuator.attributes
    transmission = next((key for key in TRANSMISSIONS if key in attributes), None)
    if transmission is not None:
        return f"on a {transmission}"
    for key in ZERO_WHEN_READ:
        if _parameters(attributes.get(key, "0"), key, where)[0] != 0.0:
            return key
    joint = attributes.get("joint")
    if joint is None:
        return "no joint"
    if joint not in joint_names:
        raise SceneError(
            f"{where}: joint {joint!r} is not a 1-DOF joint of the model; 1-DOF joints: {choices(joint_names)}"
        )
    bias = list(actuator.bias) if actuator.types[2] == "affine" else [0.0, 0.0, 0.0]
    gear = _parameters(attributes.get("gear", "1"), "gear", where)[0]  # a joint takes the first of its 6
    law: dict[str, Any] = {"joint": joint, "gear": gear, "gain": actuator.gain, "bias": bias}
    for flag, key in (("ctrllimited", "ctrlrange"), ("forcelimited", "forcerange")):
        declared = limited_range(document, element, flag, key, where, attributes)
        if declared is not None:
            law[key] = list(declared)
    return law


def _parameters(text: str, key: str, where: str) -> list[float]:
    """A parameter list of 1 to 10 numbers, padded with zeros to 3 (MuJoCo's ``gainprm``, ``biasprm``, ``gear``)."""
    try:
        values = [float(x) for x in text.split()]
    except ValueError:
        raise SceneError(f"{where}: {key}={text!r} is not a list of numbers") from None
    if not values or len(values) > 10 or not np.all(np.isfinite(values)):
        raise SceneError(f"{where}: {key}={text!r} is not 1 to 10 finite numbers")
    return values + [0.0] * max(0, 3 - len(values))
