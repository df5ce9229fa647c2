"""The pinstab command line: JSON outputs, exit codes 0 / 2 / 3, no tracebacks on bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from conftest import ROBOTS
from pinstab.cli import main

RUN_KEYS = {
    "scene",
    "method",
    "integrator",
    "solver",
    "dt",
    "steps",
    "wall_s",
    "max_position_drift",
    "max_velocity_drift",
    "final_position_drift",
    "energy_start",
    "energy_end",
    "diverged",
}


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("scene", "mobility", "redundant"),
    [("fourbar", 1, 0), ("fivebar", 2, 1), ("delta", 3, 0), ("nfourbar", 1, 0), ("bricard", 1, 2)],
)
def test_check_reports_mobility(capsys, scene, mobility, redundant):
    code, out, _ = run_cli(capsys, "check", scene, "--json")
    result = json.loads(out)
    assert code == 0
    assert {"nq", "nv", "rows", "rank", "redundant", "mobility", "assembly_residual"} <= set(result)
    assert (result["mobility"], result["redundant"]) == (mobility, redundant)
    assert result["assembly_residual"] < 1e-12


def test_check_takes_generator_parameters(capsys):
    code, out, _ = run_cli(capsys, "check", "nfourbar", "--param", "N=3", "--json")
    assert code == 0 and json.loads(out)["nv"] == 7


def test_run_json_has_the_documented_keys(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "run", "fourbar", "--duration", "0.1", "--json", "--save", str(tmp_path / "r.npz"))
    result = json.loads(out)
    assert code == 0
    assert RUN_KEYS <= set(result)
    assert result["steps"] == 100 and result["diverged"] is False
    assert (tmp_path / "r.npz").is_file()


def test_unknown_scene_exits_2_listing_bundled_scenes(capsys):
    code, out, err = run_cli(capsys, "run", "no-such-scene")
    assert code == 2 and out == ""
    assert ", ".join(sorted(path.stem for path in ROBOTS.glob("*.toml"))) in err
    assert "Traceback" not in err


def test_divergence_exits_3_with_json(capsys):
    argv = "run fourbar --method baumgarte --kp 1e6 --kd 2e3 --integrator euler --dt 1e-2 --duration 5 --json --quiet"
    code, out, err = run_cli(capsys, *argv.split())
    assert code == 3
    result = json.loads(out)
    assert result["diverged"] is True and result["diverged_at"] < 5.0
    assert "diverged" in err


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "fourbar", "--solver", "dense", "--method", "pinocchio"],
        ["run", "fivebar", "--solver", "dense", "--duration", "0.01"],
        ["check", "nfourbar", "--param", "N=zero"],
        ["run", "fourbar", "--dt", "-1"],
    ],
)
def test_bad_input_exits_2_without_traceback(capsys, argv):
    code, _, err = run_cli(capsys, *argv)
    assert code == 2
    assert err.startswith(f"pinstab {argv[0]}: error:") and "Traceback" not in err


def test_console_script_is_installed():
    completed = subprocess.run([sys.executable, "-m", "pinstab.cli", "run", "nope"], capture_output=True, text=True)
    assert completed.returncode == 2 and "Bundled scenes" in completed.stderr


def test_bad_save_path_is_refused_before_the_run(capsys, tmp_path):
    code, _, err = run_cli(capsys, "run", "fourbar", "--duration", "1000", "--save", str(tmp_path / "no" / "r.npz"))
    assert code == 2 and "does not exist" in err


def test_absurd_step_count_is_refused(capsys):
    code, _, err = run_cli(capsys, "run", "fourbar", "--duration", "1e9")
    assert code == 2 and "exceed" in err


@pytest.mark.parametrize("solver", ["dense", "proxsuite", "pinocchio"])
def test_blow_up_inside_a_step_is_a_divergence(capsys, solver):
    code, _, err = run_cli(
        capsys, "run", "fourbar", "--kp", "1e12", "--kd", "1e6", "--dt", "1e-2", "--solver", solver, "--quiet"
    )
    assert code == 3, err
    assert "Traceback" not in err


def test_too_large_step_is_named_with_a_suggestion(capsys):
    """allegro-sphere at dt = 8 ms loses its grasp only because of the step: dt is above RK4's stability limit of the
    grasp hold's stiff mode (|lambda| = 378 /s: 7.52 ms), so the error names the element and that step, with which the
    run reaches its end."""
    code, out, err = run_cli(capsys, "run", "allegro-sphere", "--dt", "8e-3", "--duration", "0.5", "--json", "--quiet")
    assert code == 3, err
    assert "dt = 8 ms is above rk4's stability limit 7.52 ms of the stiff mode of force element 'hold'" in err
    assert "--dt 0.00752" in err and "Traceback" not in err
    assert json.loads(out)["diverged"] is True and json.loads(out)["stiff_mode"]["element"] == "hold"
    code, _, err = run_cli(capsys, "run", "allegro-sphere", "--dt", "0.00752", "--duration", "0.5", "--quiet")
    assert code == 0, err


def test_a_signal_swallowed_by_a_destructor_is_delivered_again():
    """SIGTERM's KeyboardInterrupt raised while Python runs a destructor is swallowed there ("Exception ignored in",
    seen in CI inside a WeakValueDictionary callback: the run went on); the command's handler delivers it again."""
    import os
    import signal

    from pinstab.cli.dispatch import _terminate_as_interrupt

    class Dying:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(10_000):  # the handler runs here; its exception cannot leave a destructor
                pass

    received: list[int] = []
    hook = sys.unraisablehook
    with pytest.raises(KeyboardInterrupt), _terminate_as_interrupt(received):
        Dying()
        for _ in range(10**7):
            pass
    assert received[0] == signal.SIGTERM
    assert sys.unraisablehook is hook  # restored


@pytest.mark.parametrize(
    "spelling", [["--tilt-axis=-1,0,0"], ["--tilt-axis", "-1,0,0"], ["--tilt-axis", "-1", "0", "0"]]
)
def test_grasp_tilt_axis_takes_a_negative_vector_in_each_spelling(capsys, spelling):
    """The docs' ``--tilt-axis=-1,0,0`` (argparse alone refuses it): about -x the allegro ball held at 0.56 N
    slips at 1.787 deg (the tilt tests/test_grasp_capacity.py checks against the dynamics); about +x, the other
    sense, it holds at any tilt (null)."""
    code, out, err = run_cli(capsys, "grasp", "allegro-sphere", "--squeeze", "0.56", *spelling, "--json")
    assert code == 0, err
    tilts = json.loads(out)["objects"]["ball"]["first_slip_tilt_deg"]
    assert tilts["+axis"] == pytest.approx(1.787, abs=1e-3)
    assert tilts["-axis"] is None


@pytest.mark.parametrize("scale", ["1e300", "1e-300"])
def test_grasp_tilt_axis_is_a_direction_at_any_scale(capsys, scale):
    """An axis of length 1e300 or 1e-300 is the direction -x (its norm overflowed to inf, then the axis to zero:
    slip at 0 deg, exit 0), as in the test above: 1.787 deg."""
    code, out, err = run_cli(
        capsys, "grasp", "allegro-sphere", "--squeeze", "0.56", f"--tilt-axis=-{scale},0,0", "--json"
    )
    assert code == 0, err
    tilts = json.loads(out)["objects"]["ball"]["first_slip_tilt_deg"]
    assert tilts["+axis"] == pytest.approx(1.787, abs=1e-3) and tilts["-axis"] is None


@pytest.mark.parametrize(("value", "message"), [("1,0", "got 2"), ("x,0,0", "'x,0,0' is not a number")])
def test_grasp_tilt_axis_refuses_other_than_three_numbers(capsys, value, message):
    with pytest.raises(SystemExit) as exit_:
        main(["grasp", "allegro-sphere", f"--tilt-axis={value}"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2
    assert "argument --tilt-axis" in err and message in err


@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "fourbar"],
        ["plot", "run.npz"],
        ["record", "fourbar"],
        ["stability", "fourbar"],
        ["sweep", "pinch", "--grid", "mu=0.1"],
    ],
)
@pytest.mark.parametrize("flag", ["-o", "--out", "--output"])
def test_every_command_that_writes_a_file_takes_o_out_and_output(argv, flag):
    from pinstab.cli.dispatch import build_parser

    assert build_parser().parse_args([*argv, flag, "target"]).output == "target"


def test_every_command_takes_quiet(capsys):
    from pinstab.cli.commands import COMMANDS

    for name in COMMANDS:
        with pytest.raises(SystemExit):
            main([name, "--help"])
        assert "--quiet" in capsys.readouterr().out, name
    code, quiet, _ = run_cli(capsys, "check", "fourbar", "--quiet", "--json")
    assert code == 0
    assert json.loads(quiet)["mobility"] == 1
