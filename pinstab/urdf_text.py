"""Write small URDF documents for generated mechanisms (rods pinned by revolute joints)."""

from __future__ import annotations

from dataclasses import dataclass, field


def _vec(values) -> str:
    return " ".join(f"{float(x):.12g}" for x in values)


@dataclass(frozen=True)
class Rod:
    """A uniform slender rod lying along its link's +x axis.

    Attributes:
        name: link name.
        length: rod length [m].
        mass: rod mass [kg].
        radius: visual radius [m] (the inertia is that of a thin rod: m L^2 / 12).
        color: RGBA visual colour.
    """

    name: str
    length: float
    mass: float
    radius: float = 0.015
    color: tuple[float, float, float, float] = (0.2, 0.4, 0.8, 1.0)

    def to_urdf(self) -> str:
        half = self.length / 2.0
        i_transverse = self.mass * self.length**2 / 12.0
        i_axial = self.mass * self.radius**2 / 2.0
        return f"""  <link name="{self.name}">
    <inertial>
      <origin xyz="{_vec((half, 0, 0))}" rpy="0 0 0"/>
      <mass value="{self.mass:.12g}"/>
      <inertia ixx="{i_axial:.12g}" ixy="0" ixz="0" iyy="{i_transverse:.12g}" iyz="0" izz="{i_transverse:.12g}"/>
    </inertial>
    <visual>
      <origin xyz="{_vec((half, 0, 0))}" rpy="0 1.5707963267949 0"/>
      <geometry><cylinder radius="{self.radius:.12g}" length="{self.length:.12g}"/></geometry>
      <material name="{self.name}_color"><color rgba="{_vec(self.color)}"/></material>
    </visual>
  </link>
"""


@dataclass(frozen=True)
class Joint:
    """A revolute (or prismatic) joint between two links.

    Attributes:
        name: joint name.
        parent: parent link.
        child: child link.
        xyz: joint origin in the parent link [m].
        rpy: joint frame orientation in the parent link, roll-pitch-yaw [rad].
        axis: joint axis in the joint frame.
        kind: ``revolute`` or ``prismatic``.
    """

    name: str
    parent: str
    child: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    kind: str = "revolute"

    def to_urdf(self) -> str:
        bound = 1000.0
        return f"""  <joint name="{self.name}" type="{self.kind}">
    <parent link="{self.parent}"/>
    <child link="{self.child}"/>
    <origin xyz="{_vec(self.xyz)}" rpy="{_vec(self.rpy)}"/>
    <axis xyz="{_vec(self.axis)}"/>
    <limit effort="{bound}" velocity="{bound}"/>
  </joint>
"""


@dataclass
class UrdfDocument:
    """A robot made of a ground link, rods and joints."""

    name: str
    ground: str = "ground"
    links: list[Rod] = field(default_factory=list)
    joints: list[Joint] = field(default_factory=list)

    def to_urdf(self) -> str:
        body = f'  <link name="{self.ground}"/>\n'
        body += "".join(link.to_urdf() for link in self.links)
        body += "".join(joint.to_urdf() for joint in self.joints)
        return f'<?xml version="1.0"?>\n<robot name="{self.name}">\n{body}</robot>\n'
