"""What the pictures and reports say: titles name the run's parameters,
legends sit clear of the data, text stays legible, slope lines are drawn when listed, noise
and round-off are no trade, one verdict vocabulary.

Assertions are on the figure objects (titles, legend texts and boxes, font sizes in pixels,
labels), not on pixels.
"""

from __future__ import annotations

import struct
import sys

import numpy as np
import pytest

from pillar_xval.scenes import InputError, ScopeError, load_scene


# --- helpers ------------------------------------------------------------------------------
@pytest.fixture(autouse=True)
def _close_figures():
    """Close the figures a test leaves open (captured ones, pressure_plot's): a worker
    holding more than 20 warns, and their memory adds up."""
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def _capture(monkeypatch, module) -> list:
    """Figures that ``module.save_figure`` would have written (they stay open)."""
    figures = []
    monkeypatch.setattr(module, "save_figure", lambda fig, path, *a, **k: figures.append(fig))
    return figures


def _agg(fig):
    """An Agg canvas for ``fig`` (a figure already saved and closed has none)."""
    if not hasattr(fig.canvas, "get_renderer"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)


def covered_points(ax) -> list[tuple[str, float, float]]:
    """Data points of ``ax`` (its lines' vertices and its collections' offsets) that fall
    inside its legend's box on the drawn figure: (label, x, y) of each."""
    legend = ax.get_legend()
    if legend is None:
        return []
    fig = ax.figure
    _agg(fig)
    fig.canvas.draw()
    box = legend.get_window_extent()
    hits = []
    for line in ax.get_lines():
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        if x.size == 0 or not line.get_visible():
            continue
        xy = line.get_transform().transform(np.column_stack([x, y]))
        if len(xy) > 1 and line.get_linestyle() not in ("None", "", " "):
            # the segments between the vertices too, every few pixels
            t = np.linspace(0.0, 1.0, 25)[:-1]
            xy = np.concatenate([a + np.outer(t, b - a) for a, b in zip(xy[:-1], xy[1:])]
                                + [xy[-1:]])
        clip = ax.get_window_extent()  # points outside the axes are not drawn
        drawn = ((xy[:, 0] >= clip.x0) & (xy[:, 0] <= clip.x1)
                 & (xy[:, 1] >= clip.y0) & (xy[:, 1] <= clip.y1))
        inside = ((xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
                  & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1) & drawn)
        hits += [(line.get_label(), float(a), float(b)) for a, b in xy[inside]]
    return hits


def clipped_texts(fig) -> list[str]:
    """Titles, labels and legend texts of ``fig`` that run past its edges, laid out as
    figure_png lays it out before saving."""
    _agg(fig)
    fig.tight_layout()
    fig.canvas.draw()
    page = fig.bbox
    renderer = fig.canvas.get_renderer()
    texts = [t for ax in fig.axes for t in (ax.title, ax.xaxis.label, ax.yaxis.label)]
    texts += [t for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    out = []
    for t in texts:
        if not t.get_text() or not t.get_visible():
            continue
        box = t.get_window_extent(renderer)
        if box.x0 < page.x0 - 1 or box.x1 > page.x1 + 1:
            out.append(t.get_text())
    return out


def legend_texts(ax) -> list[str]:
    legend = ax.get_legend()
    return [] if legend is None else [t.get_text() for t in legend.get_texts()]


def _png_size(data: bytes) -> tuple[int, int]:
    return struct.unpack(">II", data[16:24])


# --- titles and the comparison table ------------------------------------------------------
def test_titles_name_the_parameters_that_differ_from_the_preset():
    from validation.output.report import scene_label
    from validation.studies.compare import title

    lattice = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2"])
    assert scene_label(lattice) == "paper-fig3-sparse (Φ = 0.2)"
    assert "paper-fig3-sparse (Φ = 0.2)" in title(lattice, "fem-3d")
    assert scene_label(load_scene("paper-fig3-sparse")) == "paper-fig3-sparse"
    assert scene_label(load_scene("single-pillar", ["load.indentation_um=0.5"])) \
        == "single-pillar (ζ = 0.5 µm)"
    assert scene_label(load_scene("paper-fig3-sparse", ["lens.rigid=true"])) \
        == "paper-fig3-sparse (rigid lens)"
    # a scene that is no preset says its Phi and zeta
    assert scene_label(lattice.replace(name="mine")) == "mine (Φ = 0.2, ζ = 0.3 µm)"


def test_a_solve_report_title_says_the_phi_of_the_run(fakes):
    from fakes import fake_fem

    from validation.output.report import pressure_plot

    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2"])
    fig = pressure_plot(fake_fem(scene, 1.0))
    assert "Φ = 0.2" in fig.axes[0].get_title()


def _row(q):
    return {"quantity": q, "bem": 1.0, "fem": 1.1, "closed_form": None, "u_bem": None,
            "u_fem": None, "u_bem_is_gci": True, "u_fem_is_gci": True,
            "fem_richardson": None, "difference": -0.1, "relative_difference": -0.09,
            "exceeds": None}


def test_lattice_table_has_no_column_headed_none():
    from validation.studies.compare import table_text

    text = table_text([_row("F_T"), _row("sigma0")], "none", "d/2")
    head = text.splitlines()[0]
    assert head.split()[-1] == "verdict" and "none" not in head  # nothing after the verdict
    assert len(text.splitlines()[2].split()) < len(table_text(
        [_row("F_T")], "spring model", "d/2").splitlines()[2].split()) + 1
    assert table_text([_row("F_T")], "Hertz", "a_Hertz").splitlines()[0].split()[-1] == "Hertz"


def test_flat_compare_legend_names_no_pillar_and_sits_clear(fakes, tmp_path, cli,
                                                           monkeypatch):
    from validation.output import plots

    figures = _capture(monkeypatch, plots)
    code, _, err = cli("compare", "--scene", "hertz", "--levels", "2", "--no-render",
                       "--executor", "serial", "--out", tmp_path / "c")
    assert code == 0, err
    (fig,) = figures
    ax = fig.axes[0]
    texts = legend_texts(ax)
    assert texts and not any("pillar" in t.lower() for t in texts), texts
    assert any(t.startswith("BEM, ") for t in texts)
    assert covered_points(ax) == []
    assert clipped_texts(fig) == []


# --- legends clear of the data ------------------------------------------------------------
def test_sparse_pressure_legend_covers_no_data():
    from bem_solver import solve_dense

    from validation.output.report import pressure_plot

    result = solve_dense(load_scene("paper-fig3-sparse"), 11)
    fig = pressure_plot(result)
    ax = fig.axes[1] if len(fig.axes) > 1 and fig.axes[1].get_legend() else None
    ax = ax or next(a for a in fig.axes if a.get_legend() is not None)
    assert "bem elements" in legend_texts(ax)
    assert covered_points(ax) == []
    assert clipped_texts(fig) == []


def test_fem_pressure_legend_covers_no_curve(fakes):
    """The plot of a model without an element map (fem-3d, fem-axisym): the rigid-punch and
    spring-model curves and the model's profile stay visible."""
    from fakes import fake_fem

    from validation.output.report import pressure_plot

    for scene in (load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2"]),
                  load_scene("single-pillar"), load_scene("hertz")):
        fig = pressure_plot(fake_fem(scene, 1.0))
        ax = fig.axes[0]
        assert legend_texts(ax)
        assert covered_points(ax) == [], scene.name
        assert clipped_texts(fig) == [], scene.name
        # every curve the legend lists is drawn inside the axes (not all off the top)
        fig.canvas.draw()
        box = ax.get_window_extent()
        for line in ax.get_lines():
            if line.get_label().startswith("_"):
                continue
            xy = line.get_transform().transform(np.column_stack(line.get_data()))
            assert any(box.contains(*p) for p in xy), line.get_label()


# --- quick figures: legible text; fig7(b)'s legend ----------------------------------------
def test_quick_figures_text_is_legible_and_fig7b_legend_is_clear(tmp_path, monkeypatch):
    """figures --quick draws at a lower dpi; its smallest text is still >= 10 px in the PNG
    (was 5 px: 7 pt at 60 dpi)."""
    from validation.cli import main
    from validation.output import report

    drawn = {}
    original = report.figure_png

    def record(fig, dpi=120, layout=True):
        width_in = fig.get_size_inches()[0]
        data = original(fig, dpi, layout)
        drawn[len(drawn)] = (fig, width_in, data)
        return data

    monkeypatch.setattr(report, "figure_png", record)
    code = main(["figures", "--quick", "--out", str(tmp_path / "f"), "--executor", "serial"])
    assert code == 0 and len(drawn) >= 6
    for fig, width_in, data in drawn.values():
        px_per_pt = _png_size(data)[0] / width_in / 72.0
        assert report.smallest_text_pt(fig) * px_per_pt >= 9.9, fig.texts
    fig7 = next(f for f, _, _ in drawn.values()
                if f._suptitle is not None and f._suptitle.get_text().startswith("Fig. 7"))
    bx = fig7.axes[1]
    assert legend_texts(bx) and covered_points(bx) == []
    assert clipped_texts(fig7) == []


def test_legible_dpi_raises_a_low_dpi_only_as_needed():
    from validation.output.report import legible_dpi, pyplot

    plt = pyplot()
    fig, ax = plt.subplots()
    ax.set_title("t", fontsize=7)
    assert legible_dpi(fig, 60) * 7 / 72 >= 10
    assert legible_dpi(fig, 200) == 200
    plt.close(fig)


# --- convergence.png ----------------------------------------------------------------------
@pytest.mark.parametrize("levels", [2, 3])
def test_convergence_plot_lists_only_what_it_draws(fakes, tmp_path, cli, monkeypatch, levels):
    from validation.output import plots

    figures = _capture(monkeypatch, plots)
    code, _, err = cli("converge", "--scene", "hertz", "--levels", str(levels), "--executor",
                       "serial", "--out", tmp_path / "c")
    assert code == 0, err
    (fig,) = figures
    ax = fig.axes[0]
    label = ax.get_xlabel()
    assert "((" not in label and "))" not in label and "(relative)" not in label, label
    assert label == "relative cell size h = 1/elements_per_diameter"
    for line in ax.get_lines():
        if line.get_label().startswith("slope"):
            x = np.unique(np.asarray(line.get_xdata(), dtype=float))
            assert x.size >= 2  # a drawn line, not a point
    slopes = [t for t in legend_texts(ax) if t.startswith("slope")]
    assert bool(slopes) == (levels > 2), legend_texts(ax)


# --- the 3D render's scale bar ------------------------------------------------------------
def test_scale_bar_label_is_clear_of_its_ruler():
    from validation.output.render3d import region_of_interest, scale_bar

    meta = {"scene": load_scene("paper-fig3-sparse").to_dict()}
    roi, z0, z1 = region_of_interest(meta)
    length, start, end, label = scale_bar(roi, z0, z1)
    assert end[0] - start[0] == pytest.approx(length) and length <= roi
    assert start[0] < label[0] < end[0]  # centred under the ruler
    assert start[2] - label[2] >= 0.15 * (z1 - z0)  # below it, not on it


# --- tradeoff: noise and round-off are no trade -------------------------------------------
def test_times_within_their_noise_are_ties():
    from validation.output.plots import pareto_front

    # P = 9 "faster" than P = 5 by 2 ms, equally accurate: a tie, so the cheaper in error
    # terms decides; the slow accurate rung is a real trade.
    points = [(0.0097, 1e-2), (0.0078, 1e-2), (2.0, 1e-4)]
    assert set(pareto_front(points, [0.005] * 3)) == {0, 1, 2}  # P = 5 and P = 9 tie
    assert pareto_front(points) == [1, 2]  # without the noise, P = 9 "beats" P = 5
    # within the noise, the more accurate one wins, whichever was timed faster
    assert pareto_front([(0.0097, 1e-3), (0.0078, 1e-2)], [0.005, 0.005]) == [0]
    assert pareto_front([(0.0097, 1e-3), (0.0078, 1e-2)]) == [1, 0]  # no noise: a trade


def test_round_off_errors_are_equal_on_the_front():
    from validation.output.plots import pareto_front

    points = [(1.0, 3e-16), (2.0, 1e-15), (3.0, 2e-16)]
    assert pareto_front(points, floor=1e-12) == [0]
    assert pareto_front(points) == [0, 2]  # without the floor, round-off looks like a trade


def _tradeoff_doc(errors):
    rows = [{"model": "bem", "option": "elements_per_diameter", "level": n, "h": 1 / n,
             "wall_time_s": t, "time_noise_s": 0.005, "converged": True, "peak_memory_MB": 1,
             "err_F_T": e, "err_sigma0": e, "err_a": e, "err_A": e}
            for n, t, e in errors]
    return {"models": ["bem"], "rows": rows, "scene": {"name": "hertz"}, "round_off": 1e-12,
            "references": {"half-space": {}}, "skipped": {}}


def test_tradeoff_draws_no_front_of_round_off(tmp_path, monkeypatch):
    from validation.output import plots
    from validation.studies.tradeoff import pareto_table

    doc = _tradeoff_doc([(5, 0.0097, 2e-16), (7, 0.0102, 1e-15), (9, 0.0078, 5e-16)])
    figures = _capture(monkeypatch, plots)
    plots.plot_tradeoff(doc, tmp_path / "t.png")
    (fig,) = figures
    for ax in fig.axes[:4]:
        assert not any(ln.get_label() == "Pareto front" for ln in ax.get_lines())
        assert any("at round-off" in t.get_text() for t in ax.texts)
    table = pareto_table(doc)
    assert "round-off" in table and "e-16" not in table and "e-15" not in table
    assert "ties" in table


def test_tradeoff_rows_carry_their_time_noise(fakes):
    from validation.studies.tradeoff import TIME_NOISE_S, time_noise, tradeoff

    assert time_noise({"wall_time_s": 1.0, "wall_times_s": [0.8, 1.0, 1.5]}) \
        == pytest.approx(0.7)
    assert time_noise({"wall_time_s": 0.001, "wall_times_s": [0.001]}) == TIME_NOISE_S
    doc = tradeoff(load_scene("hertz"), ["bem"], levels=3, repeats=2)
    assert all(r["time_noise_s"] >= TIME_NOISE_S for r in doc["rows"])


# --- one verdict vocabulary ----------------------------------------------------------------
@pytest.mark.parametrize("exc, word", [(ScopeError("outside its scope"), "refused"),
                                       (InputError("bad option"), "refused"),
                                       (RuntimeError("crashed"), "error")])
def test_engine_progress_uses_the_reports_verdicts(fakes, monkeypatch, tmp_path, capsys,
                                                   exc, word):
    from validation.engine import Case, Engine

    def broken(scene, **options):
        raise exc

    monkeypatch.setattr(sys.modules["xval_fakes"], "fake_bem", broken)
    outcome = Engine("serial").run_one(Case("bem", load_scene("hertz"),
                                            {"elements_per_diameter": 5}), tmp_path)
    assert not outcome.ok
    err = capsys.readouterr().err
    assert f": {word}: " in err and "FAILED" not in err, err


def test_tradeoff_says_which_extrapolation_is_the_reference():
    """Two extrapolated sigma0 with two orders were printed side by side, neither named as
    the reference."""
    from validation.studies.tradeoff import pareto_table

    est = {"bem": {"f_exact": 1.0, "order": 1.02, "band": 0.01, "status": "ok",
                   "pre_asymptotic": [], "assumed": None},
           "bem-fft": {"f_exact": 1.03, "order": 0.61, "band": 0.05, "status": "ok",
                       "pre_asymptotic": ["observed order 0.61, expected 1"],
                       "assumed": {"f_exact": 1.01, "order": 1.0, "band": 0.03}}}
    ref = {"value": 1.0, "model": "bem", "order": 1.02, "band": 0.01, "status": "richardson",
           "basis": "the narrowest of agreeing estimates (asymptotic)", "flags": [],
           "per_model": est}
    doc = {**_tradeoff_doc([(5, 0.01, 1e-2), (7, 0.02, 5e-3), (9, 0.03, 2e-3)]),
           "references": {"hooke-pillar": {"sigma0": ref}}}
    lines = pareto_table(doc).splitlines()
    bem = next(ln for ln in lines if "extrapolated by bem:" in ln)
    fft = next(ln for ln in lines if "extrapolated by bem-fft:" in ln)
    assert bem.endswith(": the reference") and "order 1.02" in bem
    assert "not used: pre-asymptotic (observed order 0.61, expected 1)" in fft
    assert any("sigma0 = 1 from bem (the narrowest of agreeing estimates" in ln for ln in lines)


# --- axes that show their data, legends that list what is seen ---------
def _hidden_listed(ax) -> list[str]:
    """Legend entries of ``ax`` whose curve a later solid curve covers at every drawn vertex
    and midpoint, measured vertically in pixels (within half its width plus a pixel)."""
    fig = ax.figure
    _agg(fig)
    fig.canvas.draw()
    listed = set(legend_texts(ax))
    lines = sorted(ax.get_lines(), key=lambda ln: ln.zorder)
    out = []
    for i, line in enumerate(lines):
        if line.get_label() not in listed or line.get_marker() not in ("None", "", " ", None):
            continue
        xy = line.get_transform().transform(np.column_stack(line.get_data()))
        xy = np.concatenate([xy, 0.5 * (xy[1:] + xy[:-1])])
        box = ax.get_window_extent()
        xy = xy[(xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
                & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1)]
        for top in lines[i + 1:]:
            if top.get_linestyle() != "-":
                continue
            t = top.get_transform().transform(np.column_stack(top.get_data()))
            order = np.argsort(t[:, 0])
            under = (xy[:, 0] >= t[order, 0].min()) & (xy[:, 0] <= t[order, 0].max())
            y = np.interp(xy[:, 0], t[order, 0], t[order, 1])
            reach = 0.5 * top.get_linewidth() * fig.dpi / 72 + 1.0
            if xy.size and np.all(under & (np.abs(xy[:, 1] - y) <= reach)):
                out.append(line.get_label())
                break
    return out


def _hertz_curves():
    """A compare of the Hertz scene: BEM, three FEM levels (the two finest 0.05 % apart, one
    under the other) and Hertz, in compare's styles."""
    from pillar_xval.scenes import analytic

    hz = analytic.hertz(load_scene("hertz"))
    r = np.linspace(0.0, 1.0, 60) * hz.contact_radius
    p = hz.pressure(r)
    return hz.contact_radius, [
        {"label": "BEM, elements_per_diameter=47", "style": "o-", "r_m": r, "pressure_Pa": p},
        {"label": "FEM mesh_size=2", "style": ":", "r_m": r, "pressure_Pa": 1.06 * p},
        {"label": "FEM mesh_size=1", "style": ":", "r_m": r, "pressure_Pa": 1.0005 * p},
        {"label": "FEM mesh_size=0.5 (finest)", "style": "-", "r_m": r, "pressure_Pa": p},
        {"label": "Hertz", "style": "k--", "r_m": r, "pressure_Pa": p}]


def test_hertz_profiles_fill_their_axis_and_list_only_visible_curves(tmp_path, monkeypatch):
    """The Hertz profiles left 45 % of the axis empty (1.8 x the peak, room for a pillar's
    edge singularity that a flat contact has not), and listed a FEM level drawn under the
    finest one."""
    from validation.output import plots

    radius, curves = _hertz_curves()
    figures = _capture(monkeypatch, plots)
    plots.plot_profiles(curves, radius, tmp_path / "p.png", "hertz", "a_Hertz")
    (fig,) = figures
    ax = fig.axes[0]
    peak = 1.06 * max(curves[0]["pressure_Pa"]) * 1e-3
    assert ax.get_ylim()[1] <= 1.1 * peak
    assert _hidden_listed(ax) == []
    texts = legend_texts(ax)
    assert "FEM mesh_size=1" not in texts
    assert "FEM mesh_size=0.5 (finest) (hides FEM mesh_size=1)" in texts
    assert "FEM mesh_size=2" in texts and "Hertz" in texts
    assert covered_points(ax) == [] and clipped_texts(fig) == []


def test_a_lattice_solve_draws_no_single_pillar_curve_and_fills_its_axis():
    """pressure.png drew the single-pillar spring model on the dense scene's 151 pillars and
    sized the pressure axis to it (6 sigma0: 45 % of it empty)."""
    from bem_solver import solve_dense

    from validation.output.report import pressure_plot

    result = solve_dense(load_scene("paper-fig3-dense"), 7, pillars="hooke")
    fig = pressure_plot(result)
    ax = next(a for a in fig.axes if a.get_legend() is not None)
    assert not any("spring" in t for t in legend_texts(ax)), legend_texts(ax)
    peak = max(result.fields["pressure_Pa"]) * 1e-3
    assert ax.get_ylim()[1] <= 1.15 * peak
    assert "bem, Hooke pillars" in fig.axes[0].get_title()  # the map names the pillar model


def test_the_colour_bar_label_stands_apart_from_the_profiles_axis():
    """pressure.png set the colour bar's "pressure (kPa)" beside the profile's "pressure
    (kPa)": two scales, one label, side by side."""
    from bem_solver import solve_dense

    from validation.output.report import pressure_plot

    fig = pressure_plot(solve_dense(load_scene("paper-fig3-sparse"), 7, pillars="hooke"))
    _agg(fig)
    fig.tight_layout()
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    bar = next(a for a in fig.axes if a.get_label() == "<colorbar>")
    profile = next(a for a in fig.axes if a.get_legend() is not None)
    labels = [t for t in (bar.xaxis.label, bar.yaxis.label) if t.get_text()]
    (label,) = labels
    assert label.get_text() != profile.yaxis.label.get_text()
    a, b = label.get_window_extent(renderer), profile.yaxis.label.get_window_extent(renderer)
    side_by_side = a.y0 < b.y1 and b.y0 < a.y1 and min(abs(a.x1 - b.x0), abs(b.x1 - a.x0)) < 80
    assert not side_by_side, (a, b)


def test_tradeoff_axes_label_at_least_two_decades(tmp_path, monkeypatch):
    """tradeoff.png spanned less than a decade (times 0.02-0.05 s) with no tick label."""
    from validation.output import plots

    doc = _tradeoff_doc([(5, 0.021, 3e-3), (7, 0.032, 2e-3), (9, 0.048, 1.2e-3)])
    figures = _capture(monkeypatch, plots)
    plots.plot_tradeoff(doc, tmp_path / "t.png")
    (fig,) = figures
    _agg(fig)
    fig.canvas.draw()
    for ax in fig.axes[:4]:
        for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            shown = [t for t, v in zip(axis.get_majorticklabels(), axis.get_majorticklocs())
                     if lo <= v <= hi and t.get_text()]
            assert len(shown) >= 2, (ax.get_title(), [t.get_text() for t in shown])


def test_the_lattice_render_title_keeps_its_glyphs_and_units():
    """The render's title lost its Phi ("( = 0.2)": VTK's fonts are Latin-1) and said "um"
    where the ruler says µm; its colour scale was linear where the other render's is log."""
    from validation.output.render import colour_scale
    from validation.output.render3d import render_title

    meta = {"scene": load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2"]).to_dict()}
    title = render_title(meta, 12, np.pi / 6, 4e-6, True)
    title.encode("latin-1")  # every character drawable
    assert "(Phi = 0.2)" in title and "4 µm" in title and " um" not in title
    assert "log colour scale" in title
    # a contact's edge peaks over the bulk: the log scale, as the axisymmetric render
    log, (lo, hi) = colour_scale(np.concatenate([np.full(900, 0.1), np.linspace(1, 40, 100)]))
    assert log and 0 < lo < hi
    assert colour_scale(np.linspace(1.0, 2.0, 100))[0] is False


def test_the_lattice_render_fills_its_frame(tmp_path):
    """The render left a third of the picture empty around the disk."""
    import json

    pv = pytest.importorskip("pyvista")
    from PIL import Image

    from validation.output.render3d import region_of_interest, render_sector

    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2"])
    meta = {"scene": scene.to_dict(), "discretisation": {"sector_angle_rad": np.pi / 6}}
    roi, z0, z1 = region_of_interest(meta)
    h = scene.pillars.height_m
    blocks = []  # the pi/6 sector of a disk: substrate, a layer for the pillars, the lens
    for body, (lo, hi) in ((2, (z0, -h)), (1, (-h, 0.0)), (0, (0.0, z1))):
        r, t, z = np.meshgrid(np.linspace(0, 1.5 * roi, 12), np.linspace(0, np.pi / 6, 4),
                              np.linspace(lo, hi, 3), indexing="ij")
        sector = pv.StructuredGrid(r * np.cos(t), r * np.sin(t), z).cast_to_unstructured_grid()
        sector.cell_data["body"] = np.full(sector.n_cells, body)
        sector.cell_data["von_mises_Pa"] = np.geomspace(10.0, 4e4, sector.n_cells)
        blocks.append(sector)
    grid = blocks[0].merge(blocks[1:])
    vtu = tmp_path / "f.vtu"
    grid.save(vtu)
    vtu.with_suffix(".json").write_text(json.dumps(meta))
    ok, message = render_sector(vtu, tmp_path / "f.png")
    if not ok:
        pytest.skip(message)  # no OpenGL context on this machine
    a = np.asarray(Image.open(tmp_path / "f.png").convert("RGB")).astype(float)
    h_px, w_px, _ = a.shape
    coloured = (a.max(axis=2) - a.min(axis=2) > 40)
    coloured[:, int(0.85 * w_px):] = False  # the colour bar
    coloured[:int(0.04 * h_px)] = False     # the title
    ys, xs = np.nonzero(coloured)
    assert (xs.max() - xs.min()) / w_px >= 0.7 and (ys.max() - ys.min()) / h_px >= 0.75
