"""Plots mark push intervals and carry units."""

from __future__ import annotations

import numpy as np

from mpcbox.comparison.plots import _pyplot, mark_pushes, plot_time_series
from mpcbox.comparison.report import Trace
from mpcbox.sim.disturbances import Push


def test_pushes_are_shaded_over_their_interval_on_every_axis() -> None:
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, sharex=True)
    pushes = [
        Push(force=(30.0, 0.0, 0.0), start=1.0, duration=0.1),
        Push(force=(0.0, 40.0, 0.0), start=2.5, duration=0.2, body="pelvis"),
    ]
    mark_pushes(axes, pushes)
    for ax in axes:
        spans = sorted(p.get_x() for p in ax.patches)
        widths = sorted(round(p.get_width(), 12) for p in ax.patches)
        assert spans == [1.0, 2.5] and widths == [0.1, 0.2]
    labels = axes[0].get_legend_handles_labels()[1]
    assert labels == ["push 30 N on torso", "push 40 N on pelvis"]
    assert axes[1].get_legend_handles_labels()[1] == []
    plt.close(fig)


def test_time_series_axes_name_their_units_and_mark_the_push(tmp_path, monkeypatch) -> None:
    from mpcbox.comparison import plots

    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    time = np.linspace(0.0, 1.0, 11)
    trace = Trace(time, {}, np.ones((11, 2)), np.zeros(2))
    push = Push(force=(5.0, 0.0, 0.0), start=0.3, duration=0.1)
    plot_time_series({"lqr": trace}, tmp_path / "ts.png", pushes=[push])
    (ax,) = figures[0].axes
    assert ax.get_xlabel() == "time (s)" and "(actuator units)" in ax.get_ylabel()
    assert [p.get_x() for p in ax.patches] == [0.3]
    assert "push 5 N on torso" in ax.get_legend_handles_labels()[1]
