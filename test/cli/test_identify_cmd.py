"""``flexmotion excite`` and ``flexmotion identify``: an excitation designed from a parameter file, run
on a simulated machine whose model is off (hidden truth, exact ZOH, white noise), identified back
from the CSV; the written parameter file plans.  Bad input: one line, exit 2, nothing on stdout."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from core.identification.truth import simulate_output

from flexmotion_ros.cli.main import main
from flexmotion_ros.core.config import load_config
from flexmotion_ros.core.model.modal_model import ModalModel

ROOT = Path(__file__).resolve().parents[2]
WB_CONFIG = ROOT / "config" / "wie_bernstein.yaml"
TRUE = ModalModel(b0=0.5, omega=(1.12 * math.sqrt(2.0),), zeta=(0.03,), b=(1.0,))
ONE_LINE_PREFIX = "flexmotion: error: "


def config_at(tmp_path, rate_hz: float) -> Path:
    path = tmp_path / "wb.yaml"
    path.write_text(WB_CONFIG.read_text().replace("rate_hz: 1000.0", f"rate_hz: {rate_hz}"))
    return path


def refused(capsys, argv, *fragments) -> str:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse errors
        status = exc.code
    out, err = capsys.readouterr()
    assert status == 2
    assert out == ""
    assert err.startswith(ONE_LINE_PREFIX) and err.count("\n") == 1, err
    for f in fragments:
        assert f in err, err
    return err


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory):
    """An excitation from the planner's file, run on the true machine (encoder on the far mass)."""
    tmp = tmp_path_factory.mktemp("run")
    cfg = config_at(tmp, 20.0)
    exc = tmp / "exc.csv"
    assert main(["excite", "--config", str(cfg), "--band", "0.5:5", "-o", str(exc)]) == 0
    data = np.loadtxt(exc, delimiter=",", skiprows=1)
    t, u = data[:, 0], data[:, 1]
    y = simulate_output(TRUE, 1.0, [-0.5], u, t[1] - t[0])
    y = y + 1e-3 * np.random.default_rng(0).standard_normal(y.size)
    run = tmp / "run.csv"
    np.savetxt(run, np.column_stack([t, u, y]), delimiter=",", header="t,u,x2", comments="")
    return cfg, run, u


def test_excite_writes_a_bounded_sequence_and_a_json_summary(tmp_path, capsys):
    cfg = config_at(tmp_path, 20.0)
    out_csv = tmp_path / "e.csv"
    assert main(["excite", "--config", str(cfg), "--band", "0.5:5", "-o", str(out_csv), "--json"]) == 0
    out, _ = capsys.readouterr()
    summary = json.loads(out)
    data = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    assert out_csv.read_text().startswith("t,u\n")
    assert summary["samples"] == data.shape[0] and summary["peak"] <= 1.0
    assert np.max(np.abs(data[:, 1])) <= 1.0
    assert np.allclose(np.diff(data[:, 0]), 0.05)
    assert summary["final_state_error"] <= 1e-9
    assert summary["predicted_omega_std_error"][0] > 0.0


def test_identify_json_and_the_written_file_plans(run_csv, tmp_path, capsys):
    cfg, run, _ = run_csv
    written = tmp_path / "identified.yaml"
    argv = ["identify", "--data", str(run), "--time", "t", "--input", "u", "--output", "x2"]
    argv += ["--output-kind", "position", "--modes", "1", "--config", str(cfg), "-o", str(written), "--json"]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    d = json.loads(out)
    for key in ("b0", "c", "modes", "noise_std", "fit_rms", "samples", "solve_time_s"):
        assert key in d
    m = d["modes"][0]
    assert abs(m["omega"] - TRUE.omega[0]) <= 3 * m["omega_std_error"]
    assert abs(m["zeta"] - 0.03) <= 3 * m["zeta_std_error"]
    assert m["omega_interval"][0] < m["omega"] < m["omega_interval"][1]
    assert d["noise_std"] == pytest.approx(1e-3, rel=0.1) and d["samples"] > 1000
    assert f"wrote {written}" in err
    config = load_config(written)
    assert config.model.omega[0] == pytest.approx(m["omega"]) and config.model.b == (1.0,)  # b from the start file
    assert config.u_max == 1.0 and config.rate_hz == 20.0
    text = written.read_text()
    assert "# mode 0: omega" in text and "rest-to-rest plans need only b0, c, omega, zeta" in text
    assert main(["plan", "--config", str(written), "--goal", "1.0", "--json"]) == 0
    plan = json.loads(capsys.readouterr()[0])
    assert plan["certified"] is True


def test_identify_text_plot_and_selected_modes_without_a_start_file(run_csv, tmp_path, capsys):
    _, run, u = run_csv
    png = tmp_path / "fit.png"
    written = tmp_path / "ident.yaml"
    argv = ["identify", "--data", str(run), "--time", "t", "--input", "u", "--output", "x2"]
    assert main([*argv, "--plot", str(png), "-o", str(written), "--max-modes", "2"]) == 0
    out, _ = capsys.readouterr()
    assert "mode 0  omega" in out and "rad/s" in out and "smallest BIC" in out
    assert png.stat().st_size > 20_000
    config = load_config(written)
    assert config.u_max == pytest.approx(np.max(np.abs(u))) and config.rate_hz == pytest.approx(20.0)
    assert "largest |u| in the data" in written.read_text()


@pytest.mark.parametrize(
    "change,fragments",
    [
        (["--output", "x3"], ["--output", "no column 'x3'", "did you mean 'x2'"]),
        (["--time", "time"], ["--time", "no column 'time'"]),
        (["--modes", "-1"], ["--modes", ">= 0"]),
        (["--output-kind", "position", "--output-kind", "velocity"], ["--output-kind", "one per --output"]),
    ],
)
def test_identify_bad_arguments(run_csv, capsys, change, fragments):
    _, run, _ = run_csv
    argv = ["identify", "--data", str(run), "--time", "t", "--input", "u"]
    if "--output" not in change:
        argv += ["--output", "x2"]
    refused(capsys, argv + change, *fragments)


def test_identify_bad_data(tmp_path, capsys):
    base = ["identify", "--time", "t", "--input", "u", "--output", "y"]
    t = 0.01 * np.arange(300)
    u = np.sign(np.sin(t * 3.0))
    y = np.cumsum(np.cumsum(u)) * 1e-4 + 1e-5 * np.random.default_rng(0).standard_normal(300)
    cases = {
        "nan": (t, u, np.where(np.arange(300) == 40, np.nan, y), ["data.output", "NaN", "sample 40"]),
        "jitter": (t + np.where(np.arange(300) == 99, 0.004, 0.0), u, y, ["data.time", "not uniform"]),
        "flat": (t, np.zeros(300), y, ["data.input", "no excitation"]),
    }
    for name, (tt, uu, yy, fragments) in cases.items():
        path = tmp_path / f"{name}.csv"
        np.savetxt(path, np.column_stack([tt, uu, yy]), delimiter=",", header="t,u,y", comments="")
        refused(capsys, [*base, "--data", str(path)], *fragments)
    bad = tmp_path / "text.csv"
    bad.write_text("t,u,y\n0,1,2\n0.01,x,3\n")
    refused(capsys, [*base, "--data", str(bad)], "--input", "line 3", "'x' is not a number")
    refused(capsys, [*base, "--data", str(tmp_path / "missing.csv")], "--data", "cannot read")


def test_excite_bad_arguments(tmp_path, capsys):
    cfg = config_at(tmp_path, 20.0)
    refused(capsys, ["excite", "--config", str(cfg), "--band", "5"], "--band", "LO:HI")
    refused(capsys, ["excite", "--config", str(cfg), "--band", "0.5:60"], "band", "Nyquist")
    refused(capsys, ["excite", "--config", str(cfg), "--band", "0.5:5", "--json"], "--json", "-o")
    refused(capsys, ["excite", "--config", str(cfg), "--band", "0.5:5", "--noise-std", "0"], "--noise-std")
