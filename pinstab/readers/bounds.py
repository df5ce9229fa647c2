"""Bounds on what a robot file may ask of the readers and of Pinocchio's parsers, checked before either walks it:
the bytes read, the nesting of its XML, its number of bodies and joints, the depth of its kinematic tree.

Pinocchio's URDF and MJCF parsers are recursive C++: a kinematic tree deep enough overflows the C stack (a crash,
no error), and the XML's nesting drives the recursion of Python's own element copies. The readers walk trees
without recursion; these bounds keep every file within what Pinocchio and the XML copies take, and name the file,
the count and the limit when one is passed.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

from ..errors import SceneError

# [bytes] a robot file, or an MJCF file and its includes together: 75 x the largest description example-robot-data
# publishes (tiago_dual.urdf, 211 kB), 5 x a URDF of MAX_BODIES links as the nfourbar generator writes them (0.7 kB
# a link and its joint); the standard library's XML reader holds about 10 times the bytes it reads
MAX_FILE_BYTES = 16_000_000
# links (bodies) or joints of a robot: twice the nfourbar generator's largest (N = 1000: 2002 links, 2001 joints);
# Pinocchio's URDF parser takes a second on it, and a model moving that many joints would need a Pinocchio Data of
# 3.6 TB (pinstab.memory.data_bytes)
MAX_BODIES = 4096
# joints on the path from the root to the deepest body (a URDF chain of a base and 1000 links: 1000; an MJCF's bodies
# nested 1000 deep in <worldbody>): Pinocchio's URDF and MJCF parsers recurse once per level, about 2.2 kB of C
# stack each (measured on its URDF parser: a chain of 3000 loads, of 4000 overflows the 8 MB main thread's stack;
# a 2 MB thread stack, glibc's when the stack limit is unlimited, holds 750 but not 1000); 1000 levels take 2.2 MB
# of the main thread's 8 MB. example-robot-data's deepest robot (tiago_dual.urdf) is 21 deep, Cassie 8
MAX_TREE_DEPTH = 1000
# elements nested in a robot file besides its bodies (an MJCF's, nested as its tree): a URDF's
# <robot><link><visual><geometry><mesh> is 5 deep, an SDF's <sdf><world><model><link><visual><geometry><mesh><uri> 8,
# MJCF default classes a few levels; Python copies and writes elements with one frame per level
MAX_XML_NESTING = 30


def read_bounded(path: Path, where: str, used: int = 0) -> bytes:
    """The bytes of ``path``, when they and the ``used`` bytes already read for the same robot are at most
    :data:`MAX_FILE_BYTES` (checked before reading).

    Raises:
        SceneError: the file cannot be read, or is too large (naming it, its size and the limit).
    """
    try:
        size = path.stat().st_size
        if used + size > MAX_FILE_BYTES:
            before = f" (after {used} bytes of the robot's other files)" if used else ""
            raise SceneError(
                f"{where}: {path} has {size} bytes{before}, more than the limit of {MAX_FILE_BYTES} bytes a robot's "
                "files may have together"
            )
        return path.read_bytes()
    except OSError as exc:
        raise SceneError(f"{where}: {path} cannot be read: {exc.strerror}") from None


def check_text_size(text: str, where: str) -> None:
    """A robot document given as text (``robot.urdf_text``, a composed URDF): at most :data:`MAX_FILE_BYTES`."""
    size = len(text.encode("utf-8"))
    if size > MAX_FILE_BYTES:
        raise SceneError(f"{where}: the document has {size} bytes, more than the limit of {MAX_FILE_BYTES} bytes")


def check_nesting(root: ET.Element, where: str, body: str | None = None) -> None:
    """Elements nested at most :data:`MAX_XML_NESTING` deep (the root at depth 1), bodies not counted, and, when
    ``body`` is the tag of the document's bodies (an MJCF's ``body``, nested as its kinematic tree), bodies nested
    at most :data:`MAX_TREE_DEPTH` deep; walked without recursion.

    Raises:
        SceneError: naming ``where``, the deepest nesting and the limit.
    """
    deepest, deepest_bodies, tag = 0, 0, root.tag
    stack = [(root, 1, 0)]
    while stack:
        element, others, bodies = stack.pop()
        if element.tag == body:
            others, bodies = others - 1, bodies + 1
        deepest_bodies = max(deepest_bodies, bodies)
        if others > deepest:
            deepest, tag = others, element.tag
        stack.extend((child, others + 1, bodies) for child in element)
    check_depth(deepest_bodies, where)
    if deepest > MAX_XML_NESTING:
        besides = f" besides the <{body}> elements" if body else ""
        raise SceneError(
            f"{where}: <{tag}> is nested {deepest} elements deep{besides}, deeper than the limit of "
            f"{MAX_XML_NESTING} (no robot description nests its elements that deep)"
        )


def check_count(count: int, what: str, where: str) -> None:
    """``count`` bodies or joints (``what``: "links", "joints", ...) at most :data:`MAX_BODIES`.

    Raises:
        SceneError: naming ``where``, the count and the limit.
    """
    if count > MAX_BODIES:
        raise SceneError(
            f"{where}: {count} {what}, more than the limit of {MAX_BODIES} a robot may have (twice the largest "
            "generated scene's; a model that size needs terabytes to run)"
        )


def tree_depth(parents: Mapping[str, str]) -> int:
    """The joints on the longest path from a root (a body without a parent) down, of the tree given as body ->
    parent body; walked without recursion, in time linear in the bodies. A cycle (which the readers refuse on their
    own) counts its joints once."""
    depth: dict[str, int] = {}
    for start in parents:
        chain: list[str] = []
        seen: set[str] = set()
        body = start
        while body in parents and body not in depth and body not in seen:
            chain.append(body)
            seen.add(body)
            body = parents[body]
        level = depth.get(body, 0)
        for item in reversed(chain):
            level += 1
            depth[item] = level
    return max(depth.values(), default=0)


def check_depth(depth: int, where: str) -> None:
    """A kinematic tree at most :data:`MAX_TREE_DEPTH` joints deep.

    Raises:
        SceneError: naming ``where``, the depth and the limit.
    """
    if depth > MAX_TREE_DEPTH:
        raise SceneError(
            f"{where}: the kinematic tree is {depth} joints deep, deeper than the limit of {MAX_TREE_DEPTH} "
            "(Pinocchio's parsers recurse once per level and would overflow the C stack)"
        )
