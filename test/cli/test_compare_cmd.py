"""``flexmotion compare``: the table names which residual is which (the whole move's, relative to a u_max step,
and a shaper's own classic one, on which its tolerance is defined), says what defaults were taken, and the
figure it writes has one distinct, labelled curve per method with its duration."""

import json
from pathlib import Path

import pytest

from flexmotion_ros.cli.main import main
from flexmotion_ros.plots import compare as compare_plot

ROOT = Path(__file__).resolve().parents[2]
WB = str(ROOT / "config" / "wie_bernstein.yaml")
METHODS = "zvd,ei,min_fuel,limited"


@pytest.fixture(scope="module")
def rows():
    import io
    from contextlib import redirect_stdout

    buf = io.StringIO()
    with redirect_stdout(buf):
        assert main(["compare", "--config", WB, "--goal", "1", "--methods", METHODS, "--json"]) == 0
    return {r["method"]: r for r in json.loads(buf.getvalue())}


def test_ei_meets_its_tolerance_on_the_classic_residual(rows):
    ei = rows["ei"]
    assert ei["shaper_residual_percent"] == pytest.approx(5.0, abs=1e-6)  # shaper.tolerance default 0.05
    assert ei["residual_percent"] > 10.0  # the whole-move figure is a different quantity
    assert rows["zvd"]["shaper_residual_percent"] == pytest.approx(0.0, abs=1e-9)
    assert rows["time_optimal"]["shaper_residual_percent"] is None  # not a shaper


def test_defaults_are_stated(rows):
    assert any("move_time" in d and "default" in d for d in rows["min_fuel"]["defaults"])
    assert any("no limits given" in d for d in rows["limited"]["defaults"])
    assert rows["zvd"]["defaults"] == []


def test_table_and_plot(tmp_path, capsys, monkeypatch):
    figures = []
    original = compare_plot.plot_sensitivity

    def keep(*a, **k):
        figures.append(original(*a, **k))
        return figures[-1]

    monkeypatch.setattr(compare_plot, "plot_sensitivity", keep)
    png = tmp_path / "compare.png"
    assert main(["compare", "--config", WB, "--goal", "1", "--methods", METHODS, "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "move res %" in out and "shaper V %" in out
    ei_line = next(ln for ln in out.splitlines() if ln.startswith("ei "))
    assert "5.000" in ei_line.split()
    assert "min_fuel: move_time" in out and "limited: no limits given" in out
    ax = figures[0].axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_label().split()[0] in ("time_optimal", *METHODS.split(","))]
    assert len(lines) == 5
    assert len({(ln.get_color(), ln.get_linestyle()) for ln in lines}) == 5
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    for ln in lines:
        assert ln.get_label() in legend and ln.get_label().endswith(" s")
