"""Path following on seeded random hoses (kinematic executor), both estimators: a subset
of the 20-hose suite, which runs whole as the campaign `path_following_random_hoses`
(`guidedarm sweep path_following_random_hoses --out DIR`)."""

import pytest
from test_path_following_runs import _run

# random_0..9: half of the suite keeps this file within the test budget.
RANDOM_SEEDS = 10


@pytest.mark.slow
@pytest.mark.parametrize("estimator", ["grid", "ranging"])
def test_random_paths_suite(tmp_path, estimator):
    rows = []
    for seed in range(RANDOM_SEEDS):
        s = _run(tmp_path, f"path=random_{seed}", "executor=kinematic", f"estimator={estimator}")
        rows.append(
            (
                seed,
                s["success"],
                s["coverage"],
                s["tracking_error_max_mm"],
                s["detected_path_error_max_mm"],
                s["failure"] or "",
            )
        )
    print(f"\n{estimator}: seed success coverage tracking_max_mm detected_max_mm failure")
    for seed, ok, cov, trk, det, why in rows:
        print(f"{seed:4d} {ok!s:7s} {cov:8.3f} {trk:15.2f} {det:15.2f} {why}")
    assert sum(row[1] for row in rows) >= 0.9 * RANDOM_SEEDS
