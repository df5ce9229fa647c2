"""Contact models [MLS ch. 5]: the wrench components a contact transmits (``frictionless`` 1, ``point-friction``
3, ``soft-finger`` 4, ``rigid`` 6, in the contact frame C: force first, then moment) and what it can carry
(a normal force that pushes, a tangential force inside the round friction cone, a soft finger's torsion)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..errors import GraspLostError
from ..kernels import contact_holds, contact_margins

WRENCH_BASES = {
    "frictionless": np.array([[0, 0, 1, 0, 0, 0]], dtype=float).T,
    "point-friction": np.eye(6)[:, :3],
    "soft-finger": np.eye(6)[:, [0, 1, 2, 5]],
    "rigid": np.eye(6),
}
"""B_c per contact model: the wrench components (fx, fy, fz, mx, my, mz in C) the contact transmits."""

CONTACT_MODEL_CODES = {"frictionless": 0, "point-friction": 1, "soft-finger": 2, "rigid": 3}
"""Each contact model's code in the compiled core (``cpp/grasp_forces.hpp`` ContactModel)."""

FRICTION_MODELS = ("point-friction", "soft-finger")
MARGIN_SLACK = 1e-9  # relative: a margin above -slack (1 + |force|) holds (rounding in the solve)


class ContactLimits(NamedTuple):
    """What a fingertip contact of a contact ``model`` can carry: a normal force that pushes, a tangential
    force inside the friction cone (mu [-]) and, for a soft finger, a moment about the normal within
    ``torsion`` [m] times the normal force. ``contact``, ``finger_name`` and ``object_name`` name it in
    messages."""

    contact: str
    model: str
    mu: float
    torsion: float
    finger_name: str
    object_name: str

    def margins(self, wrench: np.ndarray) -> dict[str, float]:
        """How far ``wrench`` (fx, fy, fz, mx, my, mz of the finger on the object in C [N, N m]) is inside:
        ``normal`` f_n [N] (>= 0: it pushes), ``friction`` ``mu f_n - |f_t|`` [N] and, for a soft finger,
        ``torsion`` ``torsion f_n - |m_z|`` [N m]. A rigid contact carries anything (no margins)."""
        if self.model == "rigid":
            return {}
        normal, friction, torsion = contact_margins(CONTACT_MODEL_CODES[self.model], self.mu, self.torsion, wrench)
        margins = {"normal": float(normal)}
        if self.model in FRICTION_MODELS:
            margins["friction"] = float(friction)
        if self.model == "soft-finger":
            margins["torsion"] = float(torsion)
        return margins

    def check(self, wrench: np.ndarray, t: float) -> None:
        """Raise :class:`GraspLostError` at time ``t`` [s] when the contact would have to pull, slide or
        spin to carry ``wrench`` (in C)."""
        if self.model == "rigid" or contact_holds(
            CONTACT_MODEL_CODES[self.model], self.mu, self.torsion, wrench, MARGIN_SLACK
        ):
            return
        slack = -MARGIN_SLACK * (1.0 + float(np.max(np.abs(wrench))))
        margins = self.margins(wrench)
        violated = [key for key in ("normal", "friction", "torsion") if margins.get(key, 0.0) < slack]
        if not violated:
            return
        key = violated[0]
        why = {
            "normal": f"would have to pull: normal force {wrench[2]:.4g} N < 0",
            "friction": f"would slide: tangential force {math.hypot(wrench[0], wrench[1]):.4g} N > mu f_n = "
            f"{self.mu * wrench[2]:.4g} N (mu = {self.mu:g})",
            "torsion": f"would spin: moment about the normal {abs(wrench[5]):.4g} N m > torsion f_n = "
            f"{self.torsion * wrench[2]:.4g} N m",
        }[key] + f" (margin {margins[key]:.4g} {'N m' if key == 'torsion' else 'N'})"
        raise GraspLostError(
            f"grasp lost at t = {t:.6g} s: contact {self.contact!r} ({self.finger_name} on {self.object_name}) {why}",
            self.contact,
            t,
            margins[key],
        )
