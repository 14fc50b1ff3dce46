"""The integrator's results, bit for bit, against digests recorded before its refactoring.

``tests/data/integrator_digests.json`` was written by ``python tests/integrator_digests.py write ...`` with
the code before the compiled loop was split into stages (commit ef64161).  A change of any trajectory,
final state, counter, extreme, event or message in these cases fails here.  The digests are of float64
bytes: on another CPU or numba/LLVM version the last bits may differ; then check the physics tests and
regenerate them.
"""

import json
from pathlib import Path

import pytest
from integrator_digests import INTEGRATOR_CASES, PLATFORM_KEY

from gfb_env.provenance import platform_fingerprint

WANT = json.loads((Path(__file__).parent / "data" / "integrator_digests.json").read_text())
RECORDED_ON = WANT.pop(PLATFORM_KEY)


def test_every_recorded_case_is_run():
    assert set(WANT) == set(INTEGRATOR_CASES)
    assert set(RECORDED_ON) == set(platform_fingerprint())


@pytest.mark.parametrize("case", sorted(INTEGRATOR_CASES))
def test_results_are_bit_for_bit_unchanged(case):
    here = platform_fingerprint()
    if here != RECORDED_ON:
        # the same code gives other last bits on another CPU or compiler: the digests only pin a
        # refactoring on the machine that recorded them (the physics tests hold everywhere)
        pytest.skip(f"digests recorded on {RECORDED_ON}, this machine is {here}; regenerate to pin here")
    got = INTEGRATOR_CASES[case]()
    want = WANT[case]
    assert got.keys() == want.keys()
    differ = sorted(k for k in want if got[k] != want[k])
    assert not differ, f"changed: {differ}"
