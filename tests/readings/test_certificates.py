"""The report's table of the thesis's method's certificates (``readings.certificates``), from results tables."""

import numpy as np
import pandas as pd

from airl_cli.readings.certificates import certificates


def _table(widths, converged, degenerate, methods=None):
    """Results rows of fits: each job once under tau and once under tau_1 (the same job facts)."""
    rows = []
    for i, (w, c, d) in enumerate(zip(widths, converged, degenerate)):
        for dynamics in ("tau", "tau_1"):
            rows.append({"method": (methods or ["airl"] * len(widths))[i], "optimizer": "exact", "dynamics": dynamics,
                         "bracket_width": w, "converged": c, "degenerate": d})
    return pd.DataFrame(rows)


def test_one_row_per_experiment_counting_each_job_once_and_a_total():
    tables = {
        "fig05": ({}, _table([2e-4, 9e-4, 3e-3], [True, True, False], [False, True, False])),
        "fig12": ({}, _table([1e-4, np.nan], [True, True], [False, False], methods=["airl", "mce"])),
        "fig02_03": ({}, pd.DataFrame({"experiment": ["fig02_03"], "n_exact": [16384]})),  # no fits
    }
    text = certificates(tables).splitlines()
    assert text[2] == "| fig05 | 3 | 2 | 9.0e-04 [3.0e-03] | 1 |"
    assert text[3] == "| fig12 | 1 | 1 | 1.0e-04 [1.0e-04] | 0 |"  # MCE IRL's row is not a certificate
    assert text[4] == "| **all** | 4 | 3 | 5.5e-04 [3.0e-03] | 1 |" and len(text) == 5
    assert certificates({"fig02_03": tables["fig02_03"]}) == ""
    old = _table([1e-4], [True], [False]).drop(columns="bracket_width")  # a table of an earlier version
    assert certificates({"fig05": ({}, old)}).splitlines()[2] == "| fig05 | 1 | 1 | – | 0 |"


def test_experiments_of_one_sweep_folder_are_one_row_counted_once():
    """A walk through the commands: fig14 and fig15 read one sweep (as fig17 and fig18 do), and the
    table counted its fits twice, in their rows and in the total."""
    shared = _table([2e-4, 5e-4], [True, True], [False, False])
    tables = {
        "fig14": ({"folder": "s/fig14_15-full"}, shared),
        "fig15": ({"folder": "s/fig14_15-full"}, shared),
        "fig05": ({"folder": "s/fig05-full"}, _table([1e-3], [False], [False])),
    }
    text = certificates(tables).splitlines()
    assert text[2] == "| fig14 + fig15 | 2 | 2 | 3.5e-04 [5.0e-04] | 0 |"
    assert text[3].startswith("| fig05 | 1 |") and text[4].startswith("| **all** | 3 | 2 |") and len(text) == 5
