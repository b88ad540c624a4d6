"""Checks a reader of the figures can see, on figures drawn from small datasets made here: the
stable/unstable colours stay apart for colour-blind eyes and the unstable side carries a second cue;
tick labels of log axes with few values do not run into one another; every symbol a model declares
reaches the labels as mathtext; derived outputs carry the user's words. The shipped scenes' figures
get the same checks in tests/figures/test_figure_data.py."""
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from matplotlib.figure import Figure

from mechsweep import figures
from mechsweep.figures import _style, generic

from . import figure_checks as fc

sys.path.insert(0, str(Path(__file__).parent))
from test_generic_figures import cam  # noqa: E402  (a dataset of a model the package does not know)

MIN_DISTANCE = 20.0  # CIEDE2000: the fills must stay at least this far apart under each simulation


@pytest.mark.parametrize("deficiency", ["deuteranopia", "protanopia"])
def test_stable_and_unstable_fills_stay_apart_under_a_colour_vision_deficiency(deficiency):
    """The colours a stability map fills its cells with, read off a drawn map (its colour map at 0
    and 1), are at least MIN_DISTANCE CIEDE2000 apart as a deuteranope or protanope sees them
    (Machado et al. 2009). The red/green pair used before falls to 2 (deuteranopia) and 7: the check
    sees a pair that fails."""
    matrix = {"deuteranopia": fc.DEUTERANOPIA, "protanopia": fc.PROTANOPIA}[deficiency]
    fig = Figure()
    art = generic.stability_panel(fig.subplots(), np.arange(6.0), np.arange(5.0),
                                  np.linspace(0.5, 1.5, 30).reshape(5, 6))
    stable, unstable = (art["mesh"].cmap(art["mesh"].norm(v)) for v in (1.0, 0.0))
    assert fc.distance(stable, unstable) >= MIN_DISTANCE
    assert fc.distance(stable, unstable, matrix) >= MIN_DISTANCE, (stable, unstable)
    assert fc.distance("#c8e6c9", "#f4c7c3", matrix) < 10  # the old green and red
    from mechsweep.figures import autobalancer

    chart = autobalancer.STABLE_COLORS  # the auto-balancer's chart uses the same pair
    assert fc.distance(chart(1.0), chart(0.0), matrix) >= MIN_DISTANCE


def test_the_unstable_cells_and_only_they_are_hatched():
    """The second cue: a hatch over exactly the cells whose verdict is unstable (the fill's cells:
    centres as pcolormesh's shading "nearest"), none over stable or valueless ones; and its legend
    handle is hatched too."""
    fig = Figure()
    ax = fig.subplots()
    values = np.array([[0.5, 2.0, np.nan], [2.0, 0.9, 1.0]])  # unstable at (0, 1) and (1, 0)
    art = generic.stability_panel(ax, np.array([1.0, 2.0, 4.0]), np.array([0.0, 1.0]), values)
    hatch = art["hatch"]
    assert hatch.get_hatch() == _style.UNSTABLE_HATCH
    x, y = np.array([1.0, 2.0, 4.0]), np.array([0.0, 1.0])
    inside = []
    for path in hatch.get_paths():  # the grid point each hatched cell holds
        box = path.get_extents()
        inside += [(i, j) for i in range(2) for j in range(3) if box.x0 < x[j] < box.x1 and box.y0 < y[i] < box.y1]
    assert sorted(inside) == [(0, 1), (1, 0)]  # the two unstable points, each in one cell
    assert _style.unstable_patch().get_hatch() == _style.UNSTABLE_HATCH and not _style.stable_patch().get_hatch()
    all_stable = generic.stability_panel(Figure().subplots(), np.arange(2.0), np.arange(2.0), np.full((2, 2), 0.5))
    assert all_stable["hatch"] is None


def test_a_ticked_boundary_points_its_ticks_to_the_lower_side():
    """ticked_contour turns every contour line so that its ticks (drawn on the right of the line's
    direction) point to the lower values: for z = x - 1 (lower on the left) and z = 1 - x (lower on
    the right) alike, whatever direction the contour came out in."""
    x, y = np.linspace(0.0, 2.0, 21), np.linspace(0.0, 1.0, 11)
    X, _ = np.meshgrid(x, y)
    for z, lower_is_left in ((X - 1.0, True), (1.0 - X, False)):
        ax = Figure().subplots()
        cs = ax.contour(x, y, z, levels=[0.0])
        ax.set_xlim(0, 2)
        ax.set_ylim(0, 1)
        (line,) = _style.ticked_contour(ax, cs, x, y, z, color="k")
        xy = line.get_xydata()
        direction = xy[-1] - xy[0]
        right = np.array([direction[1], -direction[0]])  # the ticks' side
        assert (right[0] < 0) == lower_is_left, (xy[0], xy[-1])
        assert line.get_gid() == _style.STYLE_GID  # a restyling: not counted as data drawn


@pytest.mark.parametrize("values", [[2.0, 3.0, 4.0], [1.2, 2.0, 3.5, 6.0], [2.0, 5.0, 9.0], [2.0, 30.0, 4e4]])
def test_a_log_axis_with_few_values_has_tick_labels_that_do_not_overlap(values):
    """A heatmap over a log axis with a few values, in a small panel of the user's: each tick label
    stands clear of the others (their rendered extents). Before, the minor ticks of a short log axis
    were all labelled in scientific notation and ran into one another ('2x10^0 3x10^0 4x10^0')."""
    base = cam()
    ds = base.isel(speed=slice(0, len(values))).assign_coords(
        speed=("speed", np.array(values), base["speed"].attrs))
    ds["status"][:] = 0
    fig = Figure(figsize=(3.2, 2.6), layout="constrained")
    generic.heatmap(ds, "lift", x="speed", y="preload", at={"contact": "steel"}, ax=fig.subplots())
    assert not fc.tick_label_overlaps(fig)
    shown = [t for t, _ in fc._drawn_tick_labels(fig.axes[0].xaxis, fc.renderer(fig))]
    assert len(shown) >= 2  # labelled more than once
    for kind in figures.available(ds):  # and every default figure of it
        assert not fc.tick_label_overlaps(figures.draw(ds, kind)), kind


def test_the_check_sees_overlapping_tick_labels():
    fig = Figure(figsize=(1.0, 1.0))
    ax = fig.subplots()
    ax.set_xticks([0.0, 0.01], ["a long label", "another long one"])
    assert fc.tick_label_overlaps(fig)


def _as_stored(q) -> xr.DataArray:
    """A parameter or output as a dataset stores it (mechsweep.store.write._describe)."""
    from mechsweep.store.write import _describe

    class Attrs:
        dtype = np.dtype(np.float64)  # a numeric variable (strings get no units)

        def __init__(self):
            self.attrs = {}

    holder = Attrs()
    _describe(holder, q.unit, q.long_name, q.symbol, q.latex)
    return xr.DataArray([1.0], dims="x", name=q.name, attrs=holder.attrs)


def test_every_declared_symbol_reaches_its_label_as_mathtext():
    """For every parameter and output of every built-in model that has a symbol: its label carries
    mathtext (the declared latex, which matplotlib parses), and no label prints an underscore; a
    user's plain symbol ("omega", "A1") is written as mathtext too."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.mathtext import MathTextParser

    from mechsweep.models import MODELS

    parser = MathTextParser("path")
    checked = 0
    for spec in MODELS.values():
        for q in spec.params + spec.outputs:
            if not q.symbol:
                continue
            assert q.latex.startswith("$") and q.latex.endswith("$"), (spec.name, q.name)
            parser.parse(q.latex, 72, FontProperties())  # raises on mathtext matplotlib cannot draw
            text = _style.label(_as_stored(q), width=10**6)
            assert text.startswith(q.latex), (spec.name, q.name, text)
            assert "_" not in fc._MATH.sub("", text), (spec.name, q.name, text)
            checked += 1
    assert checked > 150
    plain = xr.DataArray([1.0], dims="x", name="w", attrs={"long_name": "support angular frequency",
                                                           "symbol": "omega", "units": "rad s-1"})
    assert _style.label(plain, width=200) == r"$\omega$, support angular frequency [rad" + "\u00a0" + "s$^{-1}$]"
    assert _style.mathtext("A1") == "$A_{1}$" and _style.mathtext("omega_xi") == r"$\omega_{\xi}$"
    assert _style.mathtext("position") == ""  # a name, not a symbol: the long name alone


def test_a_user_models_derived_outputs_carry_its_long_name():
    """Steady's first harmonic and phase (name_h1, name_phase) say what the user called the main
    output (they named only the state before), and have symbols of their own."""
    from mechsweep.model import Steady

    plain = {o.name: o for o in Steady("amp", "x", horizon=10.0).outputs()}
    named = {o.name: o for o in Steady("amp", "x", horizon=10.0, long_name="platform amplitude").outputs()}
    assert named["amp_h1"].long_name.startswith("platform amplitude: first-harmonic amplitude")
    assert named["amp_phase"].long_name.startswith("platform amplitude: phase lag of the first harmonic")
    assert "x" in plain["amp_h1"].long_name and "platform" not in plain["amp_h1"].long_name
    assert named["amp_h1"].latex == "$A_1$" and named["amp_phase"].latex == r"$\varphi_1$"
    meta = Steady("amp", "x", horizon=10.0, output_meta={"amp_h1": {"latex": "$a_1$"}}).outputs()
    assert {o.name: o.latex for o in meta}["amp_h1"] == "$a_1$"  # a user's own symbol wins


def test_flag_notes_say_how_many_and_whether_they_have_a_value():
    assert generic.flag_note_text(3, 0) == ("3 flagged points (status not ok, see status) marked ×; none has a "
                                            "value (left blank)")
    assert "2 with a value (drawn), 1 without" in generic.flag_note_text(3, 2)
    assert generic.flag_note_text(1, 1).endswith("each has a value, drawn")


def test_the_readability_check_sees_an_underscore_a_label_without_mathtext_and_a_legend_on_data():
    ds = cam()
    fig = Figure()
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], label="line_one")
    ax.set_xlabel("speed of the cam [rad/s]")  # the variable has a symbol: the label shows none
    ax.legend(loc="center")
    problems = fc.check_readable(fig, ds)
    assert any("literal underscore" in p for p in problems)
    assert any("label without mathtext" in p for p in problems)
    fig = Figure()
    ax = fig.subplots()
    ax.plot(np.linspace(0, 1, 50), np.full(50, 0.5), label="on the data")
    ax.legend(loc="center")
    assert fc.legends_over_data(fig)


def _drawn(*texts):
    """Draw each text on a figure (Agg), as a title, label or caption is drawn: raises where
    matplotlib cannot (a mathtext error)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(3, 2))
    FigureCanvasAgg(fig)
    for k, text in enumerate(texts):
        fig.text(0.01, 0.1 * k, text)
    fig.canvas.draw()


def test_a_symbol_with_a_space_makes_a_fixed_parameters_caption_matplotlib_draws():
    """A fixed parameter whose symbol holds a space ("m_e e"): its caption was '$m_{e}\\<nbsp>e$' (the
    spaces made non-breaking inside the mathtext too), which matplotlib cannot parse, and every
    figure of the dataset failed."""
    ds = cam().assign_coords(me=xr.DataArray(0.01, attrs={"symbol": "m_e e", "units": "kg m", "long_name": "unbalance"}))
    text = _style.fixed_text(ds)
    assert text == "$m_{e}\\ e$\u00a0=\u00a00.01\u00a0kg\u00a0m", text
    _drawn(text)
    fig = figures.draw(_axes_of_two(ds), "heatmap_lift")
    fig.savefig(__import__("io").BytesIO(), format="png")


def _axes_of_two(ds):
    return ds.isel(contact=slice(0, 1))


TEXT = __import__("hypothesis").strategies.text(
    alphabet=__import__("hypothesis").strategies.sampled_from(list("aAmx_^{}\\$ ()[]/|-+*=,.:;'%#&~0123"
                                                                   "αωΔ²₁·≤\u00a0")), max_size=14)


@__import__("hypothesis").settings(max_examples=150, deadline=None, derandomize=True, database=None)
@__import__("hypothesis").given(symbol=TEXT, long_name=TEXT, unit=TEXT, latex=TEXT, choice=TEXT)
def test_any_declared_text_gives_labels_matplotlib_draws(symbol, long_name, unit, latex, choice):
    """Whatever a model declares (symbol, long name, unit, latex, a categorical choice's name), the
    labels made from it (axis label, value text, the fixed parameters' caption, a name in running
    text, a long name in a title) are drawn by matplotlib without a mathtext error: each piece is
    checked by matplotlib's parser and falls back to plain text (its $ escaped) where it fails."""
    attrs = {"symbol": symbol, "long_name": long_name, "units": unit, "latex": latex}
    da = xr.DataArray(0.25, name="q", attrs=attrs)
    cat = xr.DataArray(choice, name="c", attrs=attrs)
    ds = xr.Dataset(coords={"q": da, "c": cat})
    texts = [_style.label(da), _style.label(da, width=12), _style.value_text(da), _style.value_text(cat),
             _style.fixed_text(ds), _style.name_text(da), _style.prose(long_name), _style.units_text(unit),
             _style.mathtext(symbol), _style.symbol(da)]
    for text in texts:
        try:
            _drawn(text)
        except Exception as exc:  # the declaration and the label in the message
            raise AssertionError(f"{attrs}: {text!r}: {type(exc).__name__}") from exc


def test_labels_holding_the_same_symbol_parse_it_once(monkeypatch):
    """A figure's labels repeat their symbols (the axis label, a legend, the fixed parameters' caption):
    the check that matplotlib parses a label (_mathtext._parses) parses each math span once, not each
    label whole again; a label with one span that does not parse still fails the check."""
    from matplotlib.mathtext import MathTextParser

    from mechsweep import _mathtext

    calls = []
    parse = MathTextParser.parse

    def counted(self, s, *args, **kwargs):
        calls.append(s)
        return parse(self, s, *args, **kwargs)

    monkeypatch.setattr(MathTextParser, "parse", counted)
    monkeypatch.setattr(_mathtext, "_PARSED", {})
    for text in ("$\\omega_{0}$", "$\\omega_{0}$, natural frequency", "fixed: $\\omega_{0}$ = 1 rad s$^{-1}$",
                 "$\\omega_{0}$\u00a0=\u00a01\u00a0rad\u00a0s$^{-1}$"):
        assert _mathtext._parses(text)
    assert calls == ["$\\omega_{0}$", "$^{-1}$"]
    assert not _mathtext._parses("$\\omega_{0}$ and $\\nosuchsymbol$")


LINE = __import__("hypothesis").strategies.text(
    alphabet=__import__("hypothesis").strategies.sampled_from(list("$$$\\ax_^{} ()=,~%#&12αω\u00a0\r\n")), max_size=16)


@__import__("hypothesis").settings(max_examples=300, deadline=None, derandomize=True, database=None)
@__import__("hypothesis").given(text=LINE)
def test_the_check_by_math_span_says_what_matplotlibs_parser_says_of_the_whole(text):
    """_mathtext._parses (each math span of a line checked once) is True exactly when matplotlib's mathtext
    parser reads the whole text: dollar signs escaped or not, backslashes, braces, line breaks."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.mathtext import MathTextParser

    from mechsweep import _mathtext

    try:
        MathTextParser("path").parse(text, 72, FontProperties())
        whole = True
    except Exception:  # noqa: BLE001 (any parse failure)
        whole = False
    assert _mathtext._parses(text) == whole, text
