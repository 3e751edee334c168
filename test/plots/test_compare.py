"""The compare figure (``plots/compare.py``), read back: a distinct colour/style pair per method, the move
duration next to each name in the legend, every curve in the legend, labelled axes."""

import numpy as np

from flexmotion_ros.plots.compare import method_styles, plot_sensitivity

NAMES = [f"method_{i}" for i in range(17)]


def test_every_method_has_its_own_colour_and_style_and_its_duration_in_the_legend(tmp_path):
    r = np.linspace(0.7, 1.3, 61)
    curves = {n: (r, np.abs(r - 1.0) * (i + 1)) for i, n in enumerate(NAMES)}
    durations = {n: 4.0 + 0.25 * i for i, n in enumerate(NAMES)}
    fig = plot_sensitivity(curves, str(tmp_path / "c.png"), 5.0, 0.1, "t", durations=durations)
    assert (tmp_path / "c.png").stat().st_size > 10_000
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_label().split()[0] in curves]
    assert len(lines) == len(NAMES)
    pairs = {(ln.get_color(), ln.get_linestyle()) for ln in lines}
    assert len(pairs) == len(NAMES)  # no two methods look alike
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    for n, ln in zip(NAMES, lines):
        assert ln.get_label() in texts
        assert ln.get_label().split() == [n, f"{durations[n]:.3f}", "s"]
    assert any("tolerance" in t for t in texts) and any("frequency error" in t for t in texts)
    assert "(-)" in ax.get_xlabel() and "%" in ax.get_ylabel()


def test_consecutive_methods_differ_in_colour_and_style():
    styles = list(method_styles(NAMES).values())
    for a, b in zip(styles, styles[1:]):
        assert a[0] != b[0] and a[1] != b[1]
    assert len(set(method_styles([f"m{i}" for i in range(60)]).values())) == 60
