"""SDF robots: ``[robot] sdf = "path/model.sdf"`` (or ``name = "cassie"``, example-robot-data's SDF).

Read with the standard library's XML parser (:mod:`.sdf_document`; python-sdformat would add a dependency
and still leave the pose conventions to pinstab). The model is built on the spanning tree
(:mod:`.sdf_tree`), its loops, gearboxes and springs become scene entries (:mod:`.sdf_tables`). The model
is floating (a free flyer ``root_joint`` at the root link's pose) when the SDF attaches it to nothing and is
not ``<static>``, unless ``robot.free_flyer`` says otherwise. The visual and collision geometry is read by
Pinocchio's URDF geometry reader from a URDF document of the links (:func:`geometry_urdf`); mesh URIs
``model://<path>`` are found in the folders above the SDF file, relative URIs next to it.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pinocchio as pin

from ..errors import SceneError
from .base import READERS, ReaderOptions, RobotSource
from .bounds import check_depth
from .sdf_document import WORLD_LINK, SdfModel, SdfVisual, read_document, rpy_of
from .sdf_tables import scene_tables
from .sdf_tree import SdfTree, build_model, spanning_tree
from .urdf import resolve_file

PRIMITIVES = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}


def _mesh_path(uri: str, sdf_path: Path, where: str) -> str:
    """The file of a mesh URI: ``model://a/b`` in a folder above the SDF, ``file://``, or relative to the SDF."""
    if uri.startswith("model://"):
        relative = uri[len("model://") :]
        for folder in sdf_path.parents:
            if (folder / relative).is_file():
                return str(folder / relative)
        raise SceneError(f"{where}: mesh {uri!r} is not found in any folder above {sdf_path}")
    if uri.startswith("package://"):
        return uri
    path = Path(uri[len("file://") :] if uri.startswith("file://") else uri)
    path = path if path.is_absolute() else sdf_path.parent / path
    if not path.is_file():
        raise SceneError(f"{where}: mesh file {path} does not exist")
    return str(path)


def _geometry(item: SdfVisual, sdf_path: Path, where: str) -> ET.Element | None:
    """The URDF ``<geometry>`` of an SDF one (None for shapes URDF has not: planes, heightmaps)."""
    out = ET.Element("geometry")
    mesh = item.geometry.find("mesh")
    if mesh is not None:
        attributes = {"filename": _mesh_path((mesh.findtext("uri") or "").strip(), sdf_path, where)}
        if mesh.findtext("scale"):
            attributes["scale"] = mesh.findtext("scale", "").strip()
        ET.SubElement(out, "mesh", attributes)
        return out
    for shape, keys in PRIMITIVES.items():
        element = item.geometry.find(shape)
        if element is not None:
            ET.SubElement(out, shape, {key: (element.findtext(key) or "").strip() for key in keys})
            return out
    return None


def geometry_urdf(sdf: SdfModel, tree: SdfTree, sdf_path: Path) -> str:
    """A URDF document of the links' visuals and collisions, each placed in its link's (BODY) frame; the joints are
    fixed (only the links matter to Pinocchio's geometry reader, which attaches by link name)."""
    robot = ET.Element("robot", {"name": sdf.name})
    for name, link in sdf.links.items():
        element = ET.SubElement(robot, "link", {"name": name})
        for tag, items in (("visual", link.visuals), ("collision", link.collisions)):
            for item in items:
                where = f"sdf link {name!r} {tag} {item.name!r}"
                geometry = _geometry(item, sdf_path, where)
                if geometry is None:
                    continue
                placement = item.pose  # in the link's frame, where its BODY frame is
                out = ET.SubElement(element, tag, {"name": item.name})
                xyz = " ".join(f"{x:.17g}" for x in placement.translation)
                ET.SubElement(out, "origin", {"xyz": xyz, "rpy": " ".join(f"{x:.17g}" for x in rpy_of(placement))})
                out.append(geometry)
                if tag == "visual" and item.rgba is not None:
                    material = ET.SubElement(out, "material", {"name": f"{name}/{item.name}"})
                    ET.SubElement(material, "color", {"rgba": " ".join(f"{x:g}" for x in item.rgba)})
    for child, joint in tree.parent_joint.items():
        if joint.parent != WORLD_LINK:
            element = ET.SubElement(robot, "joint", {"name": joint.name, "type": "fixed"})
            ET.SubElement(element, "parent", {"link": joint.parent})
            ET.SubElement(element, "child", {"link": child})
    return ET.tostring(robot, encoding="unicode")


def read_sdf_file(path: Path, free_flyer: bool | None = None) -> RobotSource:
    """The robot of the SDF file ``path``: floating as the SDF says when ``free_flyer`` is None.

    Raises:
        SceneError: see :func:`.sdf_document.read_document`; a link not connected to the root; a tree deeper than
            :data:`~.bounds.MAX_TREE_DEPTH`; a gearbox whose bodies do not hang from its reference body; a mesh
            that is not found (each named).
    """
    sdf = read_document(path)
    tree = spanning_tree(sdf)
    check_depth(tree.depth(), f"robot.sdf {path}")  # its geometry is read by Pinocchio's (recursive) URDF parser
    floating = free_flyer if free_flyer is not None else (tree.root != WORLD_LINK and not sdf.static)
    model = build_model(sdf, tree, floating)
    notes: list[str] = []
    tables = scene_tables(sdf, tree, notes)
    urdf = geometry_urdf(sdf, tree, path)

    def geometry(full: pin.Model, kind: pin.GeometryType, search: list[str]) -> pin.GeometryModel:
        return pin.buildGeomFromUrdfString(full, urdf, kind, package_dirs=search)

    return RobotSource(
        model, "sdf", path, package_dirs=[str(path.parent)], tables=tables, notes=notes, geometry=geometry
    )


def read_sdf(robot: dict[str, Any], options: ReaderOptions) -> RobotSource:
    """The robot of ``robot.sdf`` (a path relative to the scene); ``robot.free_flyer`` overrides the SDF."""
    return read_sdf_file(resolve_file(robot, "sdf", options), robot.get("free_flyer"))


READERS.register(
    "sdf", read_sdf, summary="an SDF file (robot.sdf): loops, gearboxes and springs", capabilities={".sdf"}
)
