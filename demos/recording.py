"""
Record a scene without a screen
===============================

Record a bundled scene as a standalone HTML file and take a still of it in headless Chromium.

.. code-block:: bash

    python demos/recording.py panda-anchor --duration 2 -o panda-anchor.html --still panda-anchor.png

(The still of the documentation's recordings guide: ``python demos/recording.py panda-anchor --duration 2
-o /tmp/panda-anchor.html --still docs/recording-panda-anchor.png --time 1.0``.) Writing the HTML needs no
browser; the still needs the Debian package ``chromium``.
"""

from __future__ import annotations

import argparse

import pinstab
from pinstab.model import ConstrainedModel
from pinstab.viz.browser import screenshot
from pinstab.viz.recording import write_recording


def main() -> None:
    parser = argparse.ArgumentParser(
        description="Record a bundled scene as a standalone HTML file and take a still of it in headless Chromium."
    )
    parser.add_argument("scene", nargs="?", default="fourbar")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    parser.add_argument("-o", "--output", default="recording.html", help="HTML file to write")
    parser.add_argument("--still", help="PNG of the recording at --time, taken in headless Chromium")
    parser.add_argument("--time", type=float, default=1.0, help="animation time of the still [s]")
    args = parser.parse_args()

    scene = pinstab.load_scene(args.scene)
    trajectory = pinstab.simulate(scene, dt=1e-3, duration=args.duration, progress=True)
    recording = write_recording(ConstrainedModel(scene), trajectory, args.output)
    print(f"{recording.path}: {recording.size_bytes / 1e6:.1f} MB, {recording.frames} frames at {recording.fps:g} fps")
    if args.still:
        print(f"still at t = {args.time} s: {screenshot(recording.path, args.still, args.time, size=(900, 650))}")


if __name__ == "__main__":
    main()
