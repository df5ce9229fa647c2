"""Scenes generated from parameters (scene files are data; the generator is named, not evaluated).

A scene file with a ``[generator]`` table names one of :data:`GENERATORS` and its parameters; the
generator returns the scene content (URDF text, closures, initial state) that the file would
otherwise spell out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .contact.coefficients import friction_coefficient, restitution_coefficient
from .errors import SceneError, choices
from .forces.base import LOAD_REASON, MAX_LOAD
from .units import (
    COORDINATE_REASON,
    MAGNITUDE_REASON,
    MAX_COORDINATE,
    MAX_MAGNITUDE,
    MAX_RATE,
    MIN_LENGTH,
    MIN_MASS,
    RATE_REASON,
)
from .urdf_text import Joint, Rod, UrdfDocument

MAX_LOOPS = 1000  # nfourbar's N: 2001 links (a larger N only makes the scene wait on its URDF)
# [m] nfourbar's shortest link: a thin rod's inertia (m L^2 / 12 across, m r^2 / 2 along, r its drawn radius) keeps
# the triangle inequality of principal moments down to L = sqrt(3) r
MIN_LINK_LENGTH = math.sqrt(3.0) * Rod.radius
LINK_LENGTH_REASON = f"a rod shorter than {MIN_LINK_LENGTH:.3g} m breaks its inertia's triangle inequality; " + (
    f"the N+1 cranks' pins span N link lengths, a position within {MAX_COORDINATE:g} m, {COORDINATE_REASON}"
)
# the lightest body a generator makes is units.MIN_MASS (a microgram); pinch's cube of 1e-9 kg between its 0.1 kg
# fingers already spreads the mass matrix's diagonal over 1e8
MASS_REASON = f"from a microgram (a MEMS part) to {MAX_MAGNITUDE:.0e} kg: {MAGNITUDE_REASON}"


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
    link_length = _number(
        "nfourbar", "link_length", link_length, MIN_LINK_LENGTH, MAX_COORDINATE / n, "m", LINK_LENGTH_REASON
    )
    link_mass = _number("nfourbar", "link_mass", link_mass, MIN_MASS, MAX_MAGNITUDE, "kg", MASS_REASON)
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


GRAVITY = 9.81  # [m/s^2] of the contact scenes
BOX_SIDE = 0.1  # [m] the incline's cube


def _link(
    name: str,
    shape: str,
    mass: float,
    inertia: tuple[float, float, float],
    visual_at: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> str:
    """URDF text of one link: ``mass`` [kg] and principal ``inertia`` [kg m^2] at its origin, ``shape`` drawn at
    ``visual_at`` [m] and its collision shape there (contacts found from geometry use it)."""
    ixx, iyy, izz = inertia
    x, y, z = visual_at
    placed = f'<origin xyz="{x!r} {y!r} {z!r}"/><geometry>{shape}</geometry>'
    return (
        f'<link name="{name}"><inertial><origin xyz="0 0 0"/><mass value="{mass!r}"/>'
        f'<inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" izz="{izz!r}"/></inertial>'
        f"<visual>{placed}</visual><collision>{placed}</collision></link>"
    )


def _rigid_body(name: str, shape: str, mass: float, inertia: tuple[float, float, float]) -> str:
    """URDF text of one free body (the scene gives it a free flyer, joint ``root_joint``)."""
    return f'<?xml version="1.0"?>\n<robot name="{name}">{_link(name, shape, mass, inertia)}</robot>\n'


def _number(generator: str, name: str, value: Any, low: float, high: float, unit: str, reason: str) -> float:
    """Parameter ``name`` of ``generator`` as a float [``unit``] when a number in [``low``, ``high``].

    Raises:
        SceneError: naming the generator and the parameter, the value, the range and its ``reason``.
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not low <= value <= high:
        raise SceneError(
            f"generator {generator}: parameter {name} must be a number in [{low:.10g}, {high:.10g}] {unit}, "
            f"got {value!r}: {reason}"
        )
    return float(value)


def _rate(generator: str, name: str, value: Any, unit: str) -> float:
    """A start velocity [``unit``: m/s or rad/s] within :data:`~pinstab.units.MAX_RATE`, as ``initial.v``."""
    return _number(generator, name, value, -MAX_RATE, MAX_RATE, unit, RATE_REASON)


def _ball(radius: float) -> dict[str, Any]:
    """A solid 1 kg ball of ``radius`` [m] on a free flyer under gravity along -z (the scene's robot and gravity)."""
    inertia = 0.4 * radius**2
    urdf = _rigid_body("ball", f'<sphere radius="{radius!r}"/>', 1.0, (inertia,) * 3)
    return {"robot": {"urdf_text": urdf, "free_flyer": True}, "gravity": [0.0, 0.0, -GRAVITY]}


def incline(theta: float = 0.5, mu: float = 0.3, v_down: float = 0.0, v_across: float = 0.0) -> dict[str, Any]:
    """A 1 kg cube (side 0.1 m) on a plane tilted by ``theta`` [rad] with friction ``mu`` on its four bottom
    corners, released with ``v_down``, ``v_across`` [m/s] along and across the slope. The plane is z = 0 and
    gravity is tilted (down the slope is +x): from rest the cube sticks for mu >= tan(theta), else slides
    with x(t) = g (sin theta - mu cos theta) t^2 / 2."""
    theta = _number("incline", "theta", theta, 0.0, math.pi / 2, "rad", "from a level plane to a vertical wall")
    mu = friction_coefficient(mu, "generator incline: parameter mu")
    v_down = _rate("incline", "v_down", v_down, "m/s")
    v_across = _rate("incline", "v_across", v_across, "m/s")
    half, inertia = BOX_SIDE / 2, BOX_SIDE**2 / 6
    corners = [(sx * half, sy * half) for sx in (1, -1) for sy in (1, -1)]
    return {
        "robot": {
            "urdf_text": _rigid_body("box", f'<box size="{BOX_SIDE} {BOX_SIDE} {BOX_SIDE}"/>', 1.0, (inertia,) * 3),
            "free_flyer": True,
        },
        "gravity": [GRAVITY * math.sin(theta), 0.0, -GRAVITY * math.cos(theta)],
        "contacts": [
            {"name": f"corner{k}", "kind": "plane-contact", "frame_a": "box", "offset_a": [x, y, -half], "mu": mu}
            for k, (x, y) in enumerate(corners)
        ],
        "initial": {
            "q": {"root_joint": [0.0, 0.0, half, 0.0, 0.0, 0.0, 1.0]},
            "v": {"root_joint": [v_down, v_across, 0.0, 0.0, 0.0, 0.0]},
        },
    }


MIN_RADIUS = MIN_LENGTH  # [m] sphere-spin's smallest ball: a micrometre grain, its inertia 0.4 r^2 = 4e-13 kg m^2
RADIUS_REASON = (
    f"from a micrometre grain (its inertia 0.4 r^2 kg m^2 then 1e-12 of its mass's scale) to {MAX_COORDINATE:g} m, "
    f"where its centre starts, a coordinate of its free joint: {COORDINATE_REASON}"
)


def sphere_spin(v0: float = 2.0, omega0: float = 5.0, mu: float = 0.3, radius: float = 0.1) -> dict[str, Any]:
    """A solid 1 kg sphere of ``radius`` [m] thrown along +x at ``v0`` [m/s] with backspin ``omega0`` [rad/s]
    on the plane z = 0 with friction ``mu``: it slides until t* = 2 (v0 + r omega0) / (7 mu g), then rolls at
    v* = (5 v0 - 2 r omega0) / 7."""
    v0 = _rate("sphere-spin", "v0", v0, "m/s")
    omega0 = _rate("sphere-spin", "omega0", omega0, "rad/s")
    mu = friction_coefficient(mu, "generator sphere-spin: parameter mu")
    radius = _number("sphere-spin", "radius", radius, MIN_RADIUS, MAX_COORDINATE, "m", RADIUS_REASON)
    return {
        **_ball(radius),
        "contacts": [{"name": "ground", "kind": "plane-contact", "frame_a": "ball", "radius": radius, "mu": mu}],
        "initial": {
            "q": {"root_joint": [0.0, 0.0, radius, 0.0, 0.0, 0.0, 1.0]},
            "v": {"root_joint": [v0, 0.0, 0.0, 0.0, -omega0, 0.0]},
        },
    }


BALL_RADIUS = 0.05  # [m] the bouncing ball
HEIGHT_REASON = (
    f"the ball's centre, {BALL_RADIUS} m higher, is a coordinate of its free joint, within {MAX_COORDINATE:g} m, "
    f"{COORDINATE_REASON}"
)


def bouncing_ball(height: float = 1.0, restitution: float = 0.5) -> dict[str, Any]:
    """A 1 kg ball (radius 0.05 m) dropped from a gap ``height`` [m] above the plane z = 0 with Newton's
    ``restitution`` e: apex gaps e^(2k) h, at rest at t0 (1 + e) / (1 - e), t0 = sqrt(2 h / g)."""
    height = _number("bouncing-ball", "height", height, 0.0, MAX_COORDINATE - BALL_RADIUS, "m", HEIGHT_REASON)
    restitution = restitution_coefficient(restitution, "generator bouncing-ball: parameter restitution")
    radius = BALL_RADIUS
    return {
        **_ball(radius),
        "contacts": [
            {
                "name": "ground",
                "kind": "plane-contact",
                "frame_a": "ball",
                "radius": radius,
                "restitution": restitution,
            }
        ],
        "initial": {"q": {"root_joint": [0.0, 0.0, radius + height, 0.0, 0.0, 0.0, 1.0]}},
    }


PINCH_SIDE = 0.05  # [m] the pinched cube
FINGER_MASS = 0.1  # [kg] each pinch finger


def pinch(mu: float = 0.5, squeeze: float = 1.0, mass: float = 0.1) -> dict[str, Any]:
    """A cube (side 0.05 m) of ``mass`` [kg] squeezed between two 0.1 kg fingers on slide joints along x,
    each pushed against a side face with ``squeeze`` [N]; friction ``mu`` at the two contacts (the fingertip
    point on the face's plane, carried by the cube), gravity along -z. The cube holds iff
    2 mu F >= m g, else slides down with acceleration g - 2 mu F / m."""
    mu = friction_coefficient(mu, "generator pinch: parameter mu")
    squeeze = _number("pinch", "squeeze", squeeze, 0.0, MAX_LOAD, "N", LOAD_REASON)  # a joint-torque's range
    mass = _number("pinch", "mass", mass, MIN_MASS, MAX_MAGNITUDE, "kg", MASS_REASON)
    half, inertia = PINCH_SIDE / 2, mass * PINCH_SIDE**2 / 6
    finger_inertia = FINGER_MASS * 1e-4
    links = [_link("block", f'<box size="{PINCH_SIDE} {PINCH_SIDE} {PINCH_SIDE}"/>', mass, (inertia,) * 3)]
    joints = ['<joint name="block" type="floating"><parent link="world"/><child link="block"/></joint>']
    fingers = {"finger_left": -1.0, "finger_right": 1.0}
    for name, side in fingers.items():
        shape = f'<box size="{half} {half / 2} {half / 2}"/>'  # drawn beside its tip, the link's origin
        links.append(_link(name, shape, FINGER_MASS, (finger_inertia,) * 3, visual_at=(side * half / 2, 0.0, 0.0)))
        joints.append(
            f'<joint name="{name}" type="prismatic"><parent link="world"/><child link="{name}"/>'
            f'<origin xyz="{side * half!r} 0 0"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1e3" '
            'velocity="1e3"/></joint>'
        )
    urdf = '<?xml version="1.0"?>\n<robot name="pinch"><link name="world"/>' + "".join(links + joints) + "</robot>\n"
    return {
        "robot": {"urdf_text": urdf},
        "gravity": [0.0, 0.0, -GRAVITY],
        "contacts": [
            {
                "name": name.removeprefix("finger_"),
                "kind": "plane-contact",
                "frame_a": name,
                "frame_b": "block",
                "offset_b": [side * half, 0.0, 0.0],
                "normal": [side, 0.0, 0.0],
                "mu": mu,
            }
            for name, side in fingers.items()
        ],
        "forces": [
            {
                "name": f"squeeze_{name.removeprefix('finger_')}",
                "kind": "joint-torque",
                "joint": name,
                "torque": -side * squeeze,
            }
            for name, side in fingers.items()
        ],
        "initial": {"q": {"block": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]}},
    }


ROD_ANGLE = math.atan(2.0)  # [rad] the painleve-rod's angle to the floor, where the Painleve bound is least: 4/3
ROD_SPEED = 1.0  # [m/s] the painleve-rod's initial sliding speed


def painleve_rod(mu: float = 2.0) -> dict[str, Any]:
    """A uniform rod (1 kg, 1 m) whose lower end A slides at 1 m/s on the rough floor z = 0 (friction ``mu``)
    away from below its centre, the rod at theta = atan 2 (63.4 deg) to the floor, at rest otherwise.

    Painleve's bound. Half-length l, I = m l^2 / 3 about the centre G, A = G - l (cos theta, sin theta) in the
    vertical (x, z) plane, floor force (F, N) at A. With theta' = 0, Newton and Euler give
    ``z_A'' = -g + (N / m)(1 + 3 cos^2 theta) - (3 F / m) sin theta cos theta``. A slides along -x, so sliding
    friction is ``F = +mu N`` and ``z_A'' = -g + (N / m) (1 + 3 cos theta (cos theta - mu sin theta))``. When
    the bracket is negative, i.e. ``mu > (1 + 3 cos^2 theta) / (3 sin theta cos theta)`` (= 4/3 at tan theta = 2,
    the least over theta), sliding contact needs N = m g / bracket < 0 (a floor that pulls) and separation
    (N = 0) gives z_A'' = -g < 0 (the end goes through the floor): no mode is consistent. Sticking is not a
    mode of a contact that slips. For mu < 4/3 the end slides with N > 0."""
    mu = friction_coefficient(mu, "generator painleve-rod: parameter mu")
    half = 0.5
    c, s = math.cos(ROD_ANGLE), math.sin(ROD_ANGLE)
    urdf = _rigid_body("rod", '<box size="1.0 0.02 0.02"/>', 1.0, (5e-5, 1.0 / 12, 1.0 / 12))
    # the rod's x axis along (cos theta, 0, sin theta): a turn by -theta about y; its body velocity is R^T (-v, 0, 0)
    quaternion = [0.0, -math.sin(ROD_ANGLE / 2), 0.0, math.cos(ROD_ANGLE / 2)]
    return {
        "robot": {"urdf_text": urdf, "free_flyer": True},
        "gravity": [0.0, 0.0, -GRAVITY],
        "contacts": [
            {"name": "end", "kind": "plane-contact", "frame_a": "rod", "offset_a": [-half, 0.0, 0.0], "mu": mu}
        ],
        "initial": {
            "q": {"root_joint": [half * c, 0.0, half * s, *quaternion]},
            "v": {"root_joint": [-ROD_SPEED * c, 0.0, ROD_SPEED * s, 0.0, 0.0, 0.0]},
        },
    }


MAX_STACK = 10  # box-stack's tallest stack
DROP_REASON = "from resting on the stack to a metre above it"
GROUND_URDF = '<?xml version="1.0"?>\n<robot name="ground"><link name="ground"/></robot>\n'  # a robot without bodies


def box_stack(count: int = 3, mu: float = 0.5, drop: float = -1.0) -> dict[str, Any]:
    """``count`` 1 kg cubes (side 0.1 m, objects ``box0``, ``box1``, ... from the bottom) stacked at rest on the
    ground z = 0, their contacts found from geometry (kind ``geometry``, friction ``mu``): four corners per face
    pair, the normal forces under box k summing to the weight of the boxes from k up, (count - k) m g. With
    ``drop`` >= 0 [m] one more cube (``dropped``) starts that far above the top, at rest: it lands flat on its
    four corners (an impact, e = 0) and rests there."""
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_STACK:
        raise SceneError(f"generator box-stack: parameter count must be an integer in [1, {MAX_STACK}], got {count!r}")
    mu = friction_coefficient(mu, "generator box-stack: parameter mu")
    drop = _number("box-stack", "drop", drop, -1.0, 1.0, "m", f"-1: no box dropped; {DROP_REASON}")
    half = BOX_SIDE / 2
    heights = [half + k * BOX_SIDE for k in range(count)]
    names = [f"box{k}" for k in range(count)]
    if drop >= 0.0:
        heights.append(half + count * BOX_SIDE + drop)
        names.append("dropped")
    return {
        "robot": {"urdf_text": GROUND_URDF},
        "gravity": [0.0, 0.0, -GRAVITY],
        "objects": [
            {"name": name, "shape": "box", "size": [BOX_SIDE] * 3, "mass": 1.0, "position": [0.0, 0.0, z]}
            for name, z in zip(names, heights, strict=True)
        ],
        "contacts": [{"kind": "geometry", "mu": mu}],
    }


GENERATORS: dict[str, Callable[..., dict[str, Any]]] = {
    "nfourbar": nfourbar,
    "incline": incline,
    "sphere-spin": sphere_spin,
    "bouncing-ball": bouncing_ball,
    "pinch": pinch,
    "painleve-rod": painleve_rod,
    "box-stack": box_stack,
}
GENERATOR_PARAMETERS: dict[str, dict[str, str]] = {
    "nfourbar": {"N": "n", "link_length": "link_length", "link_mass": "link_mass"},
    "incline": {"theta": "theta", "mu": "mu", "v_down": "v_down", "v_across": "v_across"},
    "sphere-spin": {"v0": "v0", "omega0": "omega0", "mu": "mu", "radius": "radius"},
    "bouncing-ball": {"height": "height", "restitution": "restitution"},
    "pinch": {"mu": "mu", "squeeze": "squeeze", "mass": "mass"},
    "painleve-rod": {"mu": "mu"},
    "box-stack": {"count": "count", "mu": "mu", "drop": "drop"},
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
