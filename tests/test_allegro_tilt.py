"""allegro-tilt (issue 21): the Allegro sphere grasp tilted slowly slips at the tilt the grasp analysis
predicts for its capped squeeze, and ``--stop-on slip`` keeps the JSON, the saved run and the recording."""

from __future__ import annotations

import json

import numpy as np

from pinstab import cli
from pinstab.grasp import tilt_at_first_slip
from pinstab.scene import load_scene
from pinstab.trajectory import Trajectory

OUTPUT_STEP = 0.01  # [s] the runs' --dt


def test_the_tilted_grasp_slips_where_the_analysis_predicts(capsys, tmp_path):
    scene = load_scene("allegro-tilt")
    predicted = tilt_at_first_slip(scene, np.array([-1.0, 0.0, 0.0]))  # [deg], from the untilted start
    t_slip = (np.radians(predicted) - scene.tilt.start) / scene.tilt.rate
    saved = tmp_path / "tilt.npz"
    argv = ["run", "allegro-tilt", "--contacts", "event", "--duration", "0.3", "--dt", str(OUTPUT_STEP)]
    code = cli.main([*argv, "--stop-on", "slip", "--json", "--save", str(saved), "--quiet"])
    out, err = capsys.readouterr()
    assert code == cli.EXIT_STOPPED == 4, err
    result = json.loads(out)
    slips = [e for e in result["contact_events"] if e["from"] == "sticking" and e["to"] == "sliding"]
    assert slips and result["stopped"]["reason"] == "slip"
    assert abs(slips[0]["t"] - t_slip) <= OUTPUT_STEP  # measured: 1.4e-7 s
    run = Trajectory.load(saved)
    assert run.t[-1] == result["t_end"] == slips[0]["t"]
    assert run.info.contact_events == result["contact_events"]


def test_stop_on_slip_writes_the_recording(capsys, tmp_path):
    out = tmp_path / "tilt.html"
    argv = ["record", "allegro-tilt", "-o", str(out), "--contacts", "event", "--duration", "0.3", "--fps", "20"]
    code = cli.main([*argv, "--stop-on", "slip", "--json"])
    printed, err = capsys.readouterr()
    assert code == cli.EXIT_STOPPED, err
    assert json.loads(printed)["frames"] == 3  # 0, 0.05, 0.10 s, then the slip at 0.143 s
    assert "pinstab ready: allegro-tilt" in out.read_text()
