"""Percentile rows: completed runs only, infinite values (never settled) counted apart."""

import numpy as np

from shell.montecarlo.report import percentile_rows


def test_percentile_rows_count_infinite_and_skip_failed_runs():
    table = np.zeros(6, dtype=[("status", "S9"), ("settling", "<f8"), ("k", "<f8")])
    table["status"] = [b"completed", b"completed", b"failed", b"completed", b"stopped", b"completed"]
    table["settling"] = [3.0, np.inf, np.nan, 5.0, 4.0, 10.0]
    table["k"] = [1.0, 2.0, 99.0, 3.0, 4.0, 5.0]
    results = {"table": table, "metric_columns": ["settling"], "draw_columns": ["k"], "units": {"settling": "s", "k": ""}}
    settling, k = percentile_rows(results)
    assert settling[:5] == ("settling", "s", "metric", 4, 1)
    finite = np.array([3.0, 5.0, 4.0, 10.0])
    np.testing.assert_allclose(settling[5:], [finite.mean(), finite.std(ddof=1), 3.0,
                                              *np.percentile(finite, [1, 5, 50, 95, 99]), 10.0], rtol=1e-15)
    assert k[3:5] == (5, 0) and k[5] == 3.0   # the failed run's draw (99) is not in the statistics
