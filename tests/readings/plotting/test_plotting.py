"""Figures from a sweep folder: shapes of the figures, the files draw() writes, determinism, errors."""

from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import to_hex
from matplotlib.figure import Figure

import airl_cli
from airl_cli.kinds.alphas import figures as alpha_figures
from airl_cli.kinds.fit import figures as fit_figures
from airl_cli.readings import plotting
from airl_cli.readings.alpha_values import envelope_vertices

METHODS = ("airl", "mce", "bc")
SEEDS = (0, 1, 2, 3)
XS = (1.0, 10.0, 100.0)
SHOWN = ["tau_1", "tau_2"]


def make_table(x_name: str = "n_demos", methods=METHODS, seeds=SEEDS, xs=XS, n_dynamics: int = 2) -> pd.DataFrame:
    """A results table in the sweep's schema: methods x seeds x xs jobs, each with tau, tau_1..tau_D."""
    rng = np.random.default_rng(7)
    rows = []
    for method in methods:
        for seed in seeds:
            for x in (xs if x_name != "run" else (None,)):
                x_value = float(seed) if x_name == "run" else float(x)
                cos = np.nan if method == "bc" else float(rng.uniform(-0.2, 1.0))
                for d in ["tau"] + [f"tau_{j}" for j in range(1, n_dynamics + 1)]:
                    rows.append({
                        "experiment": "figtest", "method": method, "seed": seed, "run": seed,
                        "x": x_value, "x_name": x_name, "mdp": "random", "dynamics_kind": "gaussian",
                        "n_dynamics": n_dynamics, "n_features": 5, "n_demos": 100, "demos": "sampled",
                        "sigma": 0.1, "weight_sharing": True, "loss": "zero_one", "dynamics": d,
                        "learner_score": float(rng.uniform(0.85, 1.0)),
                        "demonstrator_score": float(rng.uniform(0.95, 1.0)),
                        "cosine_similarity": cos, "seconds": 0.5,
                    })
    return pd.DataFrame(rows)


def make_meta(figures, x_name: str = "n_demos", **extra) -> dict:
    meta = {
        "name": "figtest", "title": "A test figure", "figures": list(figures), "x": x_name,
        "x_label": "number of demonstrations N" if x_name == "n_demos" else "run",
        "x_log": x_name == "n_demos", "dynamics": SHOWN, "threshold": 0.99,
        "thesis": "AIRL matches the demonstrator.", "methods": list(METHODS),
    }
    meta.update(extra)
    return meta


def brute_envelope(vectors: np.ndarray, n: int = 20001) -> np.ndarray:
    """Indices of the vectors that are the maximum somewhere on a fine grid of beliefs."""
    xs = np.linspace(0.0, 1.0, n)
    values = np.outer(1 - xs, vectors[:, 0]) + np.outer(xs, vectors[:, 1])
    return np.unique(np.argmax(values, axis=1))


def make_alphas(n: int = 200, seed: int = 3) -> dict:
    rng = np.random.default_rng(seed)
    exact = rng.normal(size=(n, 2))
    envelope = brute_envelope(exact)
    pbvi = np.vstack([exact[envelope[::2]], exact[rng.choice(n, 10, replace=False)]])
    return {"exact": exact, "exact_envelope": envelope, "pbvi": pbvi, "t": np.int64(2), "s": np.int64(0)}


def write_folder(folder: Path, df: pd.DataFrame | None, meta: dict, alphas: dict | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if df is not None:
        df.to_csv(folder / "results.csv", index=False)
    if alphas is not None:
        np.savez(folder / "alphas.npz", **alphas)
    (folder / "experiment.json").write_text(json.dumps(meta))
    return folder


def colours_of_lines(ax) -> dict[str, str]:
    return {line.get_label(): to_hex(line.get_color()) for line in ax.get_lines()}


# --------------------------------------------------------------------------------------------
# the figure functions


def test_histogram_one_panel_per_method_with_bars_and_annotation():
    df = make_table("run")
    fig = fit_figures.histogram(df, make_meta(["histogram"], "run"))
    assert isinstance(fig, Figure)
    assert len(fig.axes) == len(METHODS)
    for ax, method in zip(fig.axes, METHODS):
        assert ax.patches, "no histogram"
        scores = df.loc[(df.method == method) & df.dynamics.isin(SHOWN), "learner_score"]
        (note,) = [t.get_text() for t in ax.texts]
        assert f"> 99%: {np.mean(scores > 0.99):.0%}" in note
        assert f"minimum: {scores.min():.3f}" in note
        assert f"scores: {len(SEEDS) * len(SHOWN)}" in note
        assert ax.get_title() == plotting.METHOD_LABELS[method]
        # a bin edge sits at 0.99 (the outline of a step histogram has a vertex at every edge)
        outline = ax.patches[0].get_xy()[:, 0]
        assert np.isclose(outline, 0.99).any()


def test_curves_one_panel_per_dynamics_with_median_and_band():
    df = make_table("n_demos")
    fig = fit_figures.curves(df, make_meta(["curves"]))
    d = df[df["dynamics"].isin(SHOWN)]
    shown = [d[d.method == "airl"].groupby(["dynamics", "x"]).learner_score.quantile(0.25).min()]
    shown += [d[d.method == m].groupby(["dynamics", "x"]).learner_score.median().min() for m in METHODS]
    shown += [d.groupby(["dynamics", "x", "seed"]).demonstrator_score.mean().groupby(["dynamics", "x"]).quantile(0.25).min()]
    lowest = min(shown + [0.99])
    expected_low = np.floor((lowest - 0.025) / 0.05) * 0.05
    expected_low = 0.0 if expected_low < 0.2 else expected_low
    assert len(fig.axes) == len(SHOWN)
    for ax in fig.axes:
        labels = [line.get_label() for line in ax.get_lines()]
        for method in METHODS:
            assert plotting.METHOD_LABELS[method] in labels
        demo = [line for line in ax.get_lines() if line.get_label() == "demonstrator"]
        assert demo and demo[0].get_linestyle() == "--" and to_hex(demo[0].get_color()) == "#000000"
        # interquartile bands for this thesis's method and the demonstrator only: five overlapping
        # bands (Fig. 5) hid each other
        bands = [c for c in ax.collections if type(c).__name__ in ("PolyCollection", "FillBetweenPolyCollection")]
        assert len(bands) == 2
        assert {to_hex(b.get_facecolor()[0]) for b in bands} == {plotting.METHOD_COLOURS["airl"], "#000000"}
        assert ax.get_xscale() == "log"
        # the axis starts just under the lowest band edge or median shown, in steps of 0.05
        low, high = ax.get_ylim()
        assert high == pytest.approx(plotting.SCORE_LIMITS[1]) and low == pytest.approx(expected_low)
        assert ax.get_xlabel() == "number of demonstrations N"
    label = "normalised performance" if expected_low == 0 else f"normalised performance (axis from {expected_low:g})"
    assert fig.axes[0].get_ylabel() == label
    assert fig.legends, "no legend"
    # each band's legend swatch is the band's own colour and opacity (it was one grey swatch for a pink band)
    swatches = {t.get_text(): h for t, h in zip(fig.legends[0].get_texts(), fig.legends[0].legend_handles) if "interquartile" in t.get_text()}
    band_colours = {to_hex(b.get_facecolor()[0]): b.get_alpha() for b in bands}
    assert {to_hex(h.get_facecolor()): h.get_alpha() for h in swatches.values()} == band_colours
    assert fig.get_suptitle() == "A test figure"


def test_curves_medians_are_the_medians_over_runs():
    df = make_table("n_demos")
    fig = fit_figures.curves(df, make_meta(["curves"]))
    line = next(line for line in fig.axes[0].get_lines() if line.get_label() == plotting.METHOD_LABELS["airl"])
    rows = df[(df.method == "airl") & (df.dynamics == "tau_1")]
    expected = rows.groupby("x")["learner_score"].median().sort_index()
    np.testing.assert_allclose(line.get_xdata(), expected.index)
    np.testing.assert_allclose(line.get_ydata(), expected.to_numpy())


def test_run_bars_grouped_bars_threshold_and_demonstrator():
    df = make_table("run")
    fig = fit_figures.run_bars(df, make_meta(["run_bars"], "run"))
    assert len(fig.axes) == len(SHOWN)
    for ax in fig.axes:
        assert len(ax.patches) == len(SEEDS) * len(METHODS)
        orange = [line for line in ax.get_lines() if to_hex(line.get_color()) == plotting.THRESHOLD_COLOUR]
        assert orange and orange[0].get_ydata()[0] == pytest.approx(0.99)
        dashed = [c for c in ax.collections if c.get_linestyle()[0][1] is not None]
        assert dashed, "no dashed demonstrator segments"
        # scores of 0.85-1.0 on an axis from 0 are bars of equal height (Figs. 12, 13): start near the lowest
        assert ax.get_ylim() == pytest.approx((0.8, plotting.SCORE_LIMITS[1]))
        assert ax.get_ylabel() == "normalised performance (axis from 0.8)"
    assert fig.legends


def test_run_bars_keep_a_zero_axis_when_a_score_is_low():
    df = make_table("run")
    df.loc[0, "learner_score"] = 0.2
    df.loc[df.dynamics.isin(SHOWN).idxmax(), "learner_score"] = 0.2
    fig = fit_figures.run_bars(df, make_meta(["run_bars"], "run"))
    assert fig.axes[0].get_ylim() == pytest.approx(plotting.SCORE_LIMITS)


@pytest.mark.parametrize(
    "meta, expected",
    [
        ({"title": "Fig. 4: over 100 datasets", "runs": 100, "profile": "quick"}, "Fig. 4: over 4 datasets [quick profile: 4 runs per point]"),
        ({"title": "Fig. 12: per run", "runs": 30, "profile": "full"}, "Fig. 12: per run [4 runs per point]"),
        ({"title": "Fig. 12: per run", "runs": 4, "profile": "full"}, "Fig. 12: per run"),
    ],
)
def test_a_smaller_sweep_than_the_thesiss_says_so_in_the_title(meta, expected):
    assert plotting.sized_title(meta, make_table("run")) == expected


def test_method_colours_are_the_same_across_figures():
    curves = fit_figures.curves(make_table("n_demos"), make_meta(["curves"]))
    bars = fit_figures.run_bars(make_table("run"), make_meta(["run_bars"], "run"))
    line_colours = colours_of_lines(curves.axes[0])
    for method in METHODS:
        label = plotting.METHOD_LABELS[method]
        (container,) = [c for c in bars.axes[0].containers if c.get_label() == label]
        bar_colours = {to_hex(p.get_facecolor()) for p in container}
        assert line_colours[label] == plotting.METHOD_COLOURS[method]
        assert bar_colours == {plotting.METHOD_COLOURS[method]}


def test_cosine_against_the_swept_variable_leaves_out_bc():
    fig = fit_figures.cosine(make_table("n_demos"), make_meta(["cosine"]))
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    labels = [line.get_label() for line in ax.get_lines()]
    assert plotting.METHOD_LABELS["airl"] in labels and plotting.METHOD_LABELS["mce"] in labels
    assert plotting.METHOD_LABELS["bc"] not in labels
    legend_texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert plotting.METHOD_LABELS["bc"] not in legend_texts
    assert any(line.get_ydata()[0] == 0 and to_hex(line.get_color()) != "#000000" for line in ax.get_lines()
               if len(line.get_ydata()) == 2)  # the horizontal line at 0
    low, high = ax.get_ylim()
    assert low < 0 < high and low >= -1.05 and high <= 1.05


@pytest.mark.parametrize("methods", [("airl", "mce"), ("airl", "mce", "projection", "mmp")])
def test_the_legend_lies_inside_the_figure(methods):
    """Two methods and the long band entry in one row were wider than the 7-inch figure (its ends cut off)."""
    fig = fit_figures.cosine(make_table("n_demos", methods=methods), make_meta(["cosine"]))
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box, page = fig.legends[0].get_window_extent(renderer), fig.bbox
    assert box.x0 >= page.x0 and box.x1 <= page.x1


def test_a_single_methods_curves_legend_lies_inside_the_figure():
    """One method's curves: few entries, two with long band labels; laid out in three columns,
    matplotlib splits four of them 2, 1, 1 (not 2, 2), and the legend ran past both edges of the figure."""
    fig = fit_figures.curves(make_table("n_demos", methods=("airl",)), make_meta(["curves"], methods=["airl"], threshold=None))
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box, page = fig.legends[0].get_window_extent(renderer), fig.bbox
    assert len(fig.legends[0].get_texts()) == 4
    assert box.x0 >= page.x0 and box.x1 <= page.x1


def test_cosine_per_run_bars():
    fig = fit_figures.cosine(make_table("run"), make_meta(["cosine"], "run"))
    assert len(fig.axes) == 1
    assert len(fig.axes[0].patches) == len(SEEDS) * 2  # airl and mce; bc has no weights


def test_cosine_without_any_weights_is_an_error():
    df = make_table("n_demos", methods=("bc",))
    with pytest.raises(ValueError, match="cosine"):
        fit_figures.cosine(df, make_meta(["cosine"]))


def test_unknown_dynamics_is_an_error():
    with pytest.raises(ValueError, match="tau_9"):
        fit_figures.curves(make_table("n_demos"), make_meta(["curves"], dynamics=["tau_1", "tau_9"]))


def test_upper_envelope_matches_brute_force():
    data = make_alphas(200)
    xs, ys = envelope_vertices(data["exact"])
    assert xs[0] == 0 and xs[-1] == 1 and np.all(np.diff(xs) > 0)
    grid = np.linspace(0, 1, 5001)
    brute = np.max(np.outer(1 - grid, data["exact"][:, 0]) + np.outer(grid, data["exact"][:, 1]), axis=1)
    np.testing.assert_allclose(np.interp(grid, xs, ys), brute, atol=1e-9)
    # the envelope has one vertex between each pair of neighbouring envelope vectors
    assert len(xs) == len(data["exact_envelope"]) + 1


def test_alpha_vectors_figures():
    data = make_alphas(200)
    exact, pbvi = alpha_figures.alpha_vectors(data)
    assert len(exact.axes) == 2 and len(pbvi.axes) == 1
    left, right = exact.axes
    assert left.get_lines()
    collections = [c for c in right.collections if isinstance(c, LineCollection)]
    assert collections and len(collections[0].get_segments()) == 200
    assert "200" in right.get_title()
    assert str(len(data["exact_envelope"])) in left.get_title()
    (ax,) = pbvi.axes
    assert len(ax.collections[0].get_segments()) == len(data["pbvi"])
    assert str(len(data["pbvi"])) in ax.get_title()
    assert len(ax.get_lines()) >= 2  # PBVI's envelope and the exact one
    assert "t = 2, s = 0" in exact.get_suptitle()


def test_alpha_vectors_missing_array_is_named():
    data = make_alphas(50)
    del data["pbvi"]
    with pytest.raises(ValueError, match="pbvi"):
        alpha_figures.alpha_vectors(data)


# --------------------------------------------------------------------------------------------
# draw()


@pytest.fixture
def sweep(tmp_path) -> Path:
    return write_folder(tmp_path / "sweep", make_table("n_demos"), make_meta(["curves"]))


def test_draw_writes_png_and_pdf_for_every_kind(tmp_path, capsys):
    folder = write_folder(tmp_path / "runs", make_table("run"),
                          make_meta(["histogram", "curves", "run_bars", "cosine"], "run", x_log=False))
    written = plotting.draw(folder)
    names = [p.name for p in written]
    assert names == [f"figtest_{kind}{suffix}" for kind in ("histogram", "curves", "run_bars", "cosine")
                     for suffix in (".png", ".pdf")]
    for path in written:
        assert path.parent == folder / "figures" and path.is_file()
        head = path.read_bytes()[:8]
        assert head.startswith(b"\x89PNG") if path.suffix == ".png" else head.startswith(b"%PDF")
    assert sorted(p.name for p in (folder / "figures").iterdir()) == sorted(names)  # no temporary files left
    assert capsys.readouterr() == ("", "")


def test_draw_alphas(tmp_path):
    folder = write_folder(tmp_path / "alphas", None, {"name": "fig02", "kind": "alphas", "title": "Alpha-vectors", "figures": ["alphas"]},
                          make_alphas(200))
    written = plotting.draw(folder)
    assert [p.name for p in written] == ["fig02_exact.png", "fig02_exact.pdf", "fig02_pbvi.png", "fig02_pbvi.pdf"]


def test_draw_is_deterministic(sweep, tmp_path):
    first = {p.name: p.read_bytes() for p in plotting.draw(sweep)}
    other = write_folder(tmp_path / "again", make_table("n_demos"), make_meta(["curves"]))
    second = {p.name: p.read_bytes() for p in plotting.draw(other)}
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f"{name} differs between two identical sweeps"


@pytest.mark.parametrize("kind, column", [
    ("histogram", "learner_score"),
    ("curves", "demonstrator_score"),
    ("curves", "x"),
    ("run_bars", "run"),
    ("cosine", "cosine_similarity"),
])
def test_draw_names_a_missing_column(tmp_path, kind, column):
    x_name = "run" if kind == "run_bars" else "n_demos"
    df = make_table(x_name).drop(columns=[column])
    folder = write_folder(tmp_path / kind, df, make_meta([kind], x_name))
    with pytest.raises(ValueError, match=column):
        plotting.draw(folder)
    assert not (folder / "figures").exists()  # checked before drawing anything


@pytest.mark.parametrize("missing", ["results.csv", "experiment.json"])
def test_draw_names_a_missing_file(sweep, missing):
    (sweep / missing).unlink()
    with pytest.raises(ValueError, match=missing.replace(".", r"\.")):
        plotting.draw(sweep)


def test_draw_finds_alphas_in_a_job_folder(tmp_path):
    folder = write_folder(tmp_path / "a", None, {"name": "fig02_03", "kind": "alphas", "figures": ["alphas"]})
    (folder / "seed=0").mkdir()  # the sweep keeps alphas.npz in the job's folder
    np.savez(folder / "seed=0" / "alphas.npz", **make_alphas(30))
    assert [p.name for p in plotting.draw(folder)][0] == "fig02_03_exact.png"


def test_draw_names_a_missing_alphas_file(tmp_path):
    folder = write_folder(tmp_path / "a", None, {"name": "fig02", "kind": "alphas", "figures": ["alphas"]})
    with pytest.raises(ValueError, match=r"alphas\.npz"):
        plotting.draw(folder)


def test_draw_rejects_an_unknown_kind(sweep):
    (sweep / "experiment.json").write_text(json.dumps(make_meta(["curves", "violin"])))
    with pytest.raises(ValueError, match="violin"):
        plotting.draw(sweep)


def test_bc_rows_with_empty_cosine_survive_the_csv(tmp_path):
    folder = write_folder(tmp_path / "bc", make_table("n_demos"), make_meta(["cosine"]))
    raw = (folder / "results.csv").read_text()
    assert ",,0.5" in raw  # bc's cosine is written as an empty field
    assert [p.name for p in plotting.draw(folder)] == ["figtest_cosine.png", "figtest_cosine.pdf"]


# --------------------------------------------------------------------------------------------
# the module's imports


def test_plotting_imports_only_pandas_numpy_matplotlib_the_standard_library_results_and_the_method_registry():
    package = Path(airl_cli.__file__).parent
    # the machinery here and every kind's figures (airl_cli/kinds/<kind>/figures[/...].py)
    files = sorted((package / "readings" / "plotting").glob("*.py")) + sorted(package.glob("kinds/*/figures.py")) + sorted(package.glob("kinds/*/figures/*.py"))
    assert len(files) > 8
    names = set()
    for path in files:
        assert len(path.read_text().splitlines()) <= 400, f"{path.name}: split it by figure kind"
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {alias.name for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{path.name} uses a relative import"
                names.add(node.module)
    names = {n for n in names if not n.startswith(("airl_cli.readings.plotting", "airl_cli.kinds."))}
    assert not any(name.startswith("airl_cli.core") for name in names)
    # plotting -> results (atomic writes, the checked read of a results table, a fit folder's reader), methods (each method's label and colour), alpha_values
    # (the alpha-vectors' value, numpy alone, shared with the sweep's rows), variants (a results
    # row's variant of the game, read off its settings) and transfer (its problem and expert model) only
    allowed = {"airl_cli.io.files", "airl_cli.io.run_folder", "airl_cli.io.results_table", "airl_cli.io.fit_folder", "airl_cli.methods", "airl_cli.readings.alpha_values", "airl_cli.readings.variants", "airl_cli.readings.transfer",
               "airl_cli.experiment_kinds", "airl_cli.errors"}  # the kinds' registry (which kind draws what), its one-sentence error
    assert {n for n in names if n.startswith("airl_cli")} <= allowed
    assert "matplotlib.pyplot" not in names
    for name in names - allowed:
        top = name.split(".")[0]
        assert top in {"numpy", "pandas", "matplotlib"} or top in sys.stdlib_module_names, name


def test_times_plots_one_median_per_method_and_size_on_a_log_axis():
    # two jobs per (method, size), each with three rows (one per dynamics) carrying the job's time
    rows = []
    for method, base in (("airl", 2.0), ("mce", 0.5)):
        for x in (8, 16):
            for seed, factor in ((0, 1.0), (1, 3.0)):
                for dyn in ("tau_1", "tau_2", "tau_3"):
                    rows.append(dict(method=method, x=x, seed=seed, dynamics=dyn, seconds=base * factor * x))
    fig = fit_figures.times(pd.DataFrame(rows), {"x_label": "grid side", "methods": ["airl", "mce"]})
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    lines = {line.get_label(): line for line in ax.get_lines()}
    airl = lines[[k for k in lines if k.startswith("AIRL")][0]]
    # the median of the two jobs (x 1 and x 3) is x 2: 2 * 2 * 8 = 32 and 64
    assert np.allclose(airl.get_ydata(), [32.0, 64.0])
    mce = lines["MCE IRL"]
    assert np.allclose(mce.get_ydata(), [8.0, 16.0])


def test_a_variants_figure_names_its_overrides_in_its_title(tmp_path):
    """A walk through the commands: fig05-quick-optim.lam=0.02's figure had the plain sweep's title."""
    meta = {"name": "fig05", "study": "fig05", "profile": "quick"}
    assert plotting.variant_title("Fig. 5", meta, tmp_path / "fig05-quick-optim.lam=0.02") == "Fig. 5 [optim.lam=0.02]"
    assert plotting.variant_title("Fig. 5", meta, tmp_path / "fig05-quick-optim.lam=0.02" / "partial") == "Fig. 5 [optim.lam=0.02]"
    assert plotting.variant_title("Fig. 5", meta, tmp_path / "fig05-quick") == "Fig. 5"
    assert plotting.variant_title("Fig. 5", meta, tmp_path / "mine") == "Fig. 5"  # hydra.sweep.dir=mine: no overrides known
    assert plotting.variant_title("Fig. 14", {"name": "fig14", "study": "fig14_15"}, tmp_path / "fig14_15-full-method=airl") == "Fig. 14 [method=airl]"
