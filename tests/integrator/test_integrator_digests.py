"""The integrator's and the v1 envs' results against values recorded from the code before issue 18.

Two checks per case (see ``integrator_digests.py`` beside this file): the golden values (final
states, trajectory samples, extremes, step counts, observations and rewards) within tolerances
measured per item, on every machine; and the exact digests of everything the case produced, bit for
bit, where this platform (CPU, numba, llvmlite, numpy) recorded a digest set
(``data/integrator_digests.json``: one set per platform; elsewhere that check skips and the golden one
still pins the results).
"""

import json

import numpy as np
import pytest
from integrator_digests import (
    CASES,
    DATA,
    DIGESTS_FILE,
    GOLDEN_FILE,
    PLATFORM_KEY,
    CaseResult,
    golden_differences,
    platform_digests,
)

from gfb_env.provenance import platform_fingerprint

GOLDEN = json.loads((DATA / GOLDEN_FILE).read_text())
DIGESTS = json.loads((DATA / DIGESTS_FILE).read_text())
_RESULTS: dict[str, CaseResult] = {}


def _run(case: str) -> CaseResult:
    """Each case runs once for both checks (the v1 env case takes a few seconds)."""
    if case not in _RESULTS:
        _RESULTS[case] = CASES[case]()
    return _RESULTS[case]


def test_every_case_has_golden_values_and_every_digest_set_is_of_the_cases():
    assert set(GOLDEN) == set(CASES)
    for record in DIGESTS:
        assert set(record[PLATFORM_KEY]) == set(platform_fingerprint())
        assert set(record["cases"]) <= set(CASES)
    pinned = [k for c in GOLDEN.values() for k, v in c.items() if "unpinned" not in v]
    assert len(pinned) > 100  # every case pins its items, not only its flags


@pytest.mark.parametrize("case", sorted(CASES))
def test_golden_values_hold_within_their_measured_tolerances(case):
    bad = golden_differences(_run(case), GOLDEN[case])
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("case", sorted(CASES))
def test_results_are_bit_for_bit_where_this_platform_recorded_them(case):
    want = platform_digests(DIGESTS)
    if want is None or case not in want:
        recorded = sorted({r[PLATFORM_KEY]["cpu"] for r in DIGESTS if case in r["cases"]})
        pytest.skip(
            f"no digests of {case!r} for this platform ({platform_fingerprint()}); recorded on {recorded}"
        )
    got = _run(case).digests
    assert got.keys() == want[case].keys()
    differ = sorted(k for k in want[case] if got[k] != want[case][k])
    assert not differ, f"changed: {differ}"


def test_the_golden_check_catches_a_change_beyond_the_tolerance():
    """A result moved by 10 tolerances in one sample, a count moved beyond its band and a changed flag
    are each reported (the check is not vacuous)."""
    ref = _run("ramps")
    want = GOLDEN["ramps"]
    assert golden_differences(ref, want) == []
    item = "ramps2.trajectory.xi"
    w = want[item]
    moved = CaseResult(floats=dict(ref.floats), counts=dict(ref.counts), exact=dict(ref.exact))
    xi = np.array(ref.floats[item], dtype=float)
    xi[w["index"][3]] += 10 * w["rel"] * w["scale"]
    moved.floats[item] = xi
    moved.counts["ramps0.counts"] = [
        c + b + 1 for c, b in zip(ref.counts["ramps0.counts"], want["ramps0.counts"]["band"])
    ]
    moved.exact["ramps1.status"] = "failed"
    bad = golden_differences(moved, want)
    assert [line.split(":")[0].split("[")[0] for line in bad] == ["ramps0.counts", "ramps1.status", item]
