"""Scenes generated from parameters (scene files are data; the generator is named, not evaluated).

A scene file with a ``[generator]`` table names one of :data:`GENERATORS` and its parameters; the
generator returns the scene content (URDF text, closures, initial state) that the file would
otherwise spell out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .errors import SceneError, choices
from .urdf_text import Joint, Rod, UrdfDocument

MAX_LOOPS = 1000  # nfourbar's N: 2001 links (a larger N only makes the scene wait on its URDF)


def nfourbar(n: int = 10, link_length: float = 1.0, link_mass: float = 1.0) -> dict[str, Any]:
    """The IFToMM N-four-bar benchmark: N+1 cranks pinned to the ground 1 m apart, N couplers.

    2N+1 links of ``link_length`` [m] and ``link_mass`` [kg]; cranks start vertical, couplers
    horizontal, every crank turning at -1 rad/s (coupler tops moving at +1 m/s along x). The tree
    pins every crank to the ground and hangs coupler k on crank k-1; coupler k's free end is closed
    on crank k's tip by a 2-row ``planar-point`` closure in the xy plane. 1 DOF.

    Args:
        n: number of four-bar loops N (1 to :data:`MAX_LOOPS`).
        link_length: length of every link [m].
        link_mass: mass of every link [kg].
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise SceneError(f"generator nfourbar: parameter N must be an integer >= 1, got {n!r}")
    if n > MAX_LOOPS:
        raise SceneError(f"generator nfourbar: parameter N must be at most {MAX_LOOPS}, got {n!r}")
    for name, value, unit in (("link_length", link_length, "m"), ("link_mass", link_mass, "kg")):
        if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < math.inf:
            raise SceneError(
                f"generator nfourbar: parameter {name} must be a positive finite number [{unit}], got {value!r}"
            )
    doc = UrdfDocument(name=f"nfourbar{n}")
    quarter = math.pi / 2.0
    closures = []
    q0: dict[str, float] = {}
    v0: dict[str, float] = {}
    for k in range(n + 1):
        crank = f"crank{k}"
        doc.links.append(Rod(crank, link_length, link_mass, color=(0.8, 0.3, 0.2, 1.0)))
        doc.joints.append(Joint(f"{crank}_joint", "ground", crank, xyz=(k * link_length, 0, 0), rpy=(0, 0, quarter)))
        q0[f"{crank}_joint"] = 0.0
        v0[f"{crank}_joint"] = -1.0
        if k == 0:
            continue
        coupler = f"coupler{k}"
        doc.links.append(Rod(coupler, link_length, link_mass, color=(0.2, 0.4, 0.8, 1.0)))
        doc.joints.append(
            Joint(f"{coupler}_joint", f"crank{k - 1}", coupler, xyz=(link_length, 0, 0), rpy=(0, 0, -quarter))
        )
        q0[f"{coupler}_joint"] = 0.0
        v0[f"{coupler}_joint"] = 1.0
        closures.append(
            {
                "name": f"loop{k}",
                "kind": "planar-point",
                "plane": "xy",
                "frame_a": coupler,
                "offset_a": [link_length, 0.0, 0.0],
                "frame_b": crank,
                "offset_b": [link_length, 0.0, 0.0],
            }
        )
    return {
        "robot": {"urdf_text": doc.to_urdf()},
        "gravity": [0.0, -9.81, 0.0],
        "closures": closures,
        "initial": {"q": q0, "v": v0},
    }


GENERATORS: dict[str, Callable[..., dict[str, Any]]] = {"nfourbar": nfourbar}
GENERATOR_PARAMETERS: dict[str, dict[str, str]] = {
    "nfourbar": {"N": "n", "link_length": "link_length", "link_mass": "link_mass"},
}


def generate(name: str, parameters: dict[str, Any]) -> dict[str, Any]:
    """Run generator ``name`` with scene-file ``parameters``; errors name the bad item."""
    if name not in GENERATORS:
        raise SceneError(f"unknown generator {name!r}; valid generators: {choices(GENERATORS)}")
    mapping = GENERATOR_PARAMETERS[name]
    kwargs = {}
    for key, value in parameters.items():
        if key not in mapping:
            raise SceneError(f"generator {name}: unknown parameter {key!r}; valid parameters: {choices(mapping)}")
        kwargs[mapping[key]] = value
    return GENERATORS[name](**kwargs)
